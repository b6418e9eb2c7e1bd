"""SMPL-X: the stand-in built from anny is in SMPL-X's layout (10,475 vertices, 55 joints, the keys smplx's loader
reads), the fit recovers a body the model made (jaw and eyes held at zero), and `rh-export --smplx-model` writes
`skeleton_0.smplx_data` and ZJU-MoCap `params_smplx/` whose vertices are the forward pass of the written numbers."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export_data import tiny_dataset  # noqa: E402
from rh_common.imageio import read_json  # noqa: E402
from rh_dataset.export import main as export_main  # noqa: E402
from rh_dataset.export.cli import export_dataset  # noqa: E402
from rh_dataset.poses.joints import axis_angle_matrix  # noqa: E402
from rh_dataset.smpl.fit import FitInput, FitSettings, FrameTarget, camera_frame, fit_subject  # noqa: E402
from rh_dataset.smpl.model import SMPLX_EXTRA_KEYS, forward, load_body_model, write_smplx_npz  # noqa: E402
from rh_dataset.smpl.skeletons import SMPLX  # noqa: E402
from rh_dataset.smpl.standin import build_standin  # noqa: E402
from rh_dataset.smpl.standin_pose import example_pose  # noqa: E402

QUICK = FitSettings(joint_iterations=6, surface_rounds=2, surface_iterations=1)
J = {n: i for i, n in enumerate(SMPLX.joint_names)}


@pytest.fixture(scope="module")
def standin():
    return build_standin("neutral", "smplx")


@pytest.fixture(scope="module")
def models(tmp_path_factory, standin):
    """The neutral stand-in only (the export fits the neutral file; the CLI test writes all three)."""
    folder = tmp_path_factory.mktemp("smplx_models")
    write_smplx_npz(folder / "SMPLX_NEUTRAL.npz", standin)
    return folder


def _t(a):
    return torch.as_tensor(np.asarray(a, np.float64))


def test_layout_is_smplx(standin):
    m = standin
    assert m.kind == "smplx" and m.v_template.shape == (10475, 3) and m.n_joints == 55
    assert m.shapedirs.shape == (10475, 3, 20) and not m.shapedirs[..., 10:].any()  # expression dirs zero
    assert m.n_betas == 10 and np.linalg.norm(m.shapedirs[..., 0], axis=1).max() > 0.01
    assert m.posedirs.shape == (10475, 3, 486) and not m.posedirs.any()
    assert m.J_regressor.shape == (55, 10475) and np.allclose(m.J_regressor.sum(1), 1, atol=1e-12)
    assert m.weights.shape == (10475, 55) and np.allclose(m.weights.sum(1), 1, atol=1e-12)
    assert not m.weights[:, J["jaw"]].any()  # anny has no jaw bone
    # SMPL-X's kintree: fingers hang from the wrists, three per finger; jaw and eyes from the head.
    assert [m.parents[J[k]] for k in ("jaw", "L_eye", "R_eye")] == [15, 15, 15]
    assert m.parents[J["L_index1"]] == 20 and m.parents[J["L_index3"]] == J["L_index2"]
    assert m.parents[J["R_thumb1"]] == 21 and list(SMPLX.joint_names[25:28]) == ["L_index1", "L_index2", "L_index3"]
    import trimesh

    assert len(np.unique(m.faces)) == 10475
    assert trimesh.Trimesh(m.v_template, m.faces, process=False).is_watertight
    for key, shape in (("lmk_faces_idx", (51,)), ("lmk_bary_coords", (51, 3)), ("dynamic_lmk_faces_idx", (79, 17)),
                       ("dynamic_lmk_bary_coords", (79, 17, 3)), ("hands_componentsl", (45, 45)),
                       ("hands_meanr", (45,))):
        assert np.shape(m.extra[key]) == shape, key
    assert m.extra["lmk_faces_idx"].max() < len(m.faces)


def test_joints_sit_on_anny_anatomy(standin):
    """T-pose: the fingers run out along ±X from the wrists, knuckle to tip; the eyes are in front of the head
    joint and either side of the middle; the jaw inside the head, in front of and above the head joint."""
    Jt = standin.J_regressor @ standin.v_template
    for s, sx in (("L", 1.0), ("R", -1.0)):
        for finger in ("index", "middle", "pinky", "ring"):
            x = [sx * Jt[J[f"{s}_{finger}{k}"], 0] for k in (1, 2, 3)]
            assert sx * Jt[J[f"{s}_wrist"], 0] < x[0] < x[1] < x[2], (s, finger, x)
        assert sx * Jt[J[f"{s}_eye"], 0] > 0.01
    head = Jt[J["head"]]
    assert Jt[J["L_eye"], 2] > head[2] + 0.03 and Jt[J["R_eye"], 2] > head[2] + 0.03
    assert head[2] < Jt[J["jaw"], 2] < Jt[J["L_eye"], 2] and Jt[J["jaw"], 1] > head[1]


def test_file_loads_as_smplx_and_round_trips(models, standin):
    path = models / "SMPLX_NEUTRAL.npz"
    with np.load(path, allow_pickle=False) as z:  # plain arrays: smplx's np.load(allow_pickle=True) reads it too
        keys = set(z.files)
    assert {"v_template", "f", "J_regressor", "weights", "kintree_table", "shapedirs", "posedirs",
            *SMPLX_EXTRA_KEYS} <= keys
    m = load_body_model(path, "smplx")
    for k in ("v_template", "shapedirs", "J_regressor", "weights", "faces", "parents"):
        assert np.array_equal(getattr(m, k), getattr(standin, k)), k
    assert m.extra["rh_standin"]["note"].startswith("not SMPL-X")
    assert np.array_equal(m.extra["rh_standin"]["anny_vertex_ids"], standin.extra["rh_standin"]["anny_vertex_ids"])
    for k in SMPLX_EXTRA_KEYS:
        assert np.array_equal(m.extra[k], standin.extra[k]), k
    # Bitwise reproducible file (its sha256 keys the fit cache): no write time inside, unlike np.savez's zip entries.
    import time

    time.sleep(2.1)  # the zip format's clock ticks in 2 s steps
    again = models / "again" / "SMPLX_NEUTRAL.npz"
    write_smplx_npz(again, standin)
    assert again.read_bytes() == path.read_bytes()
    from rh_dataset.smpl.model import SmplModelError

    # SMPL-X's downloads also hold pickled object arrays (joint2num, part2num): skipped, never unpickled.
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(models / "with_objects.npz", **arrays, joint2num=np.array({"pelvis": 0}, dtype=object))
    assert np.array_equal(load_body_model(models / "with_objects.npz", "smplx").J_regressor, standin.J_regressor)
    with pytest.raises(SmplModelError, match="posedirs must be .* 207"):
        load_body_model(path, "smpl")  # a SMPL-X file where SMPL is expected: the wrong topology, one line


def test_fit_recovers_a_body_the_model_made(standin):
    """Known betas, body and finger poses → the model's own surface; the fit lands on it, keeps jaw and eyes at
    zero, and its outputs are the clients' formula of its own parameters."""
    rng = np.random.default_rng(3)
    betas = rng.normal(size=10) * 0.7
    pose = np.zeros((1, 162))
    pose[0, :63] = example_pose()[1:22].ravel()
    pose[0, 72:] = rng.normal(size=90) * 0.2  # both hands' fingers
    V, Jc = camera_frame(standin, _t(betas[None]), _t(pose), _t([[np.pi, 0.3, 0.0]]), _t([[0.05, 0.1, 3.0]]))
    frames = (FrameTarget("frame 0", V[0].numpy(), standin.faces, Jc[0].numpy()),)
    fit = fit_subject(FitInput(standin, frames, QUICK), log=None)
    f = fit.frames[0]
    assert f.quality.model_to_anny_mean_mm < 1.0 and f.quality.anny_to_model_mean_mm < 1.0, f.quality
    assert f.quality.joint_mean_mm < 3.0, f.quality
    assert f.pose.shape == (162,) and not f.pose[63:72].any()  # jaw, left eye, right eye: exactly zero
    assert np.abs(f.pose[:63] - pose[0, :63]).max() < 0.15  # the body's joints recovered
    Vf, Jf = camera_frame(standin, _t(fit.betas[None]), _t(f.pose[None]), _t(f.global_orient[None]),
                          _t(f.global_trans[None]), fit.scale)
    assert np.allclose(Vf[0].numpy(), f.vertices, atol=1e-9) and np.allclose(Jf[0].numpy(), f.joints, atol=1e-9)
    again = fit_subject(FitInput(standin, frames, QUICK), log=None)
    assert again.betas.tobytes() == fit.betas.tobytes() and again.frames[0].pose.tobytes() == f.pose.tobytes()


