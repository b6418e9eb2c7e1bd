"""rh_dataset.smpl.standin: the SMPL-format stand-in built from anny is in SMPL's layout and conventions, and it
poses like anny's own body (its LBS against anny's forward pass, vertex for vertex)."""
from __future__ import annotations

import hashlib
import pickle

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from rh_dataset.smpl import standin as S  # noqa: E402
from rh_dataset.smpl import standin_pose as P  # noqa: E402
from rh_dataset.smpl.model import find_model_file, forward, load_body_model, write_smpl_pickle  # noqa: E402


@pytest.fixture(scope="session")
def neutral():
    return S.build_standin("neutral")


def test_layout(neutral):
    m = neutral
    assert m.v_template.shape == (6890, 3) and m.shapedirs.shape == (6890, 3, 10)
    assert m.posedirs.shape == (6890, 3, 207) and not m.posedirs.any()  # anny has no pose correctives
    assert m.J_regressor.shape == (24, 6890) and m.weights.shape == (6890, 24)
    assert np.array_equal(m.parents, S.SMPL_PARENTS)
    assert m.J_regressor.min() >= 0 and np.allclose(m.J_regressor.sum(1), 1, atol=1e-12)
    assert m.weights.min() >= 0 and np.allclose(m.weights.sum(1), 1, atol=1e-12)
    assert np.all((m.J_regressor > 0).sum(1) < 200)  # sparse rows
    # Every vertex in a triangle; the clustered mesh is a closed surface.
    import trimesh

    assert len(np.unique(m.faces)) == 6890
    mesh = trimesh.Trimesh(m.v_template, m.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0.03  # closed, normals outward


def test_smpl_axes_and_tpose(neutral):
    v, J = neutral.v_template, neutral.J_regressor @ neutral.v_template
    name = {n: i for i, n in enumerate(S.SMPL_JOINT_NAMES)}
    height = v[:, 1].max() - v[:, 1].min()
    assert 1.5 < height < 1.9  # metres, Y up
    assert J[name["head"], 1] > J[name["pelvis"], 1] > J[name["L_ankle"], 1]
    assert J[name["L_shoulder"], 0] > 0.1 and J[name["R_shoulder"], 0] < -0.1  # character's left is +X
    ids = S.SMPL_VERTEX_IDS
    assert v[ids["nose"], 2] > J[name["head"], 2] + 0.05  # faces +Z
    assert v[ids["LBigToe"], 2] > v[ids["LHeel"], 2] + 0.15
    for s in "LR":
        sh, el, wr = (J[name[f"{s}_{j}"]] for j in ("shoulder", "elbow", "wrist"))
        assert abs(wr[1] - sh[1]) < 0.005 and abs(el[1] - sh[1]) < 0.005  # arms horizontal
        assert abs(wr[2] - sh[2]) < 0.005  # and straight out sideways
        hip, ankle = J[name[f"{s}_hip"]], J[name[f"{s}_ankle"]]
        assert abs(ankle[0] - hip[0]) < 0.01  # legs straight down
    lm, rm = v[ids["lmiddle"]], v[ids["rmiddle"]]
    assert lm[0] > 0.75 and rm[0] < -0.75 and abs(lm[1] - J[name["L_wrist"], 1]) < 0.05


def test_regressor_reproduces_anny_joints(neutral):
    rep = S.standin_report("neutral")
    assert rep.joint_residual_template_mm < 0.5
    assert rep.joint_residual_samples_mean_mm < 10.0
    assert rep.shape_variance_kept > 0.99


def test_forward_matches_anny_posed_body(neutral):
    """The stand-in's LBS of a moderate pose against anny's own forward pass, posed by the same joint rotations.
    Joints agree to the regressor's residual (0.1 mm); vertices differ where skinning blends bones that the T-pose
    turned (armpits, groin): anny blends from its rest pose, the stand-in from the T-pose, and linear blending does
    not compose. Measured: mean 0.7 mm, max 15 mm (at the armpit)."""
    from rh_common.body_model import load_anny
    from rh_dataset.characters.body import run_anny
    from rh_dataset.poses.rig import rig_for

    pheno = S.default_phenotype("neutral")
    pose = P.example_pose()
    anny_out = run_anny(pheno, P.anny_pose_from_smpl(rig_for(load_anny(), pheno), pose))
    ids = neutral.extra["rh_standin"]["anny_vertex_ids"]
    expected = S.to_smpl_axes(anny_out["vertices"][ids])
    t = lambda a: torch.as_tensor(np.asarray(a, np.float64).reshape(1, -1))  # noqa: E731
    verts, _ = forward(neutral, t(np.zeros(10)), t(pose[1:]), t(pose[0]))
    err = np.linalg.norm(verts[0].numpy() - expected, axis=1) * 1e3
    moved = np.linalg.norm(expected - neutral.v_template, axis=1) * 1e3
    assert np.median(moved) > 50  # the pose is not a near-identity one
    assert err.mean() < 1.5 and err.max() < 25.0, (err.mean(), err.max())
    assert np.percentile(err, 50) < 0.5  # measured: median 0.2 mm, 90th percentile 2.2 mm


def test_shape_directions_are_anny_bodies(neutral):
    """betas move the template towards anny bodies of other phenotypes: the first direction changes the body
    (centimetres at one standard deviation), and all ten are orthogonal."""
    d = neutral.shapedirs.reshape(-1, 10)
    gram = d.T @ d
    assert np.allclose(gram - np.diag(np.diag(gram)), 0, atol=1e-9 * gram.max())
    assert np.linalg.norm(neutral.shapedirs[..., 0], axis=1).max() > 0.01
    assert np.all(np.diff(np.diag(gram)) <= 0)  # ordered by variance


def test_shape_space_covers_other_anny_bodies(neutral):
    """Held-out anny bodies (phenotypes not among the 64 samples), T-posed, are reproduced by the best betas to
    millimetres: the linear shape space spans anny's. Measured (bench/smpl_standin.py): mean 2.1 mm, worst body 3.9."""
    from rh_dataset.characters.body import sample_phenotype

    rng = np.random.default_rng(12345)
    bodies, _ = S.anny_tpose_bodies([sample_phenotype(rng) for _ in range(8)])
    D = neutral.shapedirs.reshape(-1, 10)
    errs = []
    for body in bodies:
        off = (body - neutral.v_template).ravel()
        betas = np.linalg.lstsq(D, off, rcond=None)[0]
        errs.append(np.linalg.norm((D @ betas - off).reshape(-1, 3), axis=1).mean() * 1e3)
        assert np.linalg.norm(off.reshape(-1, 3), axis=1).mean() * 1e3 > 15  # they do differ from the template
    assert max(errs) < 6.0 and np.mean(errs) < 3.0, errs


def test_files_load_plain_and_are_deterministic(tmp_path, neutral):
    paths = S.write_test_models(tmp_path)
    assert [p.name for p in paths] == ["SMPL_NEUTRAL.pkl", "SMPL_MALE.pkl", "SMPL_FEMALE.pkl"]
    for gender in ("neutral", "male", "female"):
        m = load_body_model(find_model_file(tmp_path, "smpl", gender), "smpl", gender)
        assert m.n_vertices == 6890 and m.n_joints == 24 and m.n_betas == 10
    with open(paths[0], "rb") as fh:
        raw = pickle.load(fh, encoding="latin1")  # the clients' way: plain numpy arrays, no chumpy
    for k in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f", "J"):
        assert type(raw[k]) is np.ndarray, k
    assert raw["rh_standin"]["note"].startswith("not SMPL")
    assert np.array_equal(raw["v_template"], neutral.v_template)
    male, female = (load_body_model(p) for p in paths[1:])
    assert np.abs(male.v_template - female.v_template).max() > 0.02  # two different bodies
    assert np.ptp(male.v_template[:, 1]) > np.ptp(female.v_template[:, 1])  # anny: gender 0 is the male end
    for m in (male, female):
        J = m.J_regressor @ m.v_template
        assert np.abs(J[[20, 21], 1] - J[[16, 17], 1]).max() < 0.005  # T-pose: wrists at shoulder height
    # Deterministic bytes: an uncached rebuild writes the same file.
    again = tmp_path / "again.pkl"
    write_smpl_pickle(again, S._build("neutral")[0])
    assert hashlib.sha256(again.read_bytes()).hexdigest() == hashlib.sha256(paths[0].read_bytes()).hexdigest()


def test_cli_writes_the_stand_in(tmp_path, capsys):
    from rh_dataset.export.cli import build_parser, main

    assert "not SMPL" in " ".join(build_parser().format_help().split())
    assert main(["--write-test-smpl", str(tmp_path / "models")]) == 0
    assert sorted(p.name for p in (tmp_path / "models").iterdir()) == ["SMPL_FEMALE.pkl", "SMPL_MALE.pkl",
                                                                      "SMPL_NEUTRAL.pkl"]
    assert "not SMPL" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["--format", "usd"])  # an export still needs --dataset and --out
    (tmp_path / "file").write_text("")
    assert main(["--write-test-smpl", str(tmp_path / "file")]) == 2  # not a folder: one line, exit 2
    assert "pass a folder you can write to" in capsys.readouterr().err


@pytest.mark.slow
def test_bytes_do_not_depend_on_blas_threads(tmp_path):
    """The file's bytes are the same whatever the BLAS thread count (the build keeps big products out of BLAS)."""
    import os
    import subprocess
    import sys

    digests = []
    for n in ("1", "2"):
        env = dict(os.environ, OPENBLAS_NUM_THREADS=n, OMP_NUM_THREADS=n, MKL_NUM_THREADS=n)
        code = ("import sys; from rh_dataset.smpl.model import write_smpl_pickle; "
                "from rh_dataset.smpl.standin import build_standin; "
                "write_smpl_pickle(sys.argv[1], build_standin('neutral'))")
        out = tmp_path / f"t{n}.pkl"
        subprocess.run([sys.executable, "-c", code, str(out)], check=True, env=env)
        digests.append(hashlib.sha256(out.read_bytes()).hexdigest())
    assert digests[0] == digests[1]
