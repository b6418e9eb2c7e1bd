"""Bring your own character, the data model: what a rigged glTF/FBX character (a licensed scan, an artist's
character) is once read, how it is posed by the generic skeleton (`rh_dataset.poses.skeleton`), and which pose each
frame of a protocol split gets.

In: the validated arrays `imported_reader` builds from Blender's reading (or any code constructing the dataclasses),
`SkeletonPose`s for `character.skeleton`, a split's kind and frame index. Out: `ImportedCharacter` (parts, skeleton,
clips, placement, the record `to_json` writes as subject_NNN/character.json), `PosedMesh`es for the renderer
(`pose_imported`), the box the camera frames (`imported_bounds`), a frame's `ImportedPose` (`split_pose`).

The contract and every convention are in docs/INTEROP.md ("Bring your own character"); the ones this module holds:

- Geometry is the file's rest (bind) pose, triangulated, one vertex per distinct (vertex, UV, normal) corner, in
  world metres with +Z up, placed and scaled by the reader (`imported_reader`'s docstring says how).
- Skinning: the top 4 bone influences per vertex, normalised; posing is linear blend skinning with
  `skeleton.skinning_transforms`, so any list of `SkeletonPose` for `character.skeleton` (the file's own clips, or
  motion retargeted onto this skeleton) drives it.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np

from rh_dataset.poses.skeleton import Skeleton, SkeletonPose, skin, skinning_transforms

from .character import Material, PosedMesh

__all__ = [
    "CharacterImportError", "CharacterImportWarning", "ImportedPart", "ImportedClip", "ImportedCharacter",
    "ImportedPose", "pose_imported", "imported_bounds", "motion_frames", "split_pose", "READER_VERSION",
    "REST_FALLBACK_LABEL",
]

# The version of what `imported_reader` reads out of a file: recorded in character.json and part of the reader's
# cache key. Bumped whenever the reader's output changes, so the on-disk cache never serves an older reading.
READER_VERSION = 1


class CharacterImportError(ValueError):
    """A character file that cannot be used; the message names the file and the problem."""


class CharacterImportWarning(UserWarning):
    """Something in a character file that is imported approximately (or left out); the message says what."""


def _ro(a, dtype) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


@dataclasses.dataclass(frozen=True, eq=False)
class ImportedPart:
    """One textured mesh in the placed rest pose. rest_vertices/rest_normals (V, 3) world metres (normals unit);
    faces (F, 3) int32; uvs (V, 2) float32, v up (may leave [0, 1]: textures repeat); bone_ids (V, K) indices into
    the skeleton, weights (V, K) >= 0 with rows summing to 1."""

    name: str
    rest_vertices: np.ndarray
    rest_normals: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    bone_ids: np.ndarray
    weights: np.ndarray
    material: Material

    def __post_init__(self) -> None:
        v = _ro(self.rest_vertices, np.float64)
        n = _ro(self.rest_normals, np.float64)
        f = _ro(self.faces, np.int32)
        uv = _ro(self.uvs, np.float32)
        ids = _ro(self.bone_ids, np.int64)
        w = _ro(self.weights, np.float64)
        V = len(v)
        where = f"imported part {self.name!r}"
        if v.shape != (V, 3) or n.shape != (V, 3) or uv.shape != (V, 2) or V == 0:
            raise CharacterImportError(f"{where}: vertices, normals (V, 3) and uvs (V, 2) expected, got {v.shape}, "
                                       f"{n.shape}, {uv.shape}")
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(n)) and np.all(np.isfinite(uv))):
            raise CharacterImportError(f"{where}: non-finite vertices, normals or UVs")
        if np.abs(np.linalg.norm(n, axis=1) - 1.0).max() > 1e-4:
            raise CharacterImportError(f"{where}: normals must be unit length")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or f.min() < 0 or f.max() >= V:
            raise CharacterImportError(f"{where}: faces must be (F, 3) indices into {V} vertices")
        if ids.shape != w.shape or ids.ndim != 2 or len(ids) != V:
            raise CharacterImportError(f"{where}: bone_ids and weights must both be ({V}, K)")
        if w.min() < 0 or np.abs(w.sum(1) - 1.0).max() > 1e-5:
            raise CharacterImportError(f"{where}: skin weights must be >= 0 with rows summing to 1")
        for k, a in (("rest_vertices", v), ("rest_normals", n), ("faces", f), ("uvs", uv), ("bone_ids", ids),
                     ("weights", w)):
            object.__setattr__(self, k, a)


@dataclasses.dataclass(frozen=True, eq=False)
class ImportedClip:
    """An animation stored in the file, sampled at every frame, as poses of the character's skeleton.
    head_error_m: the largest distance between a bone head as the file poses it and as `poses` pose it (nonzero when
    the file translates non-root bones, which `SkeletonPose` does not carry)."""

    name: str
    fps: float
    poses: tuple[SkeletonPose, ...]
    head_error_m: float


@dataclasses.dataclass(frozen=True, eq=False)
class ImportedCharacter:
    """A rigged character read from a glTF/FBX file, placed and scaled into our world (see `imported_reader`).

    `placement` (3,) and `scale`: a point p of the file's world (Blender's metres, Z up) is at scale * p + placement.
    """

    name: str
    source: str
    sha256: str
    parts: tuple[ImportedPart, ...]
    skeleton: Skeleton
    clips: tuple[ImportedClip, ...] = ()
    scale: float = 1.0
    placement: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.parts:
            raise CharacterImportError(f"{self.source}: no mesh parts")
        names = [p.name for p in self.parts]
        if len(set(names)) != len(names):
            raise CharacterImportError(f"{self.source}: part names must be unique, got {names}")
        J = len(self.skeleton)
        for p in self.parts:
            if p.bone_ids.min() < 0 or p.bone_ids.max() >= J:
                raise CharacterImportError(f"{self.source}: part {p.name!r} refers to bones outside the {J}-bone "
                                           "skeleton")
        for c in self.clips:
            if any(len(p.rotations) != J for p in c.poses):
                raise CharacterImportError(f"{self.source}: clip {c.name!r} does not match the skeleton")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise CharacterImportError(f"{self.source}: scale must be a positive number, got {self.scale}")
        object.__setattr__(self, "placement", _ro(self.placement, np.float64))
        object.__setattr__(self, "parts", tuple(self.parts))
        object.__setattr__(self, "clips", tuple(self.clips))
        object.__setattr__(self, "warnings", tuple(self.warnings))

    def part(self, name: str) -> ImportedPart:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"character {self.name!r} has no part {name!r}; parts: {[p.name for p in self.parts]}")

    @property
    def triangle_count(self) -> int:
        return int(sum(len(p.faces) for p in self.parts))

    @property
    def clip_poses(self) -> list[SkeletonPose]:
        """Every frame of every clip, in file order: the character's own motion."""
        return [p for c in self.clips for p in c.poses]

    def to_json(self) -> dict:
        """What a dataset records about the character (subject_NNN/character.json): no machine paths."""
        return {
            "model": "imported", "file": self.source, "sha256": self.sha256, "name": self.name,
            "scale": self.scale, "placement": self.placement.tolist(),
            "bones": list(self.skeleton.names), "parents": self.skeleton.parents.tolist(),
            "parts": [{"name": p.name, "vertices": len(p.rest_vertices), "triangles": len(p.faces),
                       "texture": list(p.material.albedo.shape[:2]), "roughness": p.material.roughness,
                       "specular": p.material.specular, "two_sided": p.material.two_sided} for p in self.parts],
            "clips": [{"name": c.name, "frames": len(c.poses), "fps": c.fps} for c in self.clips],
            "warnings": list(self.warnings), "reader_version": READER_VERSION,
        }


