"""`BodyPose`: one body pose on anny's rig, and the protocol-A turntable.

A pose is anny's 'local-ref' deltas (world-aligned axes at each bone head, composed down the chain; identity =
anny's reference pose, an A-pose with the root head at the origin) plus a rigid `root_transform` applied to the
skinned vertices afterwards. Only the turntable uses `root_transform`; sampled poses put their yaw in the root
bone so that what anny computes (joints, vertices) is already the final pose.

Note on "rest": anny's identity deltas give its *reference* pose, built from fixed reference bone orientations,
which is not bit-identical to `rest_vertices` (the phenotype's own rest orientations): for the default body the
two differ by up to ~1.2 cm at the hands, besides the rest root head sitting ~5 cm off the origin. The A-pose here
is the reference pose, which is the same pose for every body shape.
"""
from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from rh_common.layout import rigid_matrix

__all__ = ["BodyPose", "ANNY_BONE_LABELS", "POSE_LABELS", "turntable", "rotation_about_z"]

# anny's default rig ('anny', 104 bones), in model order; a test checks it against the installed model. Kept here
# so that a pose can be validated and (de)serialised without loading the body model.
ANNY_BONE_LABELS: tuple[str, ...] = tuple(
    ["root"]
    + [f"{b}.L" for b in ("pelvis", "upperleg01", "upperleg02", "lowerleg01", "lowerleg02", "foot")]
    + ["toe1-1.L", "toe1-2.L"] + [f"toe{t}-{p}.L" for t in (2, 3, 4, 5) for p in (1, 2, 3)]
    + [f"{b}.R" for b in ("pelvis", "upperleg01", "upperleg02", "lowerleg01", "lowerleg02", "foot")]
    + ["toe1-1.R", "toe1-2.R"] + [f"toe{t}-{p}.R" for t in (2, 3, 4, 5) for p in (1, 2, 3)]
    + ["spine05", "spine04", "spine03", "spine02", "spine01"]
    + [f"{b}.L" for b in ("clavicle", "shoulder01", "upperarm01", "upperarm02", "lowerarm01", "lowerarm02",
                          "wrist")]
    + [f"{n}.L" for f in range(1, 6) for n in
       ([f"finger{f}-1", f"finger{f}-2", f"finger{f}-3"] + ([f"metacarpal{f}"] if f < 5 else []))]
    + [f"{b}.R" for b in ("clavicle", "shoulder01", "upperarm01", "upperarm02", "lowerarm01", "lowerarm02",
                          "wrist")]
    + [f"{n}.R" for f in range(1, 6) for n in
       ([f"finger{f}-1", f"finger{f}-2", f"finger{f}-3"] + ([f"metacarpal{f}"] if f < 5 else []))]
    + ["neck01", "neck02", "neck03", "head", "eye.L", "eye.R"]
)
_BONE_SET = frozenset(ANNY_BONE_LABELS)

POSE_LABELS = ("a-pose", "stand", "walk", "reach", "bend", "sit", "arms-crossed", "random")


def rotation_about_z(deg: float, pivot: np.ndarray | None = None) -> np.ndarray:
    """4x4 rigid transform: rotation of `deg` degrees about +Z (counter-clockwise seen from above) through
    `pivot` (default the origin)."""
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    T = np.eye(4)
    T[:2, :2] = ((c, -s), (s, c))
    if pivot is not None:
        p = np.asarray(pivot, dtype=np.float64)
        T[:3, 3] = p - T[:3, :3] @ p
    return T


