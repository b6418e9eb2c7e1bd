"""rh_dataset.smpl.fit: the fit recovers a body the model itself made, is bitwise deterministic, refuses a bad
frame by name, and fits a posed anny body within the documented thresholds (slow)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from rh_dataset.smpl.fit import (FitInput, FitQuality, FitRefused, FitSettings, FrameTarget,  # noqa: E402
                                 camera_frame, check_quality, fit_subject)
from rh_dataset.smpl.standin import build_standin  # noqa: E402
from rh_dataset.smpl.standin_pose import example_pose  # noqa: E402

# A body facing an OpenCV camera 3 m away: SMPL's +Y up is the camera's −Y, its +Z (facing) the camera's −Z.
FACING_CAMERA = np.array([np.pi, 0.0, 0.0])
QUICK = FitSettings(joint_iterations=4, surface_rounds=1, surface_iterations=1)


@pytest.fixture(scope="module")
def standin():
    return build_standin("neutral")


def _t(a):
    return torch.as_tensor(np.asarray(a, np.float64))


def _made_by_the_model(model, betas, poses, orients, trans):
    V, J = camera_frame(model, _t(np.repeat(betas[None], len(poses), 0)), _t(poses), _t(orients), _t(trans))
    return tuple(FrameTarget(f"frame {i}", V[i].numpy(), model.faces, J[i].numpy()) for i in range(len(poses)))


def test_recovers_a_body_the_model_made(standin):
    """Known betas and pose → the model's own surface; the fit lands on it (sub-millimetre on average) and its
    outputs are the clients' formula of its own parameters."""
    rng = np.random.default_rng(3)
    betas = rng.normal(size=10) * 0.7
    pose = example_pose()[1:].reshape(1, 69)
    orient = (FACING_CAMERA + [0.0, 0.3, 0.0])[None]
    frames = _made_by_the_model(standin, betas, pose, orient, np.array([[0.05, 0.1, 3.0]]))
    fit = fit_subject(FitInput(standin, frames), log=None)
    q = fit.frames[0].quality
    assert q.model_to_anny_mean_mm < 1.0 and q.anny_to_model_mean_mm < 1.0, q
    assert q.joint_mean_mm < 2.0, q
    f = fit.frames[0]
    V, J = camera_frame(standin, _t(fit.betas[None]), _t(f.pose[None]), _t(f.global_orient[None]),
                        _t(f.global_trans[None]), fit.scale)
    assert np.allclose(V[0].numpy(), f.vertices, atol=1e-9) and np.allclose(J[0].numpy(), f.joints, atol=1e-9)
    assert fit.betas.shape == (10,) and f.pose.shape == (69,) and fit.scale == 1.0
    # The root joint is where global_trans says (x_cam = scale · (V − J0) + global_trans).
    assert np.allclose(f.joints[0], f.global_trans, atol=1e-12)


def test_bitwise_deterministic_and_shared_betas(standin):
    pose = example_pose()[1:].reshape(1, 69)
    poses = np.concatenate([pose, 0.5 * pose])
    frames = _made_by_the_model(standin, np.zeros(10), poses, np.stack([FACING_CAMERA] * 2),
                                np.array([[0.0, 0.1, 3.0], [0.2, 0.1, 3.5]]))
    a = fit_subject(FitInput(standin, frames, QUICK), log=None)
    b = fit_subject(FitInput(standin, frames, QUICK), log=None)
    assert a.betas.tobytes() == b.betas.tobytes()
    for fa, fb in zip(a.frames, b.frames):
        assert fa.pose.tobytes() == fb.pose.tobytes() and fa.vertices.tobytes() == fb.vertices.tobytes()
    # Given betas (a rerun's cached ones) are kept exactly; only poses are fitted.
    c = fit_subject(FitInput(standin, frames, QUICK, betas=a.betas), log=None)
    assert c.betas.tobytes() == a.betas.tobytes()


def test_refuses_a_frame_above_the_thresholds():
    good = FitQuality(2.0, 30.0, 2.0, 30.0, 5.0, 10.0)
    check_quality([("subject_000/train/000001", good)], FitSettings())
    for bad in (dataclasses.replace(good, anny_to_model_mean_mm=40.0),
                dataclasses.replace(good, model_to_anny_max_mm=300.0)):
        with pytest.raises(FitRefused, match=r"subject_000/train/000001: .*--smpl-max-mean-mm"):
            check_quality([("subject_000/train/000000", good), ("subject_000/train/000001", bad)], FitSettings())


@pytest.mark.slow
def test_fits_a_posed_anny_body_within_the_thresholds(standin):
    """The stand-in fitted to anny posed by the pose prior, as the export builds the frame's target."""
    from pathlib import Path

    from rh_common.body_model import load_anny
    from rh_dataset.export.common import FrameRef
    from rh_dataset.export.smpl import frame_target
    from rh_dataset.poses import sample_pose

    rng = np.random.default_rng(15)
    phen = dict(gender=0.3, age=0.5, muscle=0.6, weight=0.6, height=0.7, proportions=0.5)
    w2c = [[1.0, 0, 0, 0], [0, 0, -1, 0.9], [0, 1, 0, 3.0], [0, 0, 0, 1]]  # world Z up → OpenCV, 3 m in front
    frames = tuple(frame_target(FrameRef("subject_000", "train", i, Path("."), {
        "body": {"pose": sample_pose(rng, load_anny()).to_json(), "phenotype": phen},
        "camera": {"world_to_camera": w2c}})) for i in range(2))
    fit = fit_subject(FitInput(standin, frames))
    check_quality([(f.name, f.quality) for f in fit.frames], FitSettings())
    for f in fit.frames:
        assert f.quality.model_to_anny_mean_mm < 5.0 and f.quality.anny_to_model_mean_mm < 5.0, f.quality