@dataclasses.dataclass(frozen=True, eq=False)
class ImportedPose:
    """One frame's pose of an imported character: a skeleton pose (None = rest), then a rigid `root_transform`
    (the turntable's rotation about +Z). `label` says where it came from (e.g. 'rest', 'clip:walk#12')."""

    pose: SkeletonPose | None
    root_transform: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(4))
    turntable_deg: float = 0.0
    label: str = "rest"

    def to_json(self, skeleton: Skeleton) -> dict:
        """The frame JSON's `body.pose`: non-identity bone rotations by name (the local-ref deltas D of
        skeleton.py), the root translation, the rigid root transform."""
        bones = {}
        translation = [0.0, 0.0, 0.0]
        if self.pose is not None:
            for name, R in zip(skeleton.names, self.pose.rotations):
                if not np.array_equal(R, np.eye(3)):
                    bones[name] = R.tolist()
            translation = self.pose.translation.tolist()
        return {"parameterization": "skeleton-local-ref", "bones": bones, "translation": translation,
                "root_transform": np.asarray(self.root_transform, np.float64).tolist(),
                "turntable_deg": float(self.turntable_deg), "label": self.label}


# ----------------------------------------------------------------------------------------------------------------
# Posing


def pose_imported(character: ImportedCharacter, pose: SkeletonPose | None = None,
                  root_transform: np.ndarray | None = None) -> list[PosedMesh]:
    """Skin every part with `pose` (None = the rest pose) by linear blend skinning, then apply the rigid
    `root_transform` (4x4; e.g. `rotation_about_z` for the turntable). Returns what the renderer consumes."""
    skel = character.skeleton
    pose = SkeletonPose.rest(skel) if pose is None else pose
    if len(pose.rotations) != len(skel):
        raise ValueError(f"pose_imported: the pose has {len(pose.rotations)} bones, {character.name!r} has "
                         f"{len(skel)}")
    T = skinning_transforms(skel, pose)
    M = None
    if root_transform is not None:
        M = np.asarray(root_transform, np.float64)
        R = M[:3, :3] if M.shape == (4, 4) else None
        if R is None or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or not np.allclose(M[3], (0, 0, 0, 1)):
            raise ValueError("pose_imported: root_transform must be a rigid 4x4 transform")
    out = []
    for p in character.parts:
        v, n = skin(p.rest_vertices, p.bone_ids, p.weights, T, rest_normals=p.rest_normals)
        if M is not None:
            v = v @ M[:3, :3].T + M[:3, 3]
            n = n @ M[:3, :3].T
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        out.append(PosedMesh(name=p.name, vertices=_ro(v, np.float32), normals=_ro(n, np.float32), faces=p.faces,
                             uvs=p.uvs, material=p.material))
    return out


