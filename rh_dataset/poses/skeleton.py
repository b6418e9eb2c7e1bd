"""A skeleton any character can have (anny's, an imported glTF/FBX rig, a BVH hierarchy) and how it poses a mesh.

One parameterisation for every rig, the one anny calls 'local-ref' (see `rig.py`): a pose gives each bone c a
rotation D_c about its own head, expressed in its parent's carried copy of the world axes. Posed world rotations
relative to rest compose down the chain, G_c = G_p D_c (G_root = D_root); posed heads follow the rest offsets,
h'_c = h'_p + G_p (h_c - h_p); a vertex skinned to bone c moves by T_c = [G_c | h'_c - G_c h_c]. Because every
rotation is a world-axes delta from the rest pose, a motion moves between rigs by copying G_c per matched bone
(after aligning the two rest poses) rather than by converting between each rig's own bone-local axes.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

__all__ = ["Skeleton", "SkeletonPose", "posed_rotations", "posed_heads", "skinning_transforms", "skin"]

_ORTHO_TOL = 1e-5


def _frozen(a, dtype) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


def _check_rotations(name: str, R: np.ndarray) -> None:
    if R.ndim != 3 or R.shape[1:] != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError(f"{name} must be finite (J, 3, 3) rotations, got shape {R.shape}")
    err = np.abs(np.einsum("jab,jcb->jac", R, R) - np.eye(3)).max(initial=0.0)
    if err > _ORTHO_TOL or (len(R) and np.abs(np.linalg.det(R) - 1.0).max() > _ORTHO_TOL):
        raise ValueError(f"{name}: not proper rotations (orthonormality error {err:.2e})")


@dataclasses.dataclass(frozen=True, eq=False)
class Skeleton:
    """names (J,) unique bone names; parents (J,) index of each bone's parent, -1 for roots, parents before
    children; heads (J, 3) rest positions of the bone heads in world metres (Z up); tails (J, 3) rest positions of
    the bone tails (where a bone points at rest: what retargeting aligns)."""

    names: tuple[str, ...]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        if len(set(names)) != len(names) or not names:
            raise ValueError("Skeleton: bone names must be non-empty and unique")
        parents = _frozen(self.parents, np.int64)
        heads, tails = _frozen(self.heads, np.float64), _frozen(self.tails, np.float64)
        J = len(names)
        if parents.shape != (J,) or heads.shape != (J, 3) or tails.shape != (J, 3):
            raise ValueError(f"Skeleton: parents ({J},), heads and tails ({J}, 3) expected, got "
                             f"{parents.shape}, {heads.shape}, {tails.shape}")
        if np.any(parents >= np.arange(J)) or np.any(parents < -1):
            raise ValueError("Skeleton: every parent must precede its child (-1 for a root)")
        if not (np.all(np.isfinite(heads)) and np.all(np.isfinite(tails))):
            raise ValueError("Skeleton: heads and tails must be finite")
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "heads", heads)
        object.__setattr__(self, "tails", tails)

    @functools.cached_property
    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.names)}

    def __len__(self) -> int:
        return len(self.names)


@dataclasses.dataclass(frozen=True, eq=False)
class SkeletonPose:
    """rotations (J, 3, 3): each bone's D_c (identity = rest); translation (3,): added to every root's head."""

    rotations: np.ndarray
    translation: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        R = _frozen(self.rotations, np.float64)
        _check_rotations("SkeletonPose.rotations", R)
        t = _frozen(self.translation, np.float64)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError("SkeletonPose.translation must be a finite (3,) vector")
        object.__setattr__(self, "rotations", R)
        object.__setattr__(self, "translation", t)

    @classmethod
    def rest(cls, skeleton: Skeleton) -> "SkeletonPose":
        return cls(np.tile(np.eye(3), (len(skeleton), 1, 1)))


def _check(skeleton: Skeleton, pose: SkeletonPose) -> None:
    if len(pose.rotations) != len(skeleton):
        raise ValueError(f"pose has {len(pose.rotations)} bones, skeleton {len(skeleton)}")


def posed_rotations(skeleton: Skeleton, pose: SkeletonPose) -> np.ndarray:
    """G (J, 3, 3): each bone's world rotation relative to its rest orientation."""
    _check(skeleton, pose)
    G = np.empty_like(pose.rotations)
    for c, p in enumerate(skeleton.parents):
        G[c] = pose.rotations[c] if p < 0 else G[p] @ pose.rotations[c]
    return G


def posed_heads(skeleton: Skeleton, pose: SkeletonPose, G: np.ndarray | None = None) -> np.ndarray:
    """h' (J, 3): posed bone heads in world metres."""
    G = posed_rotations(skeleton, pose) if G is None else G
    h = skeleton.heads
    out = np.empty_like(h)
    for c, p in enumerate(skeleton.parents):
        out[c] = h[c] + pose.translation if p < 0 else out[p] + G[p] @ (h[c] - h[p])
    return out


def skinning_transforms(skeleton: Skeleton, pose: SkeletonPose) -> np.ndarray:
    """T (J, 3, 4) taking rest-pose points to posed points, per bone."""
    G = posed_rotations(skeleton, pose)
    heads = posed_heads(skeleton, pose, G)
    trans = heads - np.einsum("jab,jb->ja", G, skeleton.heads)
    return np.concatenate([G, trans[:, :, None]], axis=2)


def skin(rest_points: np.ndarray, bone_ids: np.ndarray, weights: np.ndarray, transforms: np.ndarray,
         rest_normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Linear blend skinning. rest_points (V, 3); bone_ids, weights (V, K) with rows summing to 1; transforms from
    `skinning_transforms`. Normals (optional) go through the blended 3x3 and are renormalised."""
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != np.shape(bone_ids) or w.ndim != 2 or len(w) != len(rest_points):
        raise ValueError("skin: bone_ids and weights must both be (V, K) for V rest points")
    blended = np.einsum("vk,vkab->vab", w, transforms[np.asarray(bone_ids)])
    pts = np.einsum("vab,vb->va", blended[:, :, :3], rest_points) + blended[:, :, 3]
    if rest_normals is None:
        return pts, None
    n = np.einsum("vab,vb->va", blended[:, :, :3], rest_normals)
    return pts, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
