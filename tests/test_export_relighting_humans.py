"""rh-export --format relighting-humans: the published layout, read the way code written for it reads it.

The clients' formulas (IntrinsicAvatar's test camera, its light's direction mapping, the semantic alpha rule) are
re-implemented here from their documented definitions (docs/INTEROP.md), never imported or copied."""
from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from PIL import Image

from export_data import published_dataset, tiny_dataset
from rh_common import sh
from rh_common.colourspace import quantize8
from rh_common.imageio import read_exr, read_hdr, read_json, read_png, write_hdr
from rh_dataset.export import main as export_main
from rh_dataset.poses.joints import axis_angle_matrix


def _export(tmp_path_factory, ds, protocol):
    out = tmp_path_factory.mktemp(f"rh_{protocol}") / "out"
    assert export_main(["--dataset", str(ds), "--protocol", protocol, "--format", "relighting-humans",
                        "--out", str(out), "--no-progress"]) == 0
    return ds, out


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    return _export(tmp_path_factory, tiny_dataset(tmp_path_factory), "a")


@pytest.fixture(scope="module")
def published(tmp_path_factory):
    return _export(tmp_path_factory, published_dataset(tmp_path_factory), "b")


FIVE = (".png", ".json", "_albedo.png", "_normals.png", "_semantic.png")
FRAME = re.compile(r"frame_(\d{6})\.png$")  # how published-data loaders find their frames


def test_layout_matches_the_published_folders(exported, published):
    ds, out = exported
    train, test = out / "train_p1" / "subject_01", out / "test" / "subject_01"
    assert [p.name for p in sorted(train.glob("frame_*.png")) if FRAME.match(p.name)] == [
        "frame_000000.png", "frame_000001.png"]
    for i in range(2):
        s = f"frame_{i:06d}"
        assert {p.name for p in test.glob(f"{s}*")} == {f"{s}{x}" for x in FIVE}
        # protocol_a's train split renders no albedo/normal: nothing is invented, the README says who fails.
        assert {p.name for p in train.glob(f"{s}*")} == {f"{s}{x}" for x in (".png", ".json", "_semantic.png")}
    assert read_json(out / "export.json")["format"] == "relighting-humans"
    readme = (out / "README.md").read_text()
    assert "train_p1 has no _albedo.png" in readme and "not 1280x720" in readme and "no SMPL" in readme
    # Protocol b as the clients name it, from the published_b scene: all five files in every split.
    _, pub = published
    assert sorted(p.name for p in pub.iterdir()) == ["README.md", "export.json", "hdri", "test", "train_p2_p3"]
    for split in ("train_p2_p3", "test"):
        d = pub / split / "subject_01"
        assert sorted(p.name for p in d.glob("*.json")) == ["frame_000000.json", "frame_000001.json"]  # only frames
        for i in range(2):
            assert {p.name for p in d.glob(f"frame_{i:06d}*")} == {f"frame_{i:06d}{x}" for x in FIVE}
    assert "_albedo" not in (pub / "README.md").read_text()


def test_a_second_protocol_into_the_same_folder_is_refused(published, tmp_path_factory, capsys):
    _, out = published
    ds = tiny_dataset(tmp_path_factory)
    assert export_main(["--dataset", str(ds), "--protocol", "a", "--format", "relighting-humans", "--out", str(out),
                        "--no-progress"]) == 2
    assert "shares" in capsys.readouterr().err


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
        assert set(np.unique(rgba[..., 3])) <= {0, 255}  # binary: no loader can read an alpha of 128 differently
        # Albedo is read as linear by code written for the published data: ours is stored linear.
        np.testing.assert_array_equal(read_png(d / f"{s}_albedo.png"), quantize8(read_exr(src / f"{s}_albedo.exr")))
        n = read_png(d / f"{s}_normals.png") / 255.0 * 2 - 1
        nn = np.linalg.norm(n[mask], axis=-1)
        assert mask.any() and np.all(np.abs(nn - 1) < 0.02)
        # The same OpenGL camera-space normals as our float layer, to 8-bit precision.
        assert np.abs(n[mask] - read_exr(src / f"{s}_normal.exr")[mask]).max() <= 1.0 / 255 + 1e-6


def _cam_body(meta):
    """anny's posed body and joints (bone heads) in OpenCV camera coordinates, from our frame record."""
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses import BodyPose

    pose = BodyPose.from_json(meta["body"]["pose"])
    out = run_anny(meta["body"]["phenotype"], dict(pose.bones))
    w2c = np.array(meta["camera"]["world_to_camera"])
    to_cam = lambda x: pose.apply_root_transform(x) @ w2c[:3, :3].T + w2c[:3, 3]  # noqa: E731
    return to_cam(out["vertices"]), to_cam(out["bone_poses"][:, :3, 3])


