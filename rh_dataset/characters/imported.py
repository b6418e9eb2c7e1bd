"""Bring your own character: a rigged glTF/FBX model (a licensed scan, an artist's character), read through Blender
and posed by the generic skeleton (`rh_dataset.poses.skeleton`), rendered by the same pipeline as anny characters.

Reading happens in Blender's Python (`bpy_read_character.py`, run by `rh_common.blender`); this side validates what it
wrote and builds the character. The contract and every convention are in docs/INTEROP.md ("Bring your own
character"); in short:

- Geometry is the file's rest (bind) pose, triangulated, one vertex per distinct (vertex, UV, normal) corner, in
  world metres with +Z up (Blender's importers convert glTF's Y-up and FBX's axes and units; we read world matrices).
- Skinning: the top 4 bone influences per vertex, normalised; posing is linear blend skinning with
  `skeleton.skinning_transforms`, so any list of `SkeletonPose` for `character.skeleton` (the file's own clips, or
  motion retargeted onto this skeleton) drives it.
- Placement: the rest mesh's horizontal bounding-box centre goes on the +Z axis and its lowest point to z = 0, so the
  protocol-A turntable (a rotation about +Z through the origin) spins the character about its own vertical axis.
  anny's bodies sit differently (pelvis at the origin); nothing downstream depends on the height (the camera frames
  the body's bounds, the floor is not modelled). The character must face -Y after import, as anny does (glTF's +Z
  forward arrives there through Blender's glTF importer).
- Scale: a rest height between 0.3 and 3 m is taken as metres; 30 to 300 "metres" is a centimetre file without a
  unit scale and is scaled by 0.01 with a warning; anything else needs an explicit `scale`.
- Materials: base colour from the Principled BSDF's image texture (decoded sRGB -> linear with
  `rh_common.colourspace`) or its constant colour; roughness; `specular` from IOR and "Specular IOR Level"
  (0.5 = a dielectric of IOR 1.5, as ours). Metallic, alpha cut-outs, normal maps and texture multipliers are not
  modelled (the reader warns).
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import shutil
import tempfile
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from rh_common.colourspace import srgb_decode
from rh_common.imageio import read_json, read_png, sha256_file
from rh_dataset.poses.skeleton import Skeleton, SkeletonPose, posed_heads, skin, skinning_transforms

from .character import Material, PosedMesh

__all__ = [
    "CharacterImportError", "CharacterImportWarning", "ImportedPart", "ImportedClip", "ImportedCharacter",
    "ImportedPose", "load_character_file", "read_character_file", "pose_imported", "imported_bounds",
    "character_digest", "motion_frames", "split_pose", "READER_SCRIPT", "CHARACTER_SUFFIXES", "MAX_TEXTURE_SIZE",
    "REST_FALLBACK_LABEL",
]

READER_SCRIPT = Path(__file__).with_name("bpy_read_character.py")
READER_FORMAT = "rh-imported-character/1"
# Bumped whenever the reader's output changes, so the on-disk cache never serves an older reading.
READER_VERSION = 1
CHARACTER_SUFFIXES = (".glb", ".gltf", ".fbx")
CACHE_ENV = "RH_CHARACTER_CACHE"
# Textures larger than this are box-filtered down (in linear light): an 8K scan texture would cost 800 MB as float32
# per process, far beyond what a 512x512 frame can show.
MAX_TEXTURE_SIZE = 2048
HUMAN_HEIGHT_M = (0.3, 3.0)
CENTIMETRE_HEIGHT = (30.0, 300.0)
# A clip whose child bones translate away from their parents cannot be expressed as rotations + root translation;
# past this many metres of disagreement at a bone head we say so.
HEAD_TOLERANCE_M = 1e-3


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
    """A rigged character read from a glTF/FBX file, placed and scaled into our world (see the module docstring).

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
# Reading


def character_digest(path: str | os.PathLike) -> str:
    """sha256 of a character file; for a .gltf, of the file and every external buffer and image it names (they
    are part of the character). An FBX's external textures are not followed (most FBX characters embed them)."""
    path = Path(path)
    if path.suffix.lower() != ".gltf":
        return sha256_file(path)
    h = hashlib.sha256(sha256_file(path).encode())
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise CharacterImportError(f"{path}: not a readable glTF JSON file ({exc})") from exc
    for entry in list(doc.get("buffers", [])) + list(doc.get("images", [])):
        uri = entry.get("uri") if isinstance(entry, dict) else None
        if uri and not uri.startswith("data:"):
            from urllib.parse import unquote

            side = path.parent / unquote(uri)
            h.update(uri.encode())
            h.update(sha256_file(side).encode() if side.is_file() else b"missing")
    return h.hexdigest()