@pytest.fixture(scope="module")
def rh_export(tmp_path_factory, models):
    ds = tiny_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("rh_smplx") / "out"
    counts = export_dataset(ds, "a", "relighting-humans", out, smplx_model=models, smpl_settings=QUICK)
    return ds, out, counts


def test_export_writes_smplx_data(rh_export, models):
    _, out, counts = rh_export
    model = load_body_model(models / "SMPLX_NEUTRAL.npz", "smplx")
    paths = sorted(out.glob("*/subject_01/frame_*.json"))
    assert len(paths) == 4 and counts["smplx_fitted_frames"] == 4 and "smpl_fitted_frames" not in counts
    betas = None
    for p in paths:
        sk = read_json(p)["skeleton_0"]
        s = sk["smplx_data"]
        assert sk["smpl_data"]["model"] == "anny"  # smpl_data as without --smpl-model
        assert s["model"] == "smplx" and s["standin"] is True and len(s["betas"]) == 10
        assert s["model_sha256"] == hashlib.sha256((models / "SMPLX_NEUTRAL.npz").read_bytes()).hexdigest()
        assert len(s["pose"]) == 162 and len(s["body_pose"]) == 63 and len(s["left_hand_pose"]) == 45
        assert len(s["right_hand_pose"]) == 45 and s["jaw_pose"] == [0.0] * 3 and s["expression"] == [0.0] * 10
        assert s["body_pose"] + s["jaw_pose"] + s["leye_pose"] + s["reye_pose"] + s["left_hand_pose"] + \
            s["right_hand_pose"] == s["pose"]
        assert np.shape(s["vertices"]) == (10475, 3) and np.shape(s["joints"]) == (55, 3)
        betas = s["betas"] if betas is None else betas
        assert s["betas"] == betas  # one subject, train and test: the same floats
        V, Jm = forward(model, _t([s["betas"]]), _t([s["pose"]]), _t([s["global_orient"]]))
        V, Jm = V[0].numpy(), Jm[0].numpy()
        assert np.abs(np.asarray(s["vertices"]) / 1000.0 - (s["scale"] * (V - Jm[0]) + s["global_trans"])).max() < 1e-6
        assert s["fit"]["model_to_anny_mean_mm"] < 15.0
    assert "NOT SMPL-X" in (out / "README.md").read_text()
    assert read_json(out / "export.json")["smplx"]["standin"] is True
    # A rerun refits nothing and writes the same bytes.
    before = {p: p.read_bytes() for p in paths}
    ds = rh_export[0]
    assert export_dataset(ds, "a", "relighting-humans", out, smplx_model=models,
                          smpl_settings=QUICK)["smplx_fitted_frames"] == 0
    assert {p: p.read_bytes() for p in paths} == before
    import dataclasses

    from rh_dataset.export import ExportError

    with pytest.raises(ExportError, match=r"frame subject_000/\w+/\d{6}: the SMPL-X fit is too far"):
        export_dataset(ds, "a", "relighting-humans", out, smplx_model=models,
                       smpl_settings=dataclasses.replace(QUICK, max_mean_mm=0.001))


