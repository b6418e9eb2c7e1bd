"""rh-export --smpl-model: SMPL's numbers in the Relighting Humans frames and the ZJU-MoCap params, checked the way
the clients use them (their formula `x_cam = scale · (V − J0) + global_trans`, their camera from `fov`, NeuralBody's
`vertices = SMPL(poses, shapes) · R(Rh)ᵀ + Th`), with the stand-in model (not SMPL) written by --write-test-smpl.
The fit runs with few iterations here: these tests check what is written, tests/test_smpl_fit.py how well it fits."""
from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from PIL import Image
from scipy.ndimage import distance_transform_edt

torch = pytest.importorskip("torch")

from export_data import tiny_dataset  # noqa: E402
from rh_common.imageio import read_json  # noqa: E402
from rh_dataset.export import main as export_main  # noqa: E402
from rh_dataset.export.cli import export_dataset  # noqa: E402
from rh_dataset.poses.joints import axis_angle_matrix  # noqa: E402
from rh_dataset.smpl.fit import FitSettings  # noqa: E402
from rh_dataset.smpl.model import forward, load_body_model  # noqa: E402

QUICK = FitSettings(joint_iterations=6, surface_rounds=2, surface_iterations=1)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("smpl_models")
    assert export_main(["--write-test-smpl", str(folder)]) == 0
    return folder


@pytest.fixture(scope="module")
def rh_export(tmp_path_factory, models):
    ds = tiny_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("rh_smpl") / "out"
    counts = export_dataset(ds, "a", "relighting-humans", out, smpl_model=models, smpl_settings=QUICK)
    return ds, out, counts


def _frames(out):
    return sorted(p for p in out.glob("*/subject_01/frame_*.json"))


def _t(a):
    return torch.as_tensor(np.asarray(a, np.float64)[None])


def test_vertices_are_the_clients_formula_of_the_parameters(rh_export, models):
    _, out, counts = rh_export
    model = load_body_model(models / "SMPL_NEUTRAL.pkl")
    paths = _frames(out)
    assert len(paths) == 4 and counts["smpl_fitted_frames"] == 4
    betas = None
    for p in paths:
        s = read_json(p)["skeleton_0"]["smpl_data"]
        assert s["model"] == "smpl" and s["gender"] == "neutral" and s["standin"] is True
        assert s["model_sha256"] == hashlib.sha256((models / "SMPL_NEUTRAL.pkl").read_bytes()).hexdigest()
        assert len(s["pose"]) == 69 and len(s["betas"]) == 10 and len(s["global_orient"]) == 3
        assert np.shape(s["vertices"]) == (6890, 3) and np.shape(s["joints"]) == (24, 3)
        assert "anny_pose" in s and "anny_betas" in s  # anny's numbers kept, renamed
        betas = s["betas"] if betas is None else betas
        assert s["betas"] == betas  # one subject, train and test: the same floats
        V, J = forward(model, _t(s["betas"]), _t(s["pose"]), _t(s["global_orient"]))
        V, J = V[0].numpy(), J[0].numpy()
        x = s["scale"] * (V - J[0]) + np.asarray(s["global_trans"])
        assert np.abs(np.asarray(s["vertices"]) / 1000.0 - x).max() < 1e-6, p
        assert np.abs(np.asarray(s["joints"]) / 1000.0 - (s["scale"] * (J - J[0]) + s["global_trans"])).max() < 1e-6
        assert s["fit"]["model_to_anny_mean_mm"] < 15.0
    readme = (out / "README.md").read_text()
    assert "NOT SMPL" in readme and "no SMPL parameters" not in readme
    assert read_json(out / "export.json")["smpl"]["gender"] == "neutral"


def test_joints_project_into_the_mask_with_the_clients_camera(rh_export):
    """IntrinsicAvatar's test camera: f = 0.5 · W / tan(fov / 2), principal point ((W−1)/2, (H−1)/2), rays through
    integer pixel coordinates; the torso and limb joints of the fit land on the person."""
    _, out, _ = rh_export
    for p in _frames(out):
        rec = read_json(p)
        cam, s = rec["camera"], rec["skeleton_0"]["smpl_data"]
        W, H = cam["width"], cam["height"]
        f = 0.5 * W / math.tan(cam["fov"] / 2)
        J = np.asarray(s["joints"]) / 1000.0
        u = np.rint(f * J[:, 0] / J[:, 2] + (W - 1) / 2).astype(int)
        v = np.rint(f * J[:, 1] / J[:, 2] + (H - 1) / 2).astype(int)
        alpha = np.asarray(Image.open(p.with_name(p.stem + "_semantic.png")))[..., 3] > 127
        assert ((0 <= u) & (u < W) & (0 <= v) & (v < H)).all(), p
        # Pixels from the person: at 32 px a forearm is a pixel wide and a hand less, so the trunk and limb joints
        # must be on the mask or next to it, the hand and foot joints within two pixels.
        off = distance_transform_edt(~alpha)[v, u]
        ends = np.isin(np.arange(24), [10, 11, 22, 23])
        assert (off[~ends] <= 1.0).all() and (off[ends] <= 2.0).all(), (p, off)


