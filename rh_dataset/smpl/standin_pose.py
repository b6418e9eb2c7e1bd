"""Posing anny as the SMPL stand-in is posed, for comparing the two (`standin.py` builds the stand-in).

In: a SMPL pose (parent-relative axis-angle of the 24 joints, SMPL's axes) and an anny rig. Out: anny 'local-ref'
bone deltas that give anny's own forward pass the same joint rotations (`anny_pose_from_smpl`), and a moderate
example pose the tests and bench/smpl_standin.py use.
"""
from __future__ import annotations

import numpy as np

from rh_dataset.poses.rig import Rig

from .standin import ANNY_TO_SMPL, SMPL_PARENTS, bone_joint_map, local_ref_deltas, tpose_rotations
from .standin import SMPL_JOINT_NAMES

__all__ = ["anny_pose_from_smpl", "example_pose"]


def anny_pose_from_smpl(rig: Rig, full_pose: np.ndarray) -> dict[str, np.ndarray]:
    """anny 'local-ref' deltas (label -> 4x4) that pose `rig`'s body as the stand-in poses it for SMPL's
    parent-relative axis-angle `full_pose` (24,3: global_orient, then joints 1-23); translation not included.

    Each bone turns with its SMPL joint's world rotation (SMPL axes turned into anny's) on top of its T-pose
    rotation. Exact, up to the J_regressor's residual, wherever a joint's group hangs from one bone; the foot and
    hand joints turn five toes / four fingers, each about its own base in anny but about their mean in the
    stand-in, so keep those two joints near zero when comparing the two."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(np.asarray(full_pose, np.float64).reshape(-1, 3)).as_matrix()
    Gs = np.empty_like(R)
    for k, p in enumerate(SMPL_PARENTS):
        Gs[k] = R[k] if p < 0 else Gs[p] @ R[k]
    Ga = np.einsum("ba,kbc,cd->kad", ANNY_TO_SMPL, Gs, ANNY_TO_SMPL)  # C^T Gs C: the same turn in anny's axes
    owner = bone_joint_map(rig.bone_labels, rig.parents)
    G = np.einsum("cab,cbd->cad", Ga[owner], tpose_rotations(rig))
    D = local_ref_deltas(rig.parents, G)
    return {label: D[i] for i, label in enumerate(rig.bone_labels)}


def example_pose() -> np.ndarray:
    """A moderate SMPL pose, parent-relative axis-angle (24,3): a walk-like step, bent elbows and knees, a turned
    torso and head, the foot and hand joints at zero (see `anny_pose_from_smpl`). What the tests and
    bench/smpl_standin.py compare the stand-in against anny with."""
    p = np.zeros((24, 3))
    n = {k: i for i, k in enumerate(SMPL_JOINT_NAMES)}
    p[n["pelvis"]] = (0.1, 0.4, 0.0)
    p[n["L_hip"]], p[n["R_hip"]] = (-0.5, 0.0, 0.1), (0.3, 0.0, -0.1)
    p[n["L_knee"]], p[n["R_knee"]] = (0.8, 0.0, 0.0), (0.3, 0.0, 0.0)
    p[n["L_ankle"]] = (0.2, 0.1, 0.0)
    p[n["spine1"]], p[n["spine2"]], p[n["spine3"]] = (0.1, 0.1, 0.0), (0.05, 0.1, 0.05), (0.0, 0.1, 0.0)
    p[n["neck"]], p[n["head"]] = (0.2, -0.2, 0.0), (0.1, -0.2, 0.1)
    p[n["L_collar"]], p[n["R_collar"]] = (0.0, 0.0, 0.1), (0.0, 0.0, -0.1)
    p[n["L_shoulder"]], p[n["R_shoulder"]] = (0.0, -0.3, -0.9), (0.2, 0.3, 1.0)
    p[n["L_elbow"]], p[n["R_elbow"]] = (0.0, -1.2, 0.0), (0.0, 0.7, 0.0)
    p[n["L_wrist"]], p[n["R_wrist"]] = (0.3, 0.0, 0.2), (-0.2, 0.0, 0.0)
    return p