def imported_bounds(character: ImportedCharacter, poses: Sequence[SkeletonPose | None]) -> tuple[np.ndarray, np.ndarray]:
    """A box the character stays inside for every pose in `poses` and every turn about +Z: (-r, -r, z_lo),
    (r, r, z_hi) with r the largest distance of any posed vertex from the Z axis. What the camera frames."""
    r, lo, hi = 0.0, np.inf, -np.inf
    for pose in poses:
        v = np.concatenate([m.vertices for m in pose_imported(character, pose)]).astype(np.float64)
        r = max(r, float(np.sqrt((v[:, :2] ** 2).sum(1)).max()))
        lo, hi = min(lo, float(v[:, 2].min())), max(hi, float(v[:, 2].max()))
    return np.array([-r, -r, lo]), np.array([r, r, hi])


# ----------------------------------------------------------------------------------------------------------------
# Poses for the protocols

REST_FALLBACK_LABEL = "rest (no motion source)"


def motion_frames(character: ImportedCharacter) -> list[tuple[str, SkeletonPose]]:
    """The character's own motion as (label, pose): every frame of every clip in the file, labelled
    'clip:<name>#<frame>'. Empty when the file has no animation."""
    return [(f"clip:{c.name}#{f}", p) for c in character.clips for f, p in enumerate(c.poses)]


def split_pose(kind: str, n_frames: int, i: int, motion: Sequence[tuple[str, SkeletonPose]]) -> ImportedPose:
    """Frame i of a split of `n_frames` frames whose poses are `kind` ('turntable', or 'random'/'train': poses
    from a motion). The turntable turns the rest pose about +Z, frame i at exactly 360 i / n degrees; motion
    splits take n_frames poses spread evenly over `motion` (frame i -> motion[floor(i * len / n)]), so a test split
    covers the whole clip and a split reusing the train poses gets the same ones. With no motion they fall back to
    the rest pose, labelled REST_FALLBACK_LABEL (generate warns once per run)."""
    from rh_dataset.poses.pose import rotation_about_z

    if not (isinstance(n_frames, int) and n_frames >= 1 and 0 <= i < n_frames):
        raise ValueError(f"split_pose: frame {i} of {n_frames}")
    if kind == "turntable":
        deg = 360.0 * i / n_frames
        return ImportedPose(None, rotation_about_z(deg), deg, "rest")
    if kind not in ("random", "train"):
        raise ValueError(f"split_pose: unknown pose source {kind!r}")
    if not motion:
        return ImportedPose(None, np.eye(4), 0.0, REST_FALLBACK_LABEL)
    label, pose = motion[(i * len(motion)) // n_frames]
    return ImportedPose(pose, np.eye(4), 0.0, label)