def test_rerun_reuses_the_cached_fit(rh_export, models):
    ds, out, _ = rh_export
    before = {p: p.read_bytes() for p in _frames(out)}
    counts = export_dataset(ds, "a", "relighting-humans", out, smpl_model=models, smpl_settings=QUICK)
    assert counts["smpl_fitted_frames"] == 0
    assert {p: p.read_bytes() for p in _frames(out)} == before  # a rerun writes the same numbers


def test_zju_mocap_params_and_vertices_as_neuralbody_reads_them(rh_export, models, tmp_path):
    ds, rh_out, _ = rh_export
    out = tmp_path / "zju"
    export_dataset(ds, "a", "zju-mocap", out, smpl_model=models, smpl_settings=QUICK)
    model = load_body_model(models / "SMPL_NEUTRAL.pkl")
    seq = out / "subject_000" / "test"
    cams = np.load(seq / "annots.npy", allow_pickle=True).item()["cams"]
    R, T = np.asarray(cams["R"][0]), np.asarray(cams["T"][0]).ravel() / 1000.0
    rh = read_json(rh_out / "test" / "subject_01" / "frame_000001.json")["skeleton_0"]["smpl_data"]
    p = np.load(seq / "params" / "1.npy", allow_pickle=True).item()
    assert p["poses"].shape == (1, 72) and not p["poses"][0, :3].any() and p["shapes"].shape == (1, 10)
    assert p["shapes"][0].tolist() == rh["betas"]
    V0, _ = forward(model, _t(p["shapes"][0]), _t(p["poses"][0, 3:]), _t(np.zeros(3)))
    world = V0[0].numpy() @ axis_angle_matrix(p["Rh"][0]).T + p["Th"][0]
    verts = np.load(seq / "vertices" / "1.npy")
    assert verts.shape == (6890, 3) and verts.dtype == np.float32
    assert np.abs(verts - world).max() < 1e-5
    # ... and it is the Relighting Humans export's camera-frame body (the same deterministic fit), seen from the world.
    assert np.abs(verts @ R.T + T - np.asarray(rh["vertices"]) / 1000.0).max() < 1e-5
    assert (seq / "vertices_anny" / "1.npy").is_file() and "anny_poses" in p


def test_bad_model_folders_are_one_line_errors(tmp_path, capsys, tmp_path_factory):
    ds = tiny_dataset(tmp_path_factory)
    from rh_dataset.smpl.model import BodyModel, write_smpl_pickle

    def run(folder):
        rc = export_main(["--dataset", str(ds), "--format", "relighting-humans", "--out", str(tmp_path / "o"),
                          "--smpl-model", str(folder), "--no-progress"])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1, err
        return err

    assert "no such folder" in run(tmp_path / "missing")
    assert "SMPL_NEUTRAL.pkl" in run(tmp_path)  # empty folder: names the file it looked for
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "SMPL_NEUTRAL.pkl").write_bytes(b"not a pickle at all")
    assert "SMPL_NEUTRAL.pkl" in run(bad) and "download the model file again" in run(bad)
    small = tmp_path / "small"
    rng = np.random.default_rng(0)
    V, parents = 100, np.array([-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21])
    w = rng.random((V, 24))
    write_smpl_pickle(small / "SMPL_NEUTRAL.pkl", BodyModel(
        "smpl", "neutral", rng.normal(size=(V, 3)), np.zeros((V, 3, 10)), np.zeros((V, 3, 207)),
        np.full((24, V), 1.0 / V), w / w.sum(1, keepdims=True), parents, rng.integers(0, V, (50, 3))))
    assert "100 vertices, not SMPL's 6890" in run(small)
    assert not (tmp_path / "o").exists()  # nothing written before the model is known to be good


def test_usd_stage_carries_the_smpl_mesh(rh_export, models, tmp_path):
    pxr = pytest.importorskip("pxr")
    ds, rh_out, _ = rh_export
    out = tmp_path / "usd"
    export_dataset(ds, "a", "usd", out, smpl_model=models, smpl_settings=QUICK, splits=("test",))
    stage = pxr.Usd.Stage.Open(str(out / "subject_000" / "protocol_a" / "test" / "frame_000001.usdc"))
    mesh = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/World/SMPL"))
    points = np.asarray(mesh.GetPointsAttr().Get())
    assert points.shape == (6890, 3) and mesh.GetPurposeAttr().Get() == "guide"
    assert stage.GetPrimAtPath("/World/Character").IsValid()  # beside the clothed character, not instead of it
    w2c = np.asarray(read_json(rh_out / "test" / "subject_01" / "frame_000001.json")["rh"]["camera"]["world_to_camera"])
    rh = read_json(rh_out / "test" / "subject_01" / "frame_000001.json")["skeleton_0"]["smpl_data"]
    assert np.abs(points @ w2c[:3, :3].T + w2c[:3, 3] - np.asarray(rh["vertices"]) / 1000.0).max() < 1e-5


def test_a_frame_above_the_threshold_is_refused_by_name(rh_export, models):
    """A limit below the fit's error: the cached fit is judged again (no refit) and the first frame is named."""
    import dataclasses

    from rh_dataset.export import ExportError

    ds, out, _ = rh_export
    strict = dataclasses.replace(QUICK, max_mean_mm=0.001)
    with pytest.raises(ExportError, match=r"frame subject_000/\w+/\d{6}: the SMPL fit is too far .*--smpl-max-mean-mm"):
        export_dataset(ds, "a", "relighting-humans", out, smpl_model=models, smpl_settings=strict)
