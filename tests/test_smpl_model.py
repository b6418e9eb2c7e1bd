"""rh_dataset.smpl.model: reading SMPL files as users download them (chumpy objects, scipy sparse, Python 2
pickles) without chumpy or scipy, and the forward pass's defining properties."""
from __future__ import annotations

import pickle
import sys
import types

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from rh_dataset.smpl.model import (BodyModel, SmplModelError, find_model_file, forward, load_body_model,  # noqa: E402
                                   rodrigues, write_smpl_pickle)

SMPL_PARENTS = np.array([-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21])


def _random_model(V=60, seed=0) -> BodyModel:
    rng = np.random.default_rng(seed)
    J = 24
    jr = np.abs(rng.normal(size=(J, V)))
    w = rng.random((V, J)) ** 4
    return BodyModel("smpl", "neutral", rng.normal(size=(V, 3)), rng.normal(size=(V, 3, 10)) * 0.02,
                     rng.normal(size=(V, 3, 207)) * 0.01, jr / jr.sum(1, keepdims=True), w / w.sum(1, keepdims=True),
                     SMPL_PARENTS.copy(), rng.integers(0, V, size=(40, 3)))


def _t(a):
    return torch.as_tensor(np.asarray(a, np.float64)[None])


def test_plain_pickle_round_trip(tmp_path):
    m = _random_model()
    write_smpl_pickle(tmp_path / "SMPL_NEUTRAL.pkl", m)
    m2 = load_body_model(find_model_file(tmp_path))
    for k in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights"):
        assert np.array_equal(getattr(m2, k), getattr(m, k)), k
    assert np.array_equal(m2.parents, SMPL_PARENTS) and np.array_equal(m2.faces, m.faces)
    assert len(m2.sha256) == 64


def _chumpy_like_pickle(path, m: BodyModel):
    """Pickle `m` the way SMPL's downloads are: arrays wrapped in chumpy.ch.Ch (value in state['x']), the joint
    regressor a scipy.sparse csc_matrix, under module names that need not be importable when reading."""
    ch_mod = types.ModuleType("chumpy.ch")
    sp_mod = types.ModuleType("scipy.sparse.csc")

    class Ch:
        def __init__(self, x):
            self.x = x
            self._dirty_vars = set()

    class csc_matrix:
        def __init__(self, dense):
            data, indices, indptr = [], [], [0]
            for c in range(dense.shape[1]):
                nz = np.nonzero(dense[:, c])[0]
                data += list(dense[nz, c])
                indices += list(nz)
                indptr.append(len(data))
            self.data, self.indices, self.indptr = np.array(data), np.array(indices, np.int32), np.array(indptr)
            self._shape = dense.shape
            self.maxprint = 50

    Ch.__module__, Ch.__qualname__ = "chumpy.ch", "Ch"
    csc_matrix.__module__, csc_matrix.__qualname__ = "scipy.sparse.csc", "csc_matrix"
    ch_mod.Ch, sp_mod.csc_matrix = Ch, csc_matrix
    saved = {k: sys.modules.get(k) for k in ("chumpy", "chumpy.ch", "scipy.sparse.csc")}
    sys.modules["chumpy"] = types.ModuleType("chumpy")
    sys.modules["chumpy.ch"], sys.modules["scipy.sparse.csc"] = ch_mod, sp_mod
    try:
        jr = m.J_regressor.copy()
        jr[jr < np.quantile(jr, 0.7)] = 0  # sparse, as SMPL's is
        data = {"v_template": Ch(m.v_template), "shapedirs": Ch(m.shapedirs), "posedirs": m.posedirs,
                "J_regressor": csc_matrix(jr), "weights": Ch(m.weights),
                "kintree_table": np.stack([np.r_[4294967295, SMPL_PARENTS[1:]], np.arange(24)]).astype(np.uint32),
                "f": m.faces.astype(np.uint32), "bs_type": "lrotmin", "bs_style": "lbs", "J": Ch(jr @ m.v_template)}
        with open(path, "wb") as fh:
            pickle.dump(data, fh, protocol=2)
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    return jr


