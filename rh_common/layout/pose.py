"""The reader of a frame's `body.pose` (docs/ARCHITECTURE.md, "Re-posing the body from a frame").

In: the JSON object `body.pose` of an anny frame: `parameterization` ('local-ref'), `bones` {label: 4x4, identity
bones omitted}, optional `root_transform` (4x4), `turntable_deg`, `label`.
Out: `PoseArrays` (float64 matrices) and, for a rig's bone order, the (J, 4, 4) deltas a body model takes.

The generator builds poses with its own `rh_dataset.poses.BodyPose` and writes them with `BodyPose.to_json`; this
is the one place that reads the format back for everyone else (rana, the exporters), so it needs no generator.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import numpy as np

__all__ = ["PoseArrays", "read_body_pose", "rigid_matrix", "ORTHO_TOL"]

_KEYS = {"bones", "label", "parameterization", "root_transform", "turntable_deg"}
ORTHO_TOL = 1e-6  # |R^T R - I| and |det R - 1|: float64 products of a few rotations stay ~1e-15 off


@dataclasses.dataclass(frozen=True)
class PoseArrays:
    bones: Mapping[str, np.ndarray]  # label -> (4, 4) float64 local-ref delta; unlisted bones are identity
    root_transform: np.ndarray  # (4, 4) float64 rigid map applied to the skinned vertices
    turntable_deg: float = 0.0
    label: str = "a-pose"

    def deltas(self, bone_labels: Sequence[str]) -> np.ndarray:
        """(J, 4, 4) float64 deltas in the order of `bone_labels`; a listed bone the rig lacks is an error."""
        labels = list(bone_labels)
        if unknown := sorted(set(self.bones) - set(labels)):
            raise ValueError(f"pose: unknown bone(s) {unknown} (not in the rig)")
        D = np.tile(np.eye(4), (len(labels), 1, 1))
        for name, M in self.bones.items():
            D[labels.index(name)] = M
        return D


def rigid_matrix(name: str, value: Any, *, translation_allowed: bool = True) -> np.ndarray:
    """`value` as a read-only float64 4x4 rigid transform (a proper rotation, bottom row [0, 0, 0, 1]), or a
    ValueError naming `name` and what is wrong. The generator's `BodyPose` checks the poses it builds with this too,
    so a pose it writes is exactly a pose this reader accepts."""
    try:
        M = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not a numeric 4x4 matrix") from exc
    if M.shape != (4, 4):
        raise ValueError(f"{name}: expected shape (4, 4), got {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{name}: non-finite values")
    if np.any(M[3] != (0.0, 0.0, 0.0, 1.0)):
        raise ValueError(f"{name}: bottom row must be exactly [0, 0, 0, 1]")
    R = M[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > ORTHO_TOL or abs(np.linalg.det(R) - 1.0) > ORTHO_TOL:
        raise ValueError(f"{name}: rotation block is not a proper rotation (orthonormal, det +1)")
    if not translation_allowed and np.any(M[:3, 3] != 0.0):
        raise ValueError(f"{name}: only the root may carry a translation in a local-ref delta")
    M.setflags(write=False)
    return M


def read_body_pose(pose_json: Mapping[str, Any]) -> PoseArrays:
    """Read `body.pose`; unknown keys and another parameterisation are refused."""
    if unknown := set(pose_json) - _KEYS:
        raise ValueError(f"pose: unknown keys {sorted(unknown)}")
    if pose_json.get("parameterization", "local-ref") != "local-ref":
        raise ValueError(f"pose: only 'local-ref' is supported, got {pose_json['parameterization']!r}")
    bones = {str(k): rigid_matrix(f"pose: bone {k!r}", v) for k, v in pose_json.get("bones", {}).items()}
    root = rigid_matrix("pose: root_transform", pose_json.get("root_transform", np.eye(4)))
    return PoseArrays(bones, root, float(pose_json.get("turntable_deg", 0.0)), str(pose_json.get("label", "a-pose")))