@dataclasses.dataclass(frozen=True)
class BodyPose:
    """One pose of anny's body.

    bones: bone label -> 4x4 'local-ref' delta; only non-identity bones are listed; rotation-only except 'root',
        whose translation is the global position of the pelvis (root head).
    root_transform: 4x4 rigid transform applied to the skinned vertices (and joints) afterwards: the turntable
        rotation about +Z through the pelvis position; identity otherwise.
    turntable_deg: the turntable angle that `root_transform` encodes (0 for non-turntable poses).
    label: what the pose is ('a-pose', 'walk', 'reach', 'bend', 'sit', 'arms-crossed', 'stand', 'random').
    """

    bones: Mapping[str, np.ndarray]
    root_transform: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(4))
    turntable_deg: float = 0.0
    label: str = "a-pose"

    def __post_init__(self) -> None:
        if not isinstance(self.bones, Mapping):
            raise ValueError("bones must be a mapping bone label -> 4x4 matrix")
        bones = {}
        for name in sorted(self.bones):
            if name not in _BONE_SET:
                raise ValueError(f"unknown bone label {name!r} (not one of anny's 104 bones)")
            M = rigid_matrix(f"bone {name!r}", self.bones[name], translation_allowed=name == "root")
            if not np.array_equal(M, np.eye(4)):  # identity bones are implied; dropping them keeps JSON canonical
                bones[name] = M
        object.__setattr__(self, "bones", MappingProxyType(bones))
        object.__setattr__(self, "root_transform",
                           rigid_matrix("root_transform", self.root_transform, translation_allowed=True))
        if isinstance(self.turntable_deg, bool) or not isinstance(self.turntable_deg, (int, float)) \
                or not math.isfinite(self.turntable_deg):
            raise ValueError(f"turntable_deg must be a finite number, got {self.turntable_deg!r}")
        object.__setattr__(self, "turntable_deg", float(self.turntable_deg))
        if not isinstance(self.label, str) or not self.label:
            raise ValueError("label must be a non-empty string")

    # Dataclass equality would compare arrays elementwise and fail; compare exactly instead.
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, BodyPose):
            return NotImplemented
        return (self.label == other.label and self.turntable_deg == other.turntable_deg
                and np.array_equal(self.root_transform, other.root_transform)
                and self.bones.keys() == other.bones.keys()
                and all(np.array_equal(self.bones[k], other.bones[k]) for k in self.bones))

    __hash__ = None  # type: ignore[assignment]  # mutable-looking contents: not hashable

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (sorted keys, matrices as nested lists of Python floats, so that `json.dumps` then
        `from_json` gives back bit-identical arrays). `parameterization` and `bones` match the frame JSON's
        `body.pose`."""
        return {
            "bones": {k: self.bones[k].tolist() for k in sorted(self.bones)},
            "label": self.label,
            "parameterization": "local-ref",
            "root_transform": self.root_transform.tolist(),
            "turntable_deg": self.turntable_deg,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any] | str) -> BodyPose:
        """Inverse of `to_json`; accepts the dict or its JSON text. Unknown keys are rejected."""
        if isinstance(data, str):
            data = json.loads(data)
        known = {"bones", "label", "parameterization", "root_transform", "turntable_deg"}
        if unknown := set(data) - known:
            raise ValueError(f"unknown BodyPose keys: {sorted(unknown)}")
        if data.get("parameterization", "local-ref") != "local-ref":
            raise ValueError(f"only the 'local-ref' parameterisation is supported, got {data['parameterization']!r}")
        return cls(bones={k: np.array(v, dtype=np.float64) for k, v in data["bones"].items()},
                   root_transform=np.array(data.get("root_transform", np.eye(4)), dtype=np.float64),
                   turntable_deg=data.get("turntable_deg", 0.0), label=data.get("label", "a-pose"))

    def deltas(self) -> np.ndarray:
        """(104, 4, 4) float64 deltas in anny's bone order, identity for unlisted bones."""
        D = np.tile(np.eye(4), (len(ANNY_BONE_LABELS), 1, 1))
        for i, name in enumerate(ANNY_BONE_LABELS):
            if name in self.bones:
                D[i] = self.bones[name]
        return D

    def as_anny_tensor(self, model):
        """(1, 104, 4, 4) torch tensor for `model(pose_parameters=...)`, in the model's dtype and device."""
        import torch

        if tuple(model.bone_labels) != ANNY_BONE_LABELS:
            raise ValueError("the model's bones differ from anny's default 104-bone rig")
        ref = model.template_vertices
        return torch.as_tensor(self.deltas(), dtype=ref.dtype, device=ref.device)[None]

    def apply_root_transform(self, points: np.ndarray) -> np.ndarray:
        """Apply `root_transform` to (..., 3) points (e.g. anny's vertices or joints)."""
        points = np.asarray(points, dtype=np.float64)
        return points @ self.root_transform[:3, :3].T + self.root_transform[:3, 3]


def turntable(n_frames: int) -> list[BodyPose]:
    """Protocol A (train): the A-pose turned about +Z through the pelvis, frame i at exactly 360·i/n degrees."""
    if isinstance(n_frames, bool) or not isinstance(n_frames, int) or n_frames < 1:
        raise ValueError(f"n_frames must be a positive integer, got {n_frames!r}")
    # With identity deltas the pelvis (root head) sits at the origin, so the pivot is the origin.
    return [BodyPose(bones={}, root_transform=rotation_about_z(360.0 * i / n_frames),
                     turntable_deg=360.0 * i / n_frames, label="a-pose") for i in range(n_frames)]