def test_reads_chumpy_and_sparse_without_importing_them(tmp_path):
    m = _random_model()
    path = tmp_path / "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl"
    jr = _chumpy_like_pickle(path, m)
    assert "chumpy" not in sys.modules
    got = load_body_model(find_model_file(tmp_path))
    assert "chumpy" not in sys.modules
    assert np.array_equal(got.v_template, m.v_template) and np.array_equal(got.shapedirs, m.shapedirs)
    assert np.array_equal(got.weights, m.weights) and np.array_equal(got.J_regressor, jr)
    assert got.parents[0] == -1 and np.array_equal(got.parents[1:], SMPL_PARENTS[1:])


def test_rest_pose_is_the_shaped_template():
    m = _random_model()
    betas = np.random.default_rng(1).normal(size=10)
    v, j = forward(m, _t(betas), _t(np.zeros(69)), _t(np.zeros(3)))
    shaped = m.v_template + m.shapedirs @ betas
    assert np.allclose(v[0].numpy(), shaped, atol=1e-12)
    assert np.allclose(j[0].numpy(), m.J_regressor @ shaped, atol=1e-12)


def test_root_rotates_about_its_joint_and_translation_adds():
    m = _random_model()
    aa = np.array([0.3, -1.1, 0.7])
    trans = np.array([0.1, 2.0, -0.5])
    v, j = forward(m, _t(np.zeros(10)), _t(np.zeros(69)), _t(aa), _t(trans))
    R = rodrigues(torch.as_tensor(aa)).numpy()
    J0 = (m.J_regressor @ m.v_template)[0]
    # Pose blend shapes see only joints 1..23, so a root-only pose is a rigid motion about J0.
    assert np.allclose(v[0].numpy(), (m.v_template - J0) @ R.T + J0 + trans, atol=1e-12)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14) and np.isclose(np.linalg.det(R), 1)


def test_vertex_bound_to_one_joint_moves_with_it():
    m = _random_model()
    w = m.weights.copy()
    w[0] = 0
    w[0, 18] = 1  # left elbow's child chain
    m = BodyModel(**{**m.__dict__, "weights": w, "posedirs": np.zeros_like(m.posedirs)})
    pose = np.random.default_rng(2).normal(size=69) * 0.4
    v, j = forward(m, _t(np.zeros(10)), _t(pose), _t(np.zeros(3)))
    v_rest, _ = forward(m, _t(np.zeros(10)), _t(np.zeros(69)), _t(np.zeros(3)))
    # The distance from the vertex to joint 18 and to its parent chain is preserved (rigid with bone 18).
    J = m.J_regressor @ m.v_template
    assert np.isclose(np.linalg.norm(v[0, 0].numpy() - j[0, 18].numpy()), np.linalg.norm(m.v_template[0] - J[18]))
    assert np.isclose(np.linalg.norm(j[0, 18].numpy() - j[0, 16].numpy()), np.linalg.norm(J[18] - J[16]))


def test_rodrigues_gradient_is_finite_at_zero():
    aa = torch.zeros(1, 3, dtype=torch.float64, requires_grad=True)
    rodrigues(aa).sum().backward()
    assert torch.isfinite(aa.grad).all()


def test_bad_files_get_one_line_errors(tmp_path):
    bad = tmp_path / "SMPL_NEUTRAL.pkl"
    bad.write_bytes(b"not a pickle")
    with pytest.raises(SmplModelError, match="SMPL_NEUTRAL.pkl: not a readable"):
        load_body_model(bad)
    m = _random_model()
    wrong = BodyModel(**{**m.__dict__, "posedirs": m.posedirs[:, :, :100]})
    write_smpl_pickle(bad, wrong)
    with pytest.raises(SmplModelError, match="posedirs must be"):
        load_body_model(bad)
    with open(bad, "wb") as fh:
        pickle.dump({"v_template": np.zeros((3, 3))}, fh)
    with pytest.raises(SmplModelError, match="missing shapedirs"):
        load_body_model(bad)
    with pytest.raises(SmplModelError, match="no SMPL male model file"):
        find_model_file(tmp_path, gender="male")
    with open(bad, "wb") as fh:  # a pickle that would run code: refused, not executed
        fh.write(pickle.dumps(__import__("os").system))
    with pytest.raises(SmplModelError, match="refusing to load"):
        load_body_model(bad)
