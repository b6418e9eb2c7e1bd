"""Finding and loading equirectangular HDRIs; the exposure normalisation.

Maps are equirectangular, linear Rec.709, mapped to directions as in docs/ARCHITECTURE.md ("Environment lights").
"""
from __future__ import annotations

import functools
import importlib.util
import math
from pathlib import Path

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance
from rh_common.imageio import ImageFileError, read_exr

from ..variant import load_mitsuba

__all__ = [
    "HdriError",
    "DEBIAN_STUDIOLIGHTS",
    "bundled_hdris",
    "hdri_library",
    "load_hdri",
    "normalised_scale",
    "downsample_equirect",
]

DEBIAN_STUDIOLIGHTS = Path("/usr/share/blender/datafiles/studiolights/world")
_EXTENSIONS = (".exr", ".hdr")


class HdriError(ValueError):
    """An HDRI that cannot be used; the one-line message names the file and the fix."""


def _bpy_studiolights() -> list[Path]:
    # find_spec only locates the package: importing bpy itself costs seconds and ~1 GB.
    try:
        spec = importlib.util.find_spec("bpy")
    except (ImportError, ValueError):
        return []
    if spec is None or not spec.submodule_search_locations:
        return []
    found: list[Path] = []
    for loc in spec.submodule_search_locations:
        found.extend(sorted(Path(loc).glob("*/datafiles/studiolights/world")))
    return found


def _scan(folder: Path) -> dict[str, Path]:
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in _EXTENSIONS)
    out: dict[str, Path] = {}
    for p in files:
        if p.stem in out:
            raise HdriError(f"{folder}: two maps named {p.stem!r} ({out[p.stem].name}, {p.name}); rename one")
        out[p.stem] = p
    return out


def bundled_hdris() -> dict[str, Path]:
    """The CC0 Poly Haven maps Blender ships: name (file stem) → path, sorted by name.

    Looks in Debian's blender-data folder, then in an installed `bpy` wheel's datafiles (without importing bpy).
    """
    for folder in [DEBIAN_STUDIOLIGHTS, *_bpy_studiolights()]:
        if folder.is_dir():
            found = _scan(folder)
            if found:
                return found
    raise FileNotFoundError(
        f"no bundled HDRIs found (looked in {DEBIAN_STUDIOLIGHTS} and the bpy wheel's datafiles); "
        "run `bash setup.sh` or `apt-get install blender-data`, or pass a folder of .exr/.hdr maps"
    )


def hdri_library(folder: str | Path | None = None) -> dict[str, Path]:
    """Maps available for sampling: every .exr/.hdr directly inside `folder` (name = stem), or the bundled ones."""
    if folder is None:
        return bundled_hdris()
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: not a folder of HDRIs")
    found = _scan(folder)
    if not found:
        raise FileNotFoundError(f"{folder}: contains no .exr or .hdr files")
    return found


def _read_any(path: Path) -> np.ndarray:
    if path.suffix.lower() == ".exr":
        try:
            return read_exr(path)
        except ImageFileError as exc:
            raise HdriError(f"{exc}; re-export it as a float32 RGB EXR") from None
    try:
        mi = load_mitsuba()  # Bitmap I/O is variant-independent: no variant is set here

        bmp = mi.Bitmap(str(path))
        bmp = bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        return np.array(bmp, dtype=np.float32)
    except Exception as exc:  # Mitsuba raises RuntimeError with multi-line text for unreadable files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise HdriError(f"{path}: not a readable Radiance .hdr file ({first}); re-export it as float32 EXR") from None


@functools.lru_cache(maxsize=16)
def _load_cached(path_str: str, mtime_ns: int, size: int) -> tuple[np.ndarray, int]:
    # Keyed on mtime and size too, so the cache stays a pure function of the file's content in practice.
    path = Path(path_str)
    img = _read_any(path)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise HdriError(f"{path}: expected an RGB(A) image, got shape {img.shape}; save it as RGB")
    img = img[..., :3]
    H, W, _ = img.shape
    if W != 2 * H:
        raise HdriError(f"{path}: {W}x{H} is not equirectangular (width must be 2 x height); use a lat-long map")
    if not np.all(np.isfinite(img)):
        bad = int(np.count_nonzero(~np.isfinite(img)))
        raise HdriError(f"{path}: {bad} NaN/Inf values; re-export it as float32 EXR (half overflows above 65504)")
    negative = int(np.count_nonzero(img < 0))
    # Negative values are lossy-compression ringing, not light: clamp (ARCHITECTURE.md) and count.
    out = np.ascontiguousarray(np.maximum(img, 0.0), dtype=np.float32)
    out.setflags(write=False)
    return out, negative


def load_hdri(path: str | Path) -> tuple[np.ndarray, int]:
    """Read an equirectangular HDRI (.exr via rh_common.imageio, .hdr via Mitsuba) → (radiance, clamped).

    ``radiance``: float32 (H, W, 3), read-only (cached), W == 2H, negatives clamped to 0;
    ``clamped``: how many channel values were negative. Raises HdriError (a ValueError) with a one-line message
    naming the file and the fix for a missing, unreadable, wrong-shaped or non-finite map.
    """
    path = Path(path)
    if not path.is_file():
        raise HdriError(f"{path}: no such HDRI file; check the path or run `bash setup.sh`")
    st = path.stat()
    return _load_cached(str(path.resolve()), st.st_mtime_ns, st.st_size)


def normalised_scale(radiance: np.ndarray) -> float:
    """The `scale` that makes the map's solid-angle-weighted mean luminance over the sphere 1.0.

    Exposure jitter is applied on top of it (``scale · 2**ev``) by the sampler.
    """
    arr = np.asarray(radiance)
    H, W = arr.shape[:2]
    mean = float(np.sum(luminance(arr).astype(np.float64) * sh.pixel_solid_angles(H, W)) / (4.0 * math.pi))
    if not (math.isfinite(mean) and mean > 0):
        raise ValueError(f"normalised_scale: map mean luminance is {mean!r}; an all-black map cannot be normalised")
    return 1.0 / mean


def downsample_equirect(radiance: np.ndarray, factor: int) -> np.ndarray:
    """Solid-angle-weighted block mean over factor x factor pixels (H, W divisible by factor), float64.

    Preserves ∫L dω exactly, so irradiance comparisons at low resolution see the same total light.
    """
    arr = np.asarray(radiance, dtype=np.float64)
    H, W, C = arr.shape
    if H % factor or W % factor:
        raise ValueError(f"downsample_equirect: {W}x{H} not divisible by {factor}")
    om = sh.pixel_solid_angles(H, W)[..., None]
    num = (arr * om).reshape(H // factor, factor, W // factor, factor, C).sum(axis=(1, 3))
    den = om.reshape(H // factor, factor, W // factor, factor, 1).sum(axis=(1, 3))
    return num / den
