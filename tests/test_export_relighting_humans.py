"""rh-export --format relighting-humans: the published layout, read the way code written for it reads it."""
from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from PIL import Image

from export_data import tiny_dataset
from rh_common.colourspace import quantize8
from rh_common.imageio import read_exr, read_json, read_png
from rh_dataset.export import main as export_main
from rh_dataset.export.common import rodrigues


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    ds = tiny_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("rh") / "out"
    assert export_main(["--dataset", str(ds), "--protocol", "a", "--format", "relighting-humans", "--out", str(out),
                        "--no-progress"]) == 0
    return ds, out


def test_layout_matches_the_published_folders(exported):
    ds, out = exported
    train, test = out / "train_p1" / "subject_01", out / "test" / "subject_01"
    pattern = re.compile(r"frame_(\d{6})\.png$")  # how published-data loaders find their frames
    assert [p.name for p in sorted(train.glob("frame_*.png")) if pattern.match(p.name)] == [
        "frame_000000.png", "frame_000001.png"]
    for i in range(2):
        s = f"frame_{i:06d}"
        assert {p.name for p in test.glob(f"{s}*")} == {f"{s}{x}" for x in (
            ".png", ".json", "_albedo.png", "_normals.png", "_semantic.png")}
        assert {p.name for p in train.glob(f"{s}*")} == {f"{s}{x}" for x in (".png", ".json", "_semantic.png")}
    assert read_json(out / "export.json")["format"] == "relighting-humans"


def test_images_masks_albedo_and_normals_read_as_the_published_code_reads_them(exported):
    ds, out = exported
    src = ds / "subject_000" / "protocol_a" / "test"
    d = out / "test" / "subject_01"
    for i in range(2):
        s = f"frame_{i:06d}"
        assert (d / f"{s}.png").read_bytes() == (src / f"{s}_image.png").read_bytes()
        rgba = np.asarray(Image.open(d / f"{s}_semantic.png"))
        assert rgba.shape[-1] == 4
        mask = rgba[..., 3] / 255.0 > 0.5  # the published rule
        np.testing.assert_array_equal(mask, read_png(src / f"{s}_mask.png") >= 128)  # ours (coverage > 0.5)
        # Albedo is read as linear by code written for the published data: ours is stored linear.
        np.testing.assert_array_equal(read_png(d / f"{s}_albedo.png"), quantize8(read_exr(src / f"{s}_albedo.exr")))
        n = read_png(d / f"{s}_normals.png") / 255.0 * 2 - 1
        nn = np.linalg.norm(n[mask], axis=-1)
        assert mask.any() and np.all(np.abs(nn - 1) < 0.02)
        # The same OpenGL camera-space normals as our float layer, to 8-bit precision.
        assert np.abs(n[mask] - read_exr(src / f"{s}_normal.exr")[mask]).max() <= 1.0 / 255 + 1e-6


def test_json_has_k_fov_hdri_and_body_parameters_that_reproduce_the_body(exported):
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses import BodyPose

    ds, out = exported
    for split, folder in (("train", "train_p1"), ("test", "test")):
        rec = json.loads((out / folder / "subject_01" / "frame_000001.json").read_text())
        meta = read_json(ds / "subject_000" / "protocol_a" / split / "frame_000001.json")
        smpl = rec["skeleton_0"]["smpl_data"]
        K = np.array(smpl["K"])
        np.testing.assert_array_equal(K, meta["camera"]["K"])
        assert rec["camera"]["fov"] == pytest.approx(math.radians(meta["camera"]["fov_y_deg"]))
        assert len(smpl["pose"]) == 3 * 103 and len(smpl["betas"]) == 6 and smpl["scale"] == 1.0
        assert ("bg_file" in rec) == (split == "test")
        if split == "test":
            assert rec["bg_file"] == meta["light"]["source"] and rec["hdri_name"] == meta["light"]["name"]
        # verts_cam = R(global_orient) @ body posed without its root + global_trans, in camera coordinates.
        pose = BodyPose.from_json(meta["body"]["pose"])
        bones = dict(pose.bones)
        bones.pop("root", None)
        local = run_anny(meta["body"]["phenotype"], bones)["vertices"]
        world = pose.apply_root_transform(run_anny(meta["body"]["phenotype"], dict(pose.bones))["vertices"])
        w2c = np.array(meta["camera"]["world_to_camera"])
        cam = world @ w2c[:3, :3].T + w2c[:3, 3]
        ours = local @ rodrigues(smpl["global_orient"]).T + np.array(smpl["global_trans"])
        np.testing.assert_allclose(ours, cam, atol=1e-6)


def test_a_foreign_folder_is_refused(tmp_path_factory, tmp_path, capsys):
    ds = tiny_dataset(tmp_path_factory)
    (tmp_path / "mine.txt").write_text("x")
    assert export_main(["--dataset", str(ds), "--format", "relighting-humans", "--out", str(tmp_path),
                        "--no-progress"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert export_main(["--dataset", str(tmp_path), "--format", "usd", "--out", str(tmp_path / "o"),
                        "--no-progress"]) == 2
    assert "not an rh dataset" in capsys.readouterr().err
