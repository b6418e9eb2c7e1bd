"""A procedural pose prior on anny's rig: a mixture of everyday archetypes, each with noise, inside anatomical
joint limits, with gross self-intersections rejected.

No mocap data or trained prior is installable here (see RESEARCH.md), so each archetype is a small recipe in
anatomical angles (degrees; see `joints.py` for the axes): a stance for the legs and trunk, an arm recipe per side
and a global yaw. Every angle is clipped to its joint's limits before it becomes a rotation, so whatever a recipe
asks for, the pose stays inside the limits that the tests check.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from .collision import find_intersections
from .joints import JointSpec, joint_specs
from .pose import BodyPose
from .rig import Rig, rig_for

__all__ = ["ARCHETYPE_WEIGHTS", "propose_pose", "sample_pose", "sample_poses", "pose_from_angles"]

Angles = dict[str, tuple[float, float, float]]  # bone -> (flex, abd, twist) in degrees

_SPINE = ("spine05", "spine04", "spine03", "spine02", "spine01")
_SPINE_SHARE = np.array([0.26, 0.26, 0.2, 0.14, 0.14])  # lumbar bends most
_NECK = ("neck01", "neck02", "neck03", "head")
_NECK_SHARE = np.array([0.25, 0.25, 0.25, 0.25])
_SIDES = ("L", "R")


def _other(side: str) -> str:
    return "R" if side == "L" else "L"


def _add(angles: Angles, bone: str, flex: float = 0.0, abd: float = 0.0, twist: float = 0.0) -> None:
    f, a, t = angles.get(bone, (0.0, 0.0, 0.0))
    angles[bone] = (f + flex, a + abd, t + twist)


def _spread(angles: Angles, bones, share, flex=0.0, abd=0.0, twist=0.0) -> None:
    """Split a chain's total bend over its segments."""
    for bone, w in zip(bones, share):
        _add(angles, bone, w * flex, w * abd, w * twist)


# -- building blocks -------------------------------------------------------------------------------------------

def _trunk_noise(rng, angles: Angles) -> None:
    for bone in _SPINE:
        _add(angles, bone, rng.normal(0, 2), rng.normal(0, 1.5), rng.normal(0, 2))
    for bone in _NECK:
        _add(angles, bone, rng.normal(0, 3), rng.normal(0, 2), rng.normal(0, 5))


def _standing_leg(rng, angles: Angles, side: str) -> None:
    _add(angles, f"upperleg01.{side}", rng.normal(0, 3), rng.uniform(-5, 3), rng.normal(0, 5))
    _add(angles, f"lowerleg01.{side}", rng.uniform(0, 8))
    _add(angles, f"foot.{side}", rng.normal(0, 3), rng.normal(0, 3))


def _hand(rng, angles: Angles, side: str, curl: float | None = None) -> None:
    """Wrist noise and a relaxed finger curl (one value per hand so the fingers move together)."""
    _add(angles, f"wrist.{side}", rng.uniform(-10, 15), rng.normal(0, 5))
    curl = rng.uniform(3, 22) if curl is None else curl
    for finger in (2, 3, 4, 5):
        extra = 2.0 * (finger - 2)  # the ulnar fingers curl a little more, as in a relaxed hand
        for phalanx in (1, 2, 3):
            _add(angles, f"finger{finger}-{phalanx}.{side}", max(0.0, curl + extra + rng.normal(0, 3)))


def _relaxed_arm(rng, angles: Angles, side: str) -> None:
    _add(angles, f"upperarm01.{side}", rng.normal(5, 7), rng.uniform(7, 20), rng.uniform(-10, 20))
    _add(angles, f"lowerarm01.{side}", rng.uniform(8, 35))
    _add(angles, f"lowerarm02.{side}", 0.0, 0.0, rng.uniform(-15, 40))
    _hand(rng, angles, side)


# -- archetypes ------------------------------------------------------------------------------------------------