def _character_path(path: str | os.PathLike) -> Path:
    """`path` as a Path, if it names an existing file of a type the reader takes; CharacterImportError otherwise."""
    path = Path(path)
    if not path.is_file():
        raise CharacterImportError(f"{path}: no such character file")
    if path.suffix.lower() not in CHARACTER_SUFFIXES:
        raise CharacterImportError(f"{path}: unsupported character file type {path.suffix!r}; expected one of "
                                   f"{', '.join(CHARACTER_SUFFIXES)}")
    return path


def read_character_file(path: str | os.PathLike, out_dir: str | os.PathLike, *, deformed: bool = False,
                        timeout: float = 1800.0) -> Path:
    """Run the Blender-side reader on `path`, writing into `out_dir` (created). Returns `out_dir`. Errors become
    CharacterImportError with the reader's own message (no armature, no skinned mesh, texture missing...)."""
    from rh_common.blender import BlenderError, BlenderUnavailable, run_blender_script

    path = _character_path(path)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    args = [str(path.resolve()), str(out_dir)] + (["--deformed"] if deformed else [])
    try:
        run_blender_script(READER_SCRIPT, args, timeout=timeout, threads=1)
    except BlenderUnavailable:
        raise
    except BlenderError as exc:
        lines = [ln for ln in str(exc).splitlines() if ln.startswith("rh-import: ")]
        if lines:  # the reader's own diagnosis, without the command line around it
            raise CharacterImportError(lines[-1][len("rh-import: "):]) from exc
        raise CharacterImportError(f"{path}: Blender could not import it:\n{exc}") from exc
    if not (out_dir / "character.json").is_file():
        raise CharacterImportError(f"{path}: the reader finished without writing character.json")
    return out_dir


def _cache_root() -> Path:
    env = os.environ.get(CACHE_ENV)
    return Path(env) if env else Path.home() / ".cache" / "relighting-humans" / "characters"


def _cached_reading(path: Path, digest: str) -> Path:
    """The reader's output for this file content, from the on-disk cache (keyed by sha256 and reader version) or
    made now. The folder is filled under a temporary name and renamed into place, so a killed run leaves no
    half-written cache entry and concurrent workers at worst read the file twice."""
    root = _cache_root()
    final = root / f"{digest}-r{READER_VERSION}"
    if (final / "character.json").is_file():
        return final
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{digest[:16]}.", suffix=".tmp", dir=root))
    try:
        read_character_file(path, tmp)
        try:
            os.replace(tmp, final)
        except OSError:
            if not (final / "character.json").is_file():  # not another worker's finished copy: a real failure
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return final


