"""The generic skeleton (rh_dataset.poses.skeleton) poses exactly like anny's own kinematics and skinning."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.body_model import load_anny
from rh_dataset.poses import sample_pose
from rh_dataset.poses.rig import rig_for
from rh_dataset.poses.skeleton import Skeleton, SkeletonPose, posed_heads, posed_rotations, skin, \
    skinning_transforms


def _rot(axis, deg):
    a = np.radians(deg)
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


@pytest.fixture(scope="module")
def anny_rig():
    return rig_for(load_anny())


def _anny_skeleton(rig):
    W0 = rig.world_poses(np.tile(np.eye(4), (len(rig.parents), 1, 1)))
    heads = W0[:, :3, 3]
    tails = heads + W0[:, :3, 1] * 0.1  # anny's bones point along their local +Y
    return Skeleton(rig.bone_labels, rig.parents, heads, tails)


def test_matches_anny_kinematics(anny_rig):
    """Same deltas, same posed joints and world rotations as anny's 'local-ref' chain (rig.py, checked against
    anny itself in test_poses)."""
    pose = sample_pose(np.random.default_rng(7), load_anny())
    D = pose.deltas()
    W = anny_rig.world_poses(D)
    skel = _anny_skeleton(anny_rig)
    sp = SkeletonPose(D[:, :3, :3], D[0, :3, 3])
    G = posed_rotations(skel, sp)
    np.testing.assert_allclose(posed_heads(skel, sp, G), W[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(G, W[:, :3, :3] @ np.transpose(anny_rig.reference_orientations, (0, 2, 1)),
                               atol=1e-9)


def test_skinning_transforms_compose_with_anny(anny_rig):
    """anny skins from its rest mesh with W_c P_c^-1 = (W_c W0_c^-1)(W0_c P_c^-1), W0 the reference pose: our
    per-bone transform from the reference pose must be exactly the first factor."""
    pose = sample_pose(np.random.default_rng(3), load_anny())
    D = pose.deltas()
    skel = _anny_skeleton(anny_rig)
    W0 = anny_rig.world_poses(np.tile(np.eye(4), (len(D), 1, 1)))
    W = anny_rig.world_poses(D)
    T = skinning_transforms(skel, SkeletonPose(D[:, :3, :3], D[0, :3, 3]))
    T4 = np.tile(np.eye(4), (len(D), 1, 1))
    T4[:, :3] = T
    np.testing.assert_allclose(T4 @ W0, W, atol=1e-9)
    # ... and skinning a point bound to one bone only reproduces anny's skinning of it.
    v = np.flatnonzero(anny_rig.weights.max(1) > 0.999)[:50]
    ref_pts, _ = anny_rig.skin(W0, v)
    want, _ = anny_rig.skin(W, v)
    got, _ = skin(ref_pts, anny_rig.weight_bones[v], anny_rig.weights[v], T)
    np.testing.assert_allclose(got, want, atol=1e-6)


def test_rest_pose_is_identity_and_child_swings_about_parent_head():
    skel = Skeleton(("hip", "knee", "ankle"), np.array([-1, 0, 1]),
                    heads=np.array([[0, 0, 1.0], [0, 0, 0.5], [0, 0, 0.0]]),
                    tails=np.array([[0, 0, 0.5], [0, 0, 0.0], [0, -0.1, 0.0]]))
    T = skinning_transforms(skel, SkeletonPose.rest(skel))
    np.testing.assert_array_equal(T[:, :, :3], np.tile(np.eye(3), (3, 1, 1)))
    np.testing.assert_array_equal(T[:, :, 3], 0)
    R = np.tile(np.eye(3), (3, 1, 1))
    R[1] = _rot((1, 0, 0), 90)  # bend the knee 90 degrees about +X
    pose = SkeletonPose(R, np.array([0.0, 0.0, 0.2]))
    heads = posed_heads(skel, pose)
    np.testing.assert_allclose(heads[:2], [[0, 0, 1.2], [0, 0, 0.7]], atol=1e-12)
    np.testing.assert_allclose(heads[2], [0, 0.5, 0.7], atol=1e-12)  # the shin now points along +Y
    pts, n = skin(np.array([[0, 0, 0.25]]), np.array([[1]]), np.array([[1.0]]),
                  skinning_transforms(skel, pose), rest_normals=np.array([[0, -1.0, 0]]))
    np.testing.assert_allclose(pts, [[0, 0.25, 0.7]], atol=1e-12)
    np.testing.assert_allclose(n, [[0, 0, -1.0]], atol=1e-12)


def test_rejects_bad_input():
    with pytest.raises(ValueError, match="precede"):
        Skeleton(("a", "b"), np.array([1, -1]), np.zeros((2, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="unique"):
        Skeleton(("a", "a"), np.array([-1, 0]), np.zeros((2, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="proper rotations"):
        SkeletonPose(np.array([np.diag([1.0, 1.0, -1.0])]))