def _stand(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    for s in _SIDES:
        _standing_leg(rng, a, s)
        _relaxed_arm(rng, a, s)
    # Weight on one leg: the pelvis drops a little on the other side.
    _add(a, "root", 0.0, rng.uniform(-4, 4), 0.0)
    return a


def _walk(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    lead = _SIDES[rng.integers(2)]
    trail = _other(lead)
    stride = rng.uniform(15, 30)
    _add(a, f"upperleg01.{lead}", stride * rng.uniform(0.7, 1.0), rng.uniform(0, 5), rng.normal(0, 4))
    _add(a, f"upperleg01.{trail}", -stride * rng.uniform(0.4, 0.7), rng.uniform(0, 5), rng.normal(0, 4))
    _add(a, f"lowerleg01.{lead}", rng.uniform(0, 15))
    _add(a, f"lowerleg01.{trail}", rng.uniform(15, 50))  # push-off / early swing
    _add(a, f"foot.{lead}", rng.uniform(0, 12))  # heel strike: toes up
    _add(a, f"foot.{trail}", rng.uniform(-25, -5))  # push-off: toes down
    # Arms swing opposite to the legs, the forward arm a little bent.
    swing = stride * rng.uniform(0.6, 1.1)
    # Some abduction keeps the backward-swinging hand clear of the thigh.
    _add(a, f"upperarm01.{lead}", -swing * 0.8, rng.uniform(9, 18), rng.uniform(-5, 15))
    _add(a, f"upperarm01.{trail}", swing, rng.uniform(7, 15), rng.uniform(-5, 15))
    _add(a, f"lowerarm01.{lead}", rng.uniform(5, 25))
    _add(a, f"lowerarm01.{trail}", rng.uniform(20, 50))
    for s in _SIDES:
        _add(a, f"lowerarm02.{s}", 0.0, 0.0, rng.uniform(0, 40))
        _hand(rng, a, s)
    # The thorax counter-rotates against the pelvis; the lead leg's side goes forward, so the trunk turns away.
    sign = 1.0 if lead == "L" else -1.0
    _spread(a, _SPINE, _SPINE_SHARE, flex=rng.uniform(0, 6), twist=-sign * rng.uniform(2, 8))
    return a


def _reach_arm(rng, a: Angles, side: str, mode: str) -> None:
    if mode == "up":
        _add(a, f"upperarm01.{side}", rng.uniform(135, 170), rng.uniform(0, 30), rng.uniform(-10, 25))
        _add(a, f"clavicle.{side}", rng.uniform(8, 25), rng.uniform(0, 10))
        _add(a, f"lowerarm01.{side}", rng.uniform(0, 25))
    elif mode == "forward":
        _add(a, f"upperarm01.{side}", rng.uniform(65, 110), rng.uniform(-10, 25), rng.uniform(-10, 25))
        _add(a, f"clavicle.{side}", rng.uniform(0, 10), rng.uniform(5, 20))
        _add(a, f"lowerarm01.{side}", rng.uniform(0, 30))
    else:  # side
        _add(a, f"upperarm01.{side}", rng.uniform(-10, 30), rng.uniform(75, 110), rng.uniform(-20, 10))
        _add(a, f"clavicle.{side}", rng.uniform(0, 15), rng.uniform(-5, 10))
        _add(a, f"lowerarm01.{side}", rng.uniform(0, 25))
    _add(a, f"lowerarm02.{side}", 0.0, 0.0, rng.uniform(-30, 40))
    _add(a, f"wrist.{side}", rng.uniform(-25, 10), rng.normal(0, 5))
    _hand(rng, a, side, curl=rng.uniform(0, 10))  # an open hand


def _reach(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    for s in _SIDES:
        _standing_leg(rng, a, s)
    mode = ("up", "forward", "side")[rng.integers(3)]
    side = _SIDES[rng.integers(2)]
    _reach_arm(rng, a, side, mode)
    if rng.random() < 0.4:
        _reach_arm(rng, a, _other(side), mode)
    else:
        _relaxed_arm(rng, a, _other(side))
    sign = 1.0 if side == "L" else -1.0
    if mode == "up":
        # Look up, stretch: the trunk extends a little and leans away from a single raised arm.
        _spread(a, _NECK, _NECK_SHARE, flex=-rng.uniform(5, 35))
        _spread(a, _SPINE, _SPINE_SHARE, flex=-rng.uniform(0, 12), abd=-sign * rng.uniform(0, 10))
    elif mode == "forward":
        _spread(a, _SPINE, _SPINE_SHARE, flex=rng.uniform(0, 25), twist=-sign * rng.uniform(0, 15))
        _add(a, "root", rng.uniform(0, 10), 0.0, 0.0)
        for s in _SIDES:
            _add(a, f"upperleg01.{s}", a["root"][0])  # keep the legs under the body
    else:
        _spread(a, _SPINE, _SPINE_SHARE, abd=-sign * rng.uniform(0, 15))
        _spread(a, _NECK, _NECK_SHARE, twist=sign * rng.uniform(0, 40))  # look at the hand
    return a


def _bend(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    pitch = rng.uniform(20, 65)  # the pelvis tips forward ...
    _add(a, "root", pitch, rng.normal(0, 3), 0.0)
    knee = rng.uniform(0, 30)
    for s in _SIDES:
        # ... and the hips flex by as much, so the legs stay about vertical (a little behind when the knees bend).
        _add(a, f"upperleg01.{s}", pitch + knee * 0.5 + rng.normal(0, 4), rng.uniform(0, 8), rng.normal(0, 5))
        _add(a, f"lowerleg01.{s}", knee + rng.uniform(0, 5))
        _add(a, f"foot.{s}", knee * 0.5 + rng.normal(0, 3))
    spine = rng.uniform(10, 50)
    _spread(a, _SPINE, _SPINE_SHARE, flex=spine, abd=rng.normal(0, 4), twist=rng.normal(0, 5))
    _spread(a, _NECK, _NECK_SHARE, flex=-rng.uniform(0, 30))  # head up to look ahead
    tilt = pitch + spine  # the arms hang (roughly) towards the floor
    for s in _SIDES:
        _add(a, f"upperarm01.{s}", tilt * rng.uniform(0.75, 1.05), rng.uniform(5, 18), rng.uniform(-10, 20))
        _add(a, f"lowerarm01.{s}", rng.uniform(5, 35))
        _add(a, f"lowerarm02.{s}", 0.0, 0.0, rng.uniform(-10, 40))
        _hand(rng, a, s)
    return a


def _sit(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    _add(a, "root", rng.uniform(-10, 5), rng.normal(0, 2), 0.0)  # upright or leaning back a little
    for s in _SIDES:
        hip, knee = rng.uniform(70, 100), rng.uniform(70, 100)
        _add(a, f"upperleg01.{s}", hip - a["root"][0], rng.uniform(3, 15), rng.uniform(-10, 5))
        _add(a, f"lowerleg01.{s}", knee)
        _add(a, f"foot.{s}", rng.uniform(-10, 10) + (knee - hip) * 0.5, rng.normal(0, 3))
    _spread(a, _SPINE, _SPINE_SHARE, flex=rng.uniform(-5, 20))  # from straight to a slouch
    for s in _SIDES:
        if rng.random() < 0.7:  # hands resting on the thighs
            _add(a, f"upperarm01.{s}", rng.uniform(15, 40), rng.uniform(5, 18), rng.uniform(0, 25))
            _add(a, f"lowerarm01.{s}", rng.uniform(45, 85))
            _add(a, f"lowerarm02.{s}", 0.0, 0.0, rng.uniform(20, 60))
            _hand(rng, a, s)
        else:
            _relaxed_arm(rng, a, s)
    return a


def _arms_crossed(rng) -> Angles:
    a: Angles = {}
    _trunk_noise(rng, a)
    for s in _SIDES:
        _standing_leg(rng, a, s)
    top = _SIDES[rng.integers(2)]
    for s in _SIDES:
        upper = s == top  # the top forearm lies over the other one, a little higher and further forward
        _add(a, f"upperarm01.{s}", rng.uniform(26, 36) + (8 if upper else 0), rng.uniform(10, 18),
             rng.uniform(60, 70))
        _add(a, f"lowerarm01.{s}", rng.uniform(98, 108) + (8 if upper else 0))
        _add(a, f"lowerarm02.{s}", 0.0, 0.0, rng.uniform(0, 30))
        _hand(rng, a, s)
    return a


def _random(rng, specs: Mapping[str, JointSpec]) -> Angles:
    """Every posable joint uniform in the central 50% of its range: the long tail the recipes miss, left to the
    intersection check to clean up."""
    a: Angles = {}
    for bone, spec in specs.items():
        if bone == "root":
            _add(a, "root", rng.uniform(-10, 30), rng.uniform(-10, 10), 0.0)
            continue
        a[bone] = tuple(float((lo + hi) / 2 + rng.uniform(-0.25, 0.25) * (hi - lo))
                        for lo, hi in (spec.flex, spec.abd, spec.twist))
    return a


_RECIPES: dict[str, Callable] = {"stand": _stand, "walk": _walk, "reach": _reach, "bend": _bend, "sit": _sit,
                                 "arms-crossed": _arms_crossed}
ARCHETYPE_WEIGHTS: Mapping[str, float] = {"stand": 0.12, "walk": 0.2, "reach": 0.2, "bend": 0.12, "sit": 0.14,
                                          "arms-crossed": 0.12, "random": 0.1}


# -- assembly --------------------------------------------------------------------------------------------------

def pose_from_angles(angles: Mapping[str, tuple[float, float, float]], specs: Mapping[str, JointSpec], *,
                     label: str) -> BodyPose:
    """Clip each joint's anatomical angles to its limits and turn them into a BodyPose. Bones not given stay at
    anny's reference pose."""
    bones = {}
    for bone, (flex, abd, twist) in sorted(angles.items()):
        if bone not in specs:
            raise ValueError(f"bone {bone!r} is not a posable joint")
        M = np.eye(4)
        M[:3, :3] = specs[bone].rotation(*specs[bone].clip(flex, abd, twist))
        bones[bone] = M
    return BodyPose(bones=bones, label=label)


def _with_reference(angles: Angles, specs: Mapping[str, JointSpec]) -> Angles:
    """Recipes give shoulder and elbow angles from the anatomical zero (arm down, arm straight); joints a recipe
    leaves out keep anny's reference values, which for those two are not zero."""
    out = dict(angles)
    for bone, spec in specs.items():
        if bone not in out and bone.startswith(("upperarm01", "lowerarm01")):
            out[bone] = spec.angles(np.eye(3))
    return out


def propose_pose(rng: np.random.Generator, model, *, yaw_range_deg: float = 60.0,
                 archetype_weights: Mapping[str, float] | None = None, rig: Rig | None = None) -> BodyPose:
    """One candidate pose from the mixture, inside the joint limits, not yet checked for self-intersection."""
    specs = joint_specs(rig if rig is not None else rig_for(model))
    weights = dict(ARCHETYPE_WEIGHTS if archetype_weights is None else archetype_weights)
    if unknown := set(weights) - set(ARCHETYPE_WEIGHTS):
        raise ValueError(f"unknown archetypes {sorted(unknown)}; known: {sorted(ARCHETYPE_WEIGHTS)}")
    if not 0.0 <= yaw_range_deg <= 180.0:
        raise ValueError(f"yaw_range_deg must be in [0, 180], got {yaw_range_deg}")
    names = sorted(weights)
    p = np.array([weights[n] for n in names], dtype=float)
    if np.any(p < 0) or p.sum() <= 0:
        raise ValueError("archetype weights must be non-negative with a positive sum")
    name = names[rng.choice(len(names), p=p / p.sum())]
    angles = _random(rng, specs) if name == "random" else _RECIPES[name](rng)
    angles = _with_reference(angles, specs)
    # The global heading: the body keeps (mostly) facing the camera at -Y.
    _add(angles, "root", 0.0, 0.0, rng.uniform(-yaw_range_deg, yaw_range_deg))
    return pose_from_angles(angles, specs, label=name)


def sample_pose(rng: np.random.Generator, model, *, max_tries: int = 50, yaw_range_deg: float = 60.0,
                archetype_weights: Mapping[str, float] | None = None,
                phenotype: Mapping[str, float] | None = None) -> BodyPose:
    """A pose from the prior without gross self-intersection on the body of `phenotype` (default: anny's default
    body). Draws candidates until one passes; raises RuntimeError after `max_tries` rejections."""
    if max_tries < 1:
        raise ValueError("max_tries must be >= 1")
    rig = rig_for(model, phenotype)
    for _ in range(max_tries):
        pose = propose_pose(rng, model, yaw_range_deg=yaw_range_deg, archetype_weights=archetype_weights, rig=rig)
        if not find_intersections(pose, rig=rig):
            return pose
    raise RuntimeError(f"no intersection-free pose in {max_tries} tries")


def sample_poses(rng: np.random.Generator, model, n: int, **kwargs) -> list[BodyPose]:
    """`n` poses from `sample_pose`, drawn in order from the one generator."""
    if n < 0:
        raise ValueError("n must be >= 0")
    return [sample_pose(rng, model, **kwargs) for _ in range(n)]