def test_zju_params_smplx(rh_export, models, tmp_path):
    ds, rh_out, _ = rh_export
    out = tmp_path / "zju"
    import shutil

    # The fit's cache from the Relighting Humans export serves this one too (same model, settings and frames).
    shutil.copytree(rh_out / "smplx_fit", out / "smplx_fit")
    counts = export_dataset(ds, "a", "zju-mocap", out, smplx_model=models, smpl_settings=QUICK)
    assert counts["smplx_fitted_frames"] == 0
    model = load_body_model(models / "SMPLX_NEUTRAL.npz", "smplx")
    seq = out / "subject_000" / "test"
    p = np.load(seq / "params_smplx" / "1.npy", allow_pickle=True).item()
    assert p["poses"].shape == (1, 165) and not p["poses"][0, :3].any() and p["expression"].shape == (1, 10)
    assert p["left_hand_pose"].shape == (1, 45) and p["body_pose"].shape == (1, 63)
    V0, _ = forward(model, _t(p["shapes"]), _t(p["poses"][:, 3:]), _t(np.zeros((1, 3))))
    verts = np.load(seq / "vertices_smplx" / "1.npy")
    assert verts.shape == (10475, 3)
    assert np.abs(verts - (V0[0].numpy() @ axis_angle_matrix(p["Rh"][0]).T + p["Th"][0])).max() < 1e-5
    rh = read_json(rh_out / "test" / "subject_01" / "frame_000001.json")["skeleton_0"]["smplx_data"]
    assert p["shapes"][0].tolist() == rh["betas"]  # the same deterministic fit
    assert np.load(seq / "params" / "1.npy", allow_pickle=True).item()["model"] != "smplx"  # params/ unchanged