def _texture(folder: Path, rec: dict, where: str) -> np.ndarray:
    if rec.get("texture") is None:
        c = np.clip(np.asarray(rec["base_colour"], np.float32), 0.0, 1.0)
        return c.reshape(1, 1, 3)
    px = read_png(folder / rec["texture"])
    if px.ndim == 2:
        px = np.repeat(px[..., None], 3, axis=2)
    rgb = px[..., :3].astype(np.float64) / 255.0
    if rec.get("texture_colourspace") == "sRGB":
        lin = srgb_decode(rgb)
    elif rec.get("texture_colourspace") == "linear":
        lin = rgb.astype(np.float32)
    else:
        raise CharacterImportError(f"{where}: unknown texture colour space {rec.get('texture_colourspace')!r}")
    factor = int(math.ceil(max(lin.shape[:2]) / MAX_TEXTURE_SIZE))
    if factor > 1:
        H, W = (lin.shape[0] // factor) * factor, (lin.shape[1] // factor) * factor
        lin = lin[:H, :W].reshape(H // factor, factor, W // factor, factor, 3).mean(axis=(1, 3))
    return np.clip(lin, 0.0, 1.0).astype(np.float32)


def _auto_scale(height: float, source: str) -> tuple[float, str | None]:
    if HUMAN_HEIGHT_M[0] <= height <= HUMAN_HEIGHT_M[1]:
        return 1.0, None
    if CENTIMETRE_HEIGHT[0] <= height <= CENTIMETRE_HEIGHT[1]:
        return 0.01, (f"{source}: the character is {height:.1f} m tall after import, which looks like centimetres "
                      "without a unit scale in the file; scaled by 0.01 (pass an explicit scale, e.g. "
                      "--character-scale 1, to override)")
    raise CharacterImportError(
        f"{source}: the character is {height:.3g} m tall after import, not a human's height in metres or "
        f"centimetres; pass its scale explicitly (e.g. --character-scale 0.0254 for inches)")


def _build(folder: Path, source: str, name: str, digest: str, scale: float | None) -> ImportedCharacter:
    meta = read_json(folder / "character.json")
    if meta.get("format") != READER_FORMAT:
        raise CharacterImportError(f"{source}: reader output has format {meta.get('format')!r}, expected "
                                   f"{READER_FORMAT!r}")
    with np.load(folder / "character.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    notes = list(meta.get("warnings", []))
    heads = arrays["skeleton_heads"].astype(np.float64)
    tails = arrays["skeleton_tails"].astype(np.float64)
    parents = arrays["skeleton_parents"]
    raw_parts = []
    for i, pm in enumerate(meta["parts"]):
        raw_parts.append((pm, {k: arrays[f"part{i}_{k}"] for k in
                               ("positions", "normals", "uvs", "faces", "bone_ids", "weights")}))
    allv = np.concatenate([rp["positions"] for _, rp in raw_parts]).astype(np.float64)
    lo, hi = allv.min(0), allv.max(0)
    if scale is None:
        scale, note = _auto_scale(float(hi[2] - lo[2]), source)
        if note:
            notes.append(note)
    else:
        scale = float(scale)
        if not (math.isfinite(scale) and scale > 0):
            raise CharacterImportError(f"{source}: scale must be a positive number, got {scale}")
        h = float(hi[2] - lo[2]) * scale
        if not HUMAN_HEIGHT_M[0] <= h <= HUMAN_HEIGHT_M[1]:
            notes.append(f"{source}: with scale {scale} the character is {h:.3g} m tall, not a human's height")
    # Horizontal bounding-box centre onto the +Z axis (the turntable's pivot), lowest point onto z = 0.
    placement = -scale * np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]])
    skel = Skeleton(tuple(meta["bones"]), parents, heads * scale + placement, tails * scale + placement)

    parts = []
    for pm, rp in raw_parts:
        mat = pm["material"]
        where = f"{source}: part {pm['name']!r}"
        parts.append(ImportedPart(
            name=pm["name"],
            rest_vertices=rp["positions"].astype(np.float64) * scale + placement,
            rest_normals=rp["normals"], faces=rp["faces"], uvs=rp["uvs"],
            bone_ids=rp["bone_ids"], weights=rp["weights"],
            material=Material(_texture(folder, mat, where),
                              roughness=float(np.clip(mat["roughness"], 0.0, 1.0)),
                              specular=float(np.clip(mat["specular"], 0.0, 1.0)),
                              two_sided=bool(mat["two_sided"]))))

    clips = []
    roots = np.flatnonzero(parents < 0)
    for k, cm in enumerate(meta.get("animations", [])):
        G = arrays[f"anim{k}_rotations"].astype(np.float64)
        H = arrays[f"anim{k}_heads"].astype(np.float64) * scale + placement
        poses, err = [], 0.0
        for f in range(len(G)):
            # skeleton.py's deltas from world rotations relative to rest: D_root = G_root, D_c = G_p^T G_c.
            D = np.empty_like(G[f])
            for c, p in enumerate(parents):
                D[c] = G[f][c] if p < 0 else G[f][p].T @ G[f][c]
            # Re-orthonormalise the float32-rounded products (the reader wrote float64, but Blender computes in
            # float32), so SkeletonPose's 1e-5 rotation check holds on long chains.
            U, _, Vt = np.linalg.svd(D)
            D = U @ Vt
            sp = SkeletonPose(D, H[f, roots[0]] - skel.heads[roots[0]])
            err = max(err, float(np.abs(posed_heads(skel, sp) - H[f]).max()))
            poses.append(sp)
        if err > HEAD_TOLERANCE_M:
            notes.append(f"{source}: clip {cm['name']!r} moves bone heads away from their parents (up to "
                         f"{err * 100:.1f} cm); only rotations and the root's translation are kept")
        clips.append(ImportedClip(name=cm["name"], fps=float(cm["fps"]), poses=tuple(poses), head_error_m=err))
    ch = ImportedCharacter(name=name, source=source, sha256=digest, parts=tuple(parts), skeleton=skel,
                           clips=tuple(clips), scale=scale, placement=placement, warnings=tuple(notes))
    for w in notes:
        warnings.warn(w, CharacterImportWarning, stacklevel=3)
    return ch


def load_character_file(path: str | os.PathLike, *, scale: float | None = None) -> ImportedCharacter:
    """Read a rigged .glb/.gltf/.fbx character (Blender runs once per file content; the reading is cached on disk
    under $RH_CHARACTER_CACHE or ~/.cache/relighting-humans/characters, keyed by sha256) and build it. `scale`:
    None detects metres vs centimetres from the height, a number multiplies the imported metres."""
    path = _character_path(path)
    digest = character_digest(path)
    return _load_cached(str(path.resolve()), digest, None if scale is None else float(scale))


@functools.lru_cache(maxsize=2)
def _load_cached(path: str, digest: str, scale: float | None) -> ImportedCharacter:
    p = Path(path)
    folder = _cached_reading(p, digest)
    return _build(folder, p.name, p.stem, digest, scale)


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
