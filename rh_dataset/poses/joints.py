"""Anatomical joint frames and limits on anny's rig.

Every posed joint is described by three angles in degrees, measured from an anatomical zero ("neutral"):
    flex  — swing that moves the bone's tail towards `flex_to` (e.g. forward for a hip, backward for a knee),
    abd   — swing that moves it towards `abd_to` (laterally for limbs, to the character's left for the spine),
    twist — rotation about the bone's own axis (for limbs positive = internal rotation on both sides).
A delta is built as D = Swing(flex·k_f + abd·k_a) · Twist(twist·t) · N, where N rotates the reference bone
direction to the neutral one (arm hanging down for the shoulder, straight arm for the elbow, identity elsewhere).
The root is the exception: D = Twist(yaw about +Z) · Swing(pitch, roll), so that a bow happens in the body's own
frame before it is turned.

Axes come from anny's reference bone orientations (`reference_bone_orientations`, the same for every body shape),
never from hard-coded world axes, so the frames follow the rig. See `rig.py` for why a delta's axes are the
reference-pose world axes whatever the parents do.

Limits are boxes on (flex, abd, twist); the swing part is additionally bounded by 179° so that the decomposition
is unique. Values come from standard range-of-motion tables (AAOS / Norkin & White), rounded and split over
anny's spine and neck segments; the hands and feet are kept narrower than anatomy allows because the linear-blend
skinning collapses there.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
from scipy.spatial.transform import Rotation

from .rig import Rig

__all__ = ["JointSpec", "joint_specs", "rotation_about", "FORWARD", "BACKWARD", "UP", "DOWN"]

FORWARD = np.array([0.0, -1.0, 0.0])  # the body faces -Y
BACKWARD = -FORWARD
UP = np.array([0.0, 0.0, 1.0])
DOWN = -UP
_MAX_SWING_DEG = 179.0


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    if n < 1e-9:
        raise ValueError(f"degenerate axis {v}")
    return v / n


def rotation_about(axis: np.ndarray, deg: float) -> np.ndarray:
    """3x3 rotation of `deg` degrees about a (not necessarily unit) axis, right-handed."""
    return Rotation.from_rotvec(_unit(np.asarray(axis, float)) * np.radians(deg)).as_matrix()


def axis_angle(R: np.ndarray) -> np.ndarray:
    """3x3 rotation -> axis-angle vector (3,), angle in radians (the Rodrigues vector OpenCV and SMPL use)."""
    return Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_rotvec()


def axis_angle_matrix(v) -> np.ndarray:
    """Axis-angle vector (3 numbers, radians) -> 3x3 rotation; the inverse of `axis_angle`."""
    return Rotation.from_rotvec(np.asarray(v, dtype=np.float64).reshape(3)).as_matrix()


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The minimal rotation taking unit vector a onto unit vector b."""
    axis = np.cross(a, b)
    if np.linalg.norm(axis) < 1e-12:
        return np.eye(3)
    return rotation_about(axis, np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def _swing_twist(M: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, float]:
    """M = Swing · Twist about `axis`: (swing rotation vector in radians, twist angle in degrees)."""
    x, y, z, w = Rotation.from_matrix(M).as_quat()
    v = np.array([x, y, z])
    along = v @ axis
    norm = np.hypot(along, w)
    if norm < 1e-12:  # a pure 180° swing: the twist is undefined; call it zero
        return Rotation.from_matrix(M).as_rotvec(), 0.0
    q_twist = np.concatenate([along * axis, [w]]) / norm
    swing = Rotation.from_quat([x, y, z, w]) * Rotation.from_quat(q_twist).inv()
    twist = np.degrees(2.0 * np.arctan2(along, w))
    twist = (twist + 180.0) % 360.0 - 180.0
    return swing.as_rotvec(), float(twist)


@dataclasses.dataclass(frozen=True, eq=False)
class JointSpec:
    """One posed joint: its anatomical frame (unit axes in reference-pose world coordinates) and its limits."""

    bone: str
    neutral: np.ndarray  # (3,3) N: reference pose -> anatomical zero
    twist_axis: np.ndarray  # bone axis at the anatomical zero (sign chosen so + = internal rotation for limbs)
    flex_axis: np.ndarray
    abd_axis: np.ndarray
    flex: tuple[float, float]
    abd: tuple[float, float]
    twist: tuple[float, float]
    twist_last: bool = False  # the root: yaw applied after the swing

    def __post_init__(self) -> None:
        for lo, hi in (self.flex, self.abd, self.twist):
            if not lo <= hi:
                raise ValueError(f"{self.bone}: empty range ({lo}, {hi})")
        for a in ("neutral", "twist_axis", "flex_axis", "abd_axis"):
            getattr(self, a).setflags(write=False)

    def rotation(self, flex: float, abd: float, twist: float) -> np.ndarray:
        swing_vec = np.radians(flex) * self.flex_axis + np.radians(abd) * self.abd_axis
        S = Rotation.from_rotvec(swing_vec).as_matrix()
        T = Rotation.from_rotvec(np.radians(twist) * self.twist_axis).as_matrix()
        return (T @ S if self.twist_last else S @ T) @ self.neutral

    def angles(self, D: np.ndarray) -> tuple[float, float, float]:
        """(flex, abd, twist) in degrees of a delta rotation; inverse of `rotation` within the limits."""
        M = D @ self.neutral.T
        if self.twist_last:
            # M = T S  <=>  M^T = S^T T^T, a swing-twist product of the inverses.
            swing, twist = _swing_twist(M.T, self.twist_axis)
            swing, twist = -swing, -twist
        else:
            swing, twist = _swing_twist(M, self.twist_axis)
        return (float(np.degrees(swing @ self.flex_axis)), float(np.degrees(swing @ self.abd_axis)), twist)

    def clip(self, flex: float, abd: float, twist: float) -> tuple[float, float, float]:
        flex, abd = float(np.clip(flex, *self.flex)), float(np.clip(abd, *self.abd))
        swing = np.hypot(flex, abd)
        if swing > _MAX_SWING_DEG:
            flex, abd = flex * _MAX_SWING_DEG / swing, abd * _MAX_SWING_DEG / swing
        return flex, abd, float(np.clip(twist, *self.twist))

    def violation_deg(self, D: np.ndarray) -> float:
        """How far (degrees) a delta lies outside this joint's limits; 0 inside. The decomposition is exact
        (flex, abd and twist axes span all rotations), so the box is the whole test."""
        angles = self.angles(D)
        ranges = (self.flex, self.abd, self.twist)
        out = max(max(lo - a, a - hi) for a, (lo, hi) in zip(angles, ranges))
        return max(out, float(np.hypot(angles[0], angles[1])) - _MAX_SWING_DEG, 0.0)


def _spec(bone, neutral, t, flex_to, abd_to, flex, abd, twist, twist_sign=1.0, twist_last=False) -> JointSpec:
    t = _unit(t)
    kf = _unit(np.cross(t, flex_to))
    ka = np.cross(t, abd_to) if abd_to is not None else np.cross(t, kf)
    ka = _unit(ka - (ka @ kf) * kf)
    return JointSpec(bone, neutral, twist_sign * t, kf, ka, flex, abd, twist, twist_last)


# Midline chains: (bone, flex range, lateral-bend range, twist range). Trunk totals: flexion -35..+95°
# (lumbar + thoracic), lateral ±35°, axial ±40°; neck + head: flexion -50..+55°, lateral ±35°, rotation ±65°.
_SPINE = (
    ("spine05", (-10.0, 25.0), (-8.0, 8.0), (-5.0, 5.0)),
    ("spine04", (-10.0, 25.0), (-8.0, 8.0), (-6.0, 6.0)),
    ("spine03", (-7.0, 20.0), (-7.0, 7.0), (-9.0, 9.0)),
    ("spine02", (-4.0, 13.0), (-6.0, 6.0), (-10.0, 10.0)),
    ("spine01", (-4.0, 12.0), (-6.0, 6.0), (-10.0, 10.0)),
    ("neck01", (-12.0, 14.0), (-9.0, 9.0), (-16.0, 16.0)),
    ("neck02", (-12.0, 14.0), (-9.0, 9.0), (-16.0, 16.0)),
    ("neck03", (-12.0, 14.0), (-9.0, 9.0), (-16.0, 16.0)),
    ("head", (-14.0, 13.0), (-8.0, 8.0), (-17.0, 17.0)),
)
# Limb joints in anatomical degrees. Shoulder angles are measured from the arm hanging straight down (anny's
# A-pose is ~42° of abduction); elbow flexion from the straight arm (anny's reference elbow is bent ~42°).
_HIP = ((-20.0, 120.0), (-25.0, 45.0), (-35.0, 40.0))
_KNEE = ((0.0, 145.0), (0.0, 0.0), (-8.0, 8.0))  # flexion only, measured from anny's reference (~5° bent)
_ANKLE = ((-40.0, 20.0), (-15.0, 15.0), (-10.0, 10.0))  # flex = dorsiflexion, abd = eversion
_CLAVICLE = ((-5.0, 25.0), (-10.0, 20.0), (-5.0, 5.0))  # flex = elevation, abd = protraction
_SHOULDER = ((-45.0, 170.0), (-20.0, 170.0), (-70.0, 80.0))
_ELBOW = ((0.0, 145.0), (0.0, 0.0), (0.0, 0.0))  # flexion only
_FOREARM = ((0.0, 0.0), (0.0, 0.0), (-60.0, 60.0))  # pronation (+) / supination on the forearm twist bone
_WRIST = ((-30.0, 35.0), (-15.0, 15.0), (0.0, 0.0))  # flex = towards the palm
_FINGER = ((0.0, 30.0), (0.0, 0.0), (0.0, 0.0))  # small curl towards the palm only
_ROOT = ((-15.0, 80.0), (-20.0, 20.0), (-180.0, 180.0))  # pitch forward, roll to the left, yaw


@functools.lru_cache(maxsize=8)
def joint_specs(rig: Rig) -> dict[str, JointSpec]:
    """The posable joints of anny's rig, by bone label. Bones not listed (pelvis.*, shoulder01.*, twist bones of
    the thigh, shin and upper arm, metacarpals, thumbs, toes, eyes) stay at the reference pose."""
    idx, U = rig.index, rig.reference_orientations
    axis = lambda bone: _unit(U[idx[bone]][:, 1])  # noqa: E731  (blender convention: bones point along +y)
    I3 = np.eye(3)
    specs = {"root": _spec("root", I3, UP, FORWARD, np.array([1.0, 0.0, 0.0]), *_ROOT, twist_last=True)}
    for bone, *limits in _SPINE:
        specs[bone] = _spec(bone, I3, axis(bone), FORWARD, np.array([1.0, 0.0, 0.0]), *limits)

    # Reference-pose joint positions (shape-dependent, but only their directions are used, for the palm).
    heads = rig.world_poses(np.tile(np.eye(4), (len(rig.bone_labels), 1, 1)))[:, :3, 3]
    for side, s in (("L", 1.0), ("R", -1.0)):
        lateral = np.array([s, 0.0, 0.0])
        b = lambda name: f"{name}.{side}"  # noqa: E731
        specs[b("upperleg01")] = _spec(b("upperleg01"), I3, axis(b("upperleg02")), FORWARD, lateral, *_HIP,
                                       twist_sign=s)
        specs[b("lowerleg01")] = _spec(b("lowerleg01"), I3, axis(b("lowerleg01")), BACKWARD, lateral, *_KNEE,
                                       twist_sign=s)
        specs[b("foot")] = _spec(b("foot"), I3, axis(b("foot")), UP, lateral, *_ANKLE, twist_sign=s)
        specs[b("clavicle")] = _spec(b("clavicle"), I3, axis(b("clavicle")), UP, FORWARD, *_CLAVICLE)
        upper = axis(b("upperarm02"))
        specs[b("upperarm01")] = _spec(b("upperarm01"), _align(upper, DOWN), DOWN, FORWARD, lateral, *_SHOULDER,
                                       twist_sign=s)
        fore = axis(b("lowerarm01"))
        specs[b("lowerarm01")] = _spec(b("lowerarm01"), _align(fore, upper), upper, fore, None, *_ELBOW,
                                       twist_sign=s)
        specs[b("lowerarm02")] = _spec(b("lowerarm02"), I3, axis(b("lowerarm02")), FORWARD, None, *_FOREARM,
                                       twist_sign=s)
        # Palm normal from the knuckle line and the hand direction: for the left hand in the anatomical
        # position the index is lateral, the hand points down and the palm faces forward, hence the sign.
        hand = _unit(heads[idx[b("finger3-1")]] - heads[idx[b("wrist")]])
        across = heads[idx[b("finger2-1")]] - heads[idx[b("finger5-1")]]
        palm = _unit(-s * np.cross(across, hand))
        specs[b("wrist")] = _spec(b("wrist"), I3, axis(b("wrist")), palm, across, *_WRIST)
        for finger in (2, 3, 4, 5):
            for phalanx in (1, 2, 3):
                name = b(f"finger{finger}-{phalanx}")
                specs[name] = _spec(name, I3, axis(name), palm, None, *_FINGER)
    return specs
