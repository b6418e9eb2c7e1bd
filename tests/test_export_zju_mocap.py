"""rh-export --format zju-mocap: annots.npy, images, masks, params and vertices as the NeuralBody family reads them."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from export_data import tiny_dataset
from rh_common.imageio import read_json, read_png
from rh_dataset.export import main as export_main
from rh_dataset.poses.joints import axis_angle_matrix


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    ds = tiny_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("zju") / "out"
    assert export_main(["--dataset", str(ds), "--format", "zju-mocap", "--out", str(out), "--no-progress"]) == 0
    return ds, out


@pytest.mark.parametrize("split", ["train", "test"])
def test_annots_cameras_and_images_as_neuralbody_reads_them(exported, split):
    ds, out = exported
    root = out / "subject_000" / split
    annots = np.load(root / "annots.npy", allow_pickle=True).item()
    cams = annots["cams"]
    assert all(len(cams[k]) == 1 for k in ("K", "R", "T", "D"))
    meta = read_json(ds / "subject_000" / "protocol_a" / split / "frame_000000.json")
    w2c = np.array(meta["camera"]["world_to_camera"])
    np.testing.assert_allclose(np.array(cams["R"][0]), w2c[:3, :3])
    np.testing.assert_allclose(np.array(cams["T"][0]) / 1000.0, w2c[:3, 3:4])  # NeuralBody: T / 1000
    # The same camera for code that casts rays through integer pixel coordinates (NeuralBody): c moves by −0.5 px.
    np.testing.assert_array_equal(np.array(cams["K"][0]), np.array(meta["camera"]["K"]) - [[0, 0, .5], [0, 0, .5],
                                                                                             [0, 0, 0]])
    ims = [np.array(d["ims"])[0] for d in annots["ims"]]
    assert ims == ["Camera_B1/000000.png", "Camera_B1/000001.png"]
    for i, rel in enumerate(ims):
        assert (root / rel).read_bytes() == (ds / "subject_000" / "protocol_a" / split /
                                             f"frame_{i:06d}_image.png").read_bytes()
        msk = read_png(root / "mask" / rel)
        assert set(np.unique(msk)) <= {0, 255}
        assert int(rel.split("/")[-1][:-4]) == i  # NeuralBody parses the frame index from the file name


def test_vertices_project_onto_the_mask_and_params_rebuild_them(exported):
    from rh_dataset.characters import CharacterRecipe, build_character, pose_character
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses import BodyPose

    ds, out = exported
    root = out / "subject_000" / "test"
    annots = np.load(root / "annots.npy", allow_pickle=True).item()
    K, R, T = (np.array(annots["cams"][k][0]) for k in ("K", "R", "T"))
    for i in range(2):
        xyz = np.load(root / "vertices" / f"{i}.npy")
        p = (xyz @ R.T + (T / 1000.0).T) @ K.T
        uv = np.rint(p[:, :2] / p[:, 2:]).astype(int)  # integer pixel centres
        msk = read_png(root / "mask" / "Camera_B1" / f"{i:06d}.png") > 0
        ok = (uv[:, 0] >= 0) & (uv[:, 0] < msk.shape[1]) & (uv[:, 1] >= 0) & (uv[:, 1] < msk.shape[0])
        assert ok.all()
        # A 32-px mask is coarse (thin limbs cover under half a pixel, so hands fall outside it): compare the
        # silhouette's bounding box with a pixel of slack, and most vertices land on the mask.
        rows, cols = np.nonzero(msk)
        assert abs(uv[:, 1].min() - rows.min()) <= 1 and abs(uv[:, 1].max() - rows.max()) <= 1
        assert abs(uv[:, 0].min() - cols.min()) <= 1 and abs(uv[:, 0].max() - cols.max()) <= 1
        assert binary_dilation(msk)[uv[:, 1], uv[:, 0]].mean() > 0.8
        params = np.load(root / "params" / f"{i}.npy", allow_pickle=True).item()
        assert params["poses"].shape == (1, 312) and np.all(params["poses"][0, :3] == 0)
        assert params["shapes"].shape == (1, 6) and params["Rh"].shape == (1, 3) and params["Th"].shape == (1, 3)
        meta = read_json(ds / "subject_000" / "protocol_a" / "test" / f"frame_{i:06d}.json")
        pose = BodyPose.from_json(params["rh_pose"])
        assert pose == BodyPose.from_json(meta["body"]["pose"])
        bones = dict(pose.bones)
        bones.pop("root", None)
        local = run_anny(dict(zip(params["shape_labels"], params["shapes"][0])), bones)["vertices"]
        np.testing.assert_allclose(local @ axis_angle_matrix(params["Rh"][0]).T + params["Th"][0], xyz, atol=1e-5)
        # ... and they are exactly the skin the renderer drew (the body part of the posed character), but where
        # posing tucked skin that came out through draped cloth back under it (`cloth_pose.tuck_skin`: hidden).
        character = build_character(CharacterRecipe.from_json(read_json(ds / "subject_000" / "character.json")),
                                    drape="coarse")  # export_data generates with --drape coarse
        split = character.part("body").body_vertex
        body = pose_character(character, dict(pose.bones), pose.root_transform, tuck_depth=0.0)[0]
        np.testing.assert_allclose(xyz[split], body.vertices, atol=1e-6)
        drawn = pose_character(character, dict(pose.bones), pose.root_transform)[0]
        tucked = np.unique(split[np.any(drawn.vertices != body.vertices, axis=1)])
        inside = [p.inside_skin for p in character.parts if p.inside_depth is not None]
        assert np.isin(tucked, np.concatenate(inside) if inside else []).all()