def test_bad_smplx_input_is_one_line(tmp_path, tmp_path_factory, capsys, models):
    ds = tiny_dataset(tmp_path_factory)

    def run(folder, fmt="relighting-humans"):
        rc = export_main(["--dataset", str(ds), "--format", fmt, "--out", str(tmp_path / "o"),
                          "--smplx-model", str(folder), "--no-progress"])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1, err
        return err

    assert "SMPLX_NEUTRAL.npz" in run(tmp_path)  # no file: names what it looked for
    wrong = tmp_path / "wrong"
    wrong.mkdir()
    from rh_dataset.smpl.model import write_smpl_pickle

    write_smpl_pickle(wrong / "SMPLX_NEUTRAL.pkl", build_standin("neutral"))  # SMPL's topology under SMPL-X's name
    assert "SMPLX_NEUTRAL.pkl" in run(wrong) and "SMPL-X model" in run(wrong)
    assert "USD stage carries the SMPL mesh only" in run(models, "usd")
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_cli_writes_all_three(tmp_path, capsys):
    assert export_main(["--write-test-smplx", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["SMPLX_FEMALE.npz", "SMPLX_MALE.npz", "SMPLX_NEUTRAL.npz"]
    assert "not SMPL-X" in capsys.readouterr().out
    male, female = (load_body_model(tmp_path / f"SMPLX_{g}.npz", "smplx") for g in ("MALE", "FEMALE"))
    assert np.ptp(male.v_template[:, 1]) > np.ptp(female.v_template[:, 1])


@pytest.mark.slow
def test_an_uncached_rebuild_writes_the_same_bytes(tmp_path, models):
    from rh_dataset.smpl.standin import _build

    write_smplx_npz(tmp_path / "SMPLX_NEUTRAL.npz", _build("neutral", "smplx")[0])
    assert (tmp_path / "SMPLX_NEUTRAL.npz").read_bytes() == (models / "SMPLX_NEUTRAL.npz").read_bytes()