def test_json_has_k_fov_hdri_and_body_parameters_that_reproduce_the_body(exported):
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses import BodyPose

    ds, out = exported
    for split, folder in (("train", "train_p1"), ("test", "test")):
        rec = json.loads((out / folder / "subject_01" / "frame_000001.json").read_text())
        meta = read_json(ds / "subject_000" / "protocol_a" / split / "frame_000001.json")
        smpl = rec["skeleton_0"]["smpl_data"]
        K = np.array(smpl["K"])
        # The same camera with rays through integer pixel coordinates: principal point half a pixel up-left.
        np.testing.assert_array_equal(K, np.array(meta["camera"]["K"]) - [[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]])
        assert rec["camera"]["fov"] == pytest.approx(2 * math.atan(meta["width"] / 2 / K[0, 0]))  # horizontal
        assert rec["camera"]["fov_y"] == pytest.approx(math.radians(meta["camera"]["fov_y_deg"]))
        assert rec["camera"]["yaw"] == 0
        assert len(smpl["pose"]) == 3 * 103 and len(smpl["betas"]) == 6 and smpl["scale"] == 1.0
        # Every frame names its baked light, train included, and the file is in <out>/hdri/.
        assert rec["bg_file"].startswith("rh_") and (out / "hdri" / rec["bg_file"]).is_file()
        assert (out / "hdri" / (rec["bg_file"][:-3] + "exr")).is_file()  # the name another loader derives
        # verts_cam = R(global_orient) @ body posed without its root + global_trans, in camera coordinates.
        pose = BodyPose.from_json(meta["body"]["pose"])
        bones = dict(pose.bones)
        bones.pop("root", None)
        local = run_anny(meta["body"]["phenotype"], bones)["vertices"]
        cam, _ = _cam_body(meta)
        ours = local @ axis_angle_matrix(smpl["global_orient"]).T + np.array(smpl["global_trans"])
        np.testing.assert_allclose(ours, cam, atol=1e-6)


JOINTS = ("root", "upperleg01.L", "upperleg01.R", "lowerleg01.L", "lowerleg01.R", "foot.L", "foot.R", "spine03",
          "spine01", "neck01", "head", "upperarm01.L", "upperarm01.R", "lowerarm01.L", "lowerarm01.R")


def test_the_clients_test_camera_projects_the_body_into_the_mask(published):
    """IntrinsicAvatar builds the test camera from `fov` and the image size: f = 0.5·W / tan(fov/2),
    c = ((W−1)/2, (H−1)/2), rays through integer pixel coordinates. On a non-square export it must equal
    `smpl_data.K`, and the body's joints must land inside the mask."""
    from rh_common.body_model import load_anny

    ds, out = published
    labels = list(load_anny().bone_labels)
    idx = [labels.index(b) for b in JOINTS]
    for split in ("train_p2_p3", "test"):
        for i in range(2):
            d = out / split / "subject_01"
            rec = read_json(d / f"frame_{i:06d}.json")
            W, H = rec["camera"]["width"], rec["camera"]["height"]
            assert (W, H) == (64, 36) and np.asarray(Image.open(d / f"frame_{i:06d}.png")).shape[:2] == (H, W)
            f = 0.5 * W / math.tan(rec["camera"]["fov"] / 2)
            K_client = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1]])
            np.testing.assert_allclose(K_client, rec["skeleton_0"]["smpl_data"]["K"], atol=1e-9)
            _, joints = _cam_body(read_json(ds / "subject_000" / "protocol_b" / rec["rh"]["split"]
                                            / f"frame_{i:06d}.json"))
            uv = joints[idx] @ K_client.T
            uv = np.rint(uv[:, :2] / uv[:, 2:]).astype(int)  # the pixel whose centre is nearest
            mask = np.asarray(Image.open(d / f"frame_{i:06d}_semantic.png"))[..., 3] / 255.0 > 0.5
            assert np.all((0 <= uv[:, 0]) & (uv[:, 0] < W) & (0 <= uv[:, 1]) & (uv[:, 1] < H))
            # The mask has one sample per pixel (--aov-spp 1): a limb a pixel wide can miss the one sample of the
            # pixel its joint projects to (a draped dress's framing put an ankle there), so a joint counts as inside
            # when its pixel or a neighbour is covered; the camera convention itself is K_client == K above.
            padded = np.pad(mask, 1)
            near = np.zeros_like(mask)
            for dv in range(3):
                for du in range(3):
                    near |= padded[dv:dv + H, du:du + W]
            inside = near[uv[:, 1], uv[:, 0]]
            assert inside.all(), [JOINTS[k] for k in np.flatnonzero(~inside)]
            assert mask[uv[:, 1], uv[:, 0]].sum() >= len(JOINTS) - 2  # most land on a covered pixel itself


