"""Bring your own character, the reading: a rigged .glb/.gltf/.fbx file read through Blender, checked, cached on
disk and built into an `ImportedCharacter` (`imported_model`).

In: a character file's path (and optionally its scale). Out: `load_character_file` -> `ImportedCharacter`;
`character_digest` -> the sha256 a dataset records; `read_character_file` -> the folder the Blender-side reader
(`bpy_read_character.py`, run by `rh_common.blender`) wrote (character.json + character.npz + textures). Unusable
files raise `CharacterImportError`; approximations warn with `CharacterImportWarning`.

The contract and every convention are in docs/INTEROP.md ("Bring your own character"); the ones this module holds:

- World frame: Blender's importers convert glTF's Y-up and FBX's axes and units; the reader reads world matrices,
  so the geometry arrives in world metres with +Z up.
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

import functools
import hashlib
import json
import math
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from rh_common.colourspace import srgb_decode
from rh_common.imageio import read_json, read_png, sha256_file
from rh_dataset.poses.skeleton import Skeleton, SkeletonPose, posed_heads

from .character import Material
from .imported_model import (
    READER_VERSION,
    CharacterImportError,
    CharacterImportWarning,
    ImportedCharacter,
    ImportedClip,
    ImportedPart,
)

__all__ = [
    "load_character_file", "read_character_file", "character_digest", "READER_SCRIPT", "CHARACTER_SUFFIXES",
    "MAX_TEXTURE_SIZE",
]

READER_SCRIPT = Path(__file__).with_name("bpy_read_character.py")
READER_FORMAT = "rh-imported-character/1"
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