def _ia_directions(H, W):
    """torch_pbr's lookup, inverted: texel (i, j) of an align-corners grid is lon = (j/(W−1) − 0.5)·2π,
    lat = (i/(H−1) − 0.5)·π, d = (cos lat sin lon, sin lat, cos lat cos lon) in IntrinsicAvatar's test world."""
    lon = (np.arange(W) / (W - 1) - 0.5) * 2 * np.pi
    lat = (np.arange(H) / (H - 1) - 0.5) * np.pi
    lon, lat = np.meshgrid(lon, lat)
    return np.stack([np.cos(lat) * np.sin(lon), np.sin(lat), np.cos(lat) * np.cos(lon)], axis=-1), lat


def test_the_baked_light_has_the_frames_sh_in_the_clients_frame(published):
    """SH of the baked map, integrated over IntrinsicAvatar's directions, rotated from its test world into our
    OpenGL camera axes, equal the frame's exposure × `sh_camera` (the scaled, rotated map seen from the camera)."""
    ds, out = published
    # IA's test world → OpenCV camera (its get_perspective at yaw 0: the camera looks along +x, right is −z),
    # then OpenCV → OpenGL camera axes.
    R_ia = np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])
    to_gl = np.diag([1.0, -1, -1]) @ R_ia
    seen = set()
    for split in ("train_p2_p3", "test"):
        for i in range(2):
            rec = read_json(out / split / "subject_01" / f"frame_{i:06d}.json")
            if rec["bg_file"] in seen:
                continue
            seen.add(rec["bg_file"])
            L = read_hdr(out / "hdri" / rec["bg_file"]).astype(np.float64)
            exr = read_exr(out / "hdri" / (rec["bg_file"][:-3] + "exr"))  # the same map, float32
            assert np.all(np.abs(exr - L) <= exr.max(axis=-1, keepdims=True) / 256 + 1e-30)
            H, W = L.shape[:2]
            dirs, lat = _ia_directions(H, W)
            w_lon = np.full(W, 2 * np.pi / (W - 1))
            w_lon[[0, -1]] /= 2  # the first and last columns are the same meridian: trapezoid rule
            w_lat = np.full(H, np.pi / (H - 1))
            w_lat[[0, -1]] /= 2
            w = np.cos(lat) * w_lat[:, None] * w_lon[None, :]
            coeffs = np.einsum("hwk,hwc->kc", sh.basis(dirs) * w[..., None], L)
            got = sh.rotate(coeffs, to_gl)
            want = rec["rh_bake"]["k"] * np.array(rec["rh"]["light"]["sh_camera"])
            assert rec["rh_bake"]["k"] == rec["rh"]["exposure"]
            # The bake resamples the map bilinearly and RGBE keeps 8 bits of mantissa: measured <= 0.09% of the DC
            # term on these maps; a wrong orientation (no R_ia, or the map turned 180°) is off by 80% or more.
            np.testing.assert_allclose(got, want, atol=0.003 * np.abs(want[0]).max())
    assert len(seen) >= 2 and len(list((out / "hdri").glob("*.hdr"))) == len(seen)  # one file per distinct light


def test_hdr_files_round_trip_to_8_bits_of_mantissa(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.random((7, 5, 3)) * np.array([1e-3, 1.0, 5e4])
    img[0, 0] = 0
    write_hdr(tmp_path / "x.hdr", img)
    head = (tmp_path / "x.hdr").read_bytes()[:64]
    assert head.startswith(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 7 +X 5\n")
    back = read_hdr(tmp_path / "x.hdr")
    assert back.shape == img.shape and np.all(back[0, 0] == 0)
    assert np.all(np.abs(back - img) <= img.max(axis=-1, keepdims=True) / 256 + 1e-30)
    with pytest.raises(ValueError, match="NaN"):
        write_hdr(tmp_path / "y.hdr", np.full((2, 2, 3), np.nan))


def test_a_foreign_folder_is_refused(tmp_path_factory, tmp_path, capsys):
    ds = tiny_dataset(tmp_path_factory)
    (tmp_path / "mine.txt").write_text("x")
    assert export_main(["--dataset", str(ds), "--format", "relighting-humans", "--out", str(tmp_path),
                        "--no-progress"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert export_main(["--dataset", str(tmp_path), "--format", "usd", "--out", str(tmp_path / "o"),
                        "--no-progress"]) == 2
    assert "not an rh dataset" in capsys.readouterr().err


def test_a_light_that_is_not_on_this_machine_is_a_one_line_error(tmp_path_factory, tmp_path, monkeypatch, capsys):
    import rh_dataset.export.rh_light as rh_light

    ds = tiny_dataset(tmp_path_factory)
    monkeypatch.setattr(rh_light, "hdri_path", lambda light, folder: None)  # as on a machine without the maps
    assert export_main(["--dataset", str(ds), "--format", "relighting-humans", "--out", str(tmp_path / "o"),
                        "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "is not on this machine" in err and "--hdri-folder" in err
