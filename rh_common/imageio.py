"""The one image and file I/O module: float32 EXR, 8-bit PNG, Radiance RGBE .hdr, lossy WebP previews, JSON,
all written atomically.

Atomic means: write to a temporary file in the destination folder, flush and fsync it, then rename it over the
destination. A reader (or a rerun after `kill -9`) therefore sees either the old file, the complete new file, or
no file, never a truncated one.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import OpenEXR
from PIL import Image

from rh_common.interrupt import checkpoint

__all__ = [
    "ImageFileError",
    "atomic_path",
    "atomic_dir",
    "read_exr",
    "write_exr",
    "read_png",
    "write_png",
    "write_hdr",
    "read_hdr",
    "write_webp",
    "read_json",
    "write_json",
    "dumps_json",
    "sha256_file",
]



class ImageFileError(ValueError):
    """A file that cannot be read as the image the caller expects; the message names the file."""


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to `path`; on success fsync it and rename it to `path`.

    The temporary name ends in `.tmp` so that a leftover from a killed process is recognisable and never taken for
    a finished file. The finished file gets the mode a plain `open()` would give it (0666 less the umask):
    the temporary file is created 0600 and a rename keeps the mode, which would leave a dataset unreadable to the
    rest of a group on a shared filesystem.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # The temporary file's name is known (`tmp_path` set) before the file exists, and it is created by one
    # exclusive open: an interruption (rh_common.interrupt raises at any bytecode, including for a signal that
    # arrived just before) then lands either before the file exists or where the `finally` below knows it and
    # removes it. (tempfile.mkstemp creates the file inside a Python loop and returns its name only after: a Ctrl-C
    # delivered in between left a `.tmp` file behind, seen under load in tests/test_interrupt.py.)
    tmp_path = None
    try:
        while True:
            tmp_path = path.parent / f".{path.name}.{os.urandom(6).hex()}.tmp"
            try:
                os.close(os.open(tmp_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                break
            except FileExistsError:  # another writer's name (a 48-bit random collision): never ours to remove
                tmp_path = None
        yield tmp_path
        # A stop that arrived while this file was computed may have been lost in a C callback (rh_common.interrupt):
        # then what was computed may be wrong, and it is not kept.
        checkpoint()
        with open(tmp_path, "rb+") as f:
            os.fchmod(f.fileno(), 0o666 & ~_umask())
            os.fsync(f.fileno())
        os.replace(tmp_path, path)
    except OSError as exc:
        # A full disk inside an encoder (PIL, OpenEXR) names no file, or names the temporary one: name the file
        # being written, which is what the user knows (rh_common.interrupt turns this into one line).
        if exc.errno is not None and (exc.filename is None or (tmp_path and str(exc.filename) == str(tmp_path))):
            raise OSError(exc.errno, exc.strerror or os.strerror(exc.errno), str(path)) from exc
        raise
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()


@contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a new empty folder next to `path`; on success it replaces `path` whole (the old folder, if any, is
    renamed aside, the new one renamed in, the old one deleted), so a reader sees the old set of files or the new
    one. Each file inside is still written with `atomic_path` (fsynced). On error the new folder is removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes it 0700
        old = None
        if path.exists():
            old = path.with_name(f".{path.name}.old-{os.getpid()}.tmp")
            os.replace(path, old)
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _umask() -> int:
    """The process's umask, read without changing it where Linux allows (`os.umask` can only set it, and setting
    it twice to read it is a race with other threads creating files)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    old = os.umask(0o022)
    os.umask(old)
    return old


def _channel_names(n: int) -> tuple[str, ...]:
    return {1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}[n]


def write_exr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) array as a float32 EXR (ZIP compression), atomically.

    float32 always: half floats overflow at 65504, which the sun in a real HDRI exceeds.
    """
    arr = np.asarray(image)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 3, 4):
        raise ValueError(f"write_exr {path}: expected (H, W[, 1|3|4]), got shape {np.shape(image)}")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    names = _channel_names(arr.shape[2])
    channels = {name: np.ascontiguousarray(arr[..., i]) for i, name in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            try:
                f.write(str(tmp))
            except RuntimeError as exc:
                raise _exr_os_error(exc, path) from exc


def _exr_os_error(exc: RuntimeError, path) -> Exception:
    """OpenEXR reports a full disk as a RuntimeError whose text carries strerror: give it back its errno, so that a
    full disk reads the same whichever encoder hit it."""
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EROFS, errno.EIO):
        if os.strerror(code) in str(exc):
            return OSError(code, os.strerror(code), str(path))
    return exc


def read_exr(path: str | os.PathLike) -> np.ndarray:
    """Read an EXR as float32 (H, W, C): C = 1 for a `Y` image, 3 for RGB, 4 for RGBA. Half is widened."""
    path = Path(path)
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            chans = f.channels()
            names = list(chans.keys())
            data = {k: np.asarray(v.pixels) for k, v in chans.items()}
    except Exception as exc:  # OpenEXR raises plain Exceptions for corrupt files
        raise ImageFileError(f"{path}: not a readable EXR file ({exc})") from exc
    for wanted in (("R", "G", "B", "A"), ("R", "G", "B"), ("Y",)):
        if all(w in data for w in wanted) and len(data) == len(wanted):
            return np.stack([data[w].astype(np.float32) for w in wanted], axis=-1)
    if len(names) == 1:
        return data[names[0]].astype(np.float32)[..., None]
    raise ImageFileError(f"{path}: unexpected EXR channels {sorted(names)}; expected R,G,B[,A] or Y")


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a uint8 (H, W), (H, W, 3) or (H, W, 4) array as PNG, atomically. Floats are refused: quantise first
    (`rh_common.colourspace.quantize8`) so the rounding rule is the project's, not Pillow's."""
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        raise ValueError(f"write_png {path}: expected uint8, got {arr.dtype}; quantise with colourspace.quantize8")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] in (3, 4))):
        raise ValueError(f"write_png {path}: expected (H, W[, 3|4]), got shape {arr.shape}")
    # zlib level 1, not Pillow's 6: a 512x512 beauty preview encodes ~4x faster for ~25% more bytes (0.86 against
    # 0.69 bytes per pixel, bench/bench_writer.py); the pixels are the same (PNG is lossless).
    with atomic_path(path) as tmp:
        Image.fromarray(arr).save(tmp, format="PNG", compress_level=1)


def write_webp(path: str | os.PathLike, image: np.ndarray, *, quality: int = 80) -> None:
    """Write a uint8 (H, W, 3) array as lossy WebP (libwebp, `quality` 0-100, slowest/smallest method 6),
    atomically. For small previews only (rh-eval's thumbnails): lossy, never for data that is scored."""
    arr = np.asarray(image)
    if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"write_webp {path}: expected uint8 (H, W, 3), got {arr.dtype} {arr.shape}; quantise with "
                         f"colourspace.quantize8")
    with atomic_path(path) as tmp:
        Image.fromarray(np.ascontiguousarray(arr)).save(tmp, format="WEBP", quality=int(quality), method=6)


def read_png(path: str | os.PathLike, *, allow_16bit: bool = False) -> np.ndarray:
    """Read an 8-bit PNG as uint8 (H, W) or (H, W, C). A 16-bit PNG raises unless `allow_16bit`, because silently
    rescaling it would change every score computed from it."""
    path = Path(path)
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    try:
        with open(path, "rb") as f:
            head = f.read(26)
        # Pillow decodes a 16-bit RGB(A) PNG as 8-bit without a word; the IHDR bit depth (byte 24) tells.
        if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR" and head[24] == 16 and not allow_16bit:
            raise ImageFileError(f"{path}: 16-bit PNG; save it as 8-bit RGB (or as float32 EXR)")
        with Image.open(path) as im:
            im.load()
            mode = im.mode
            if mode in ("I;16", "I;16B", "I;16L", "I"):
                if not allow_16bit:
                    raise ImageFileError(f"{path}: 16-bit PNG; save it as 8-bit RGB (or as float32 EXR)")
                return np.asarray(im).astype(np.uint16)
            if mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            elif mode not in ("L", "RGB", "RGBA", "LA"):
                raise ImageFileError(f"{path}: unsupported PNG mode {mode}; save it as 8-bit RGB")
            return np.asarray(im).copy()
    except ImageFileError:
        raise
    except Exception as exc:
        raise ImageFileError(f"{path}: not a readable PNG file ({exc})") from exc


_HDR_MAGIC = b"#?RADIANCE"


def write_hdr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write (H, W, 3) linear RGB as a Radiance RGBE `.hdr` (flat scanlines, top row first), atomically.

    For readers without EXR support (OpenCV builds leave EXR off by default; loaders written for Poly Haven's `.hdr`
    maps). RGBE keeps a shared 8-bit exponent, so each channel is exact to 1/256 of the pixel's largest channel (rounded: readers such as OpenCV decode
    `byte · 2**(e − 136)` with no half-step);
    negative values cannot be stored and are written as 0. Flat (not run-length encoded) scanlines are part of the
    format every reader accepts. Non-finite input is refused: it has no RGBE encoding.
    """
    arr = np.asarray(image, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"write_hdr {path}: expected (H, W, 3), got shape {np.shape(image)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"write_hdr {path}: image contains NaN or Inf")
    arr = np.maximum(arr, 0.0)
    H, W, _ = arr.shape
    v = arr.max(axis=-1)
    mant, exp = np.frexp(v)  # v = mant * 2**exp, mant in [0.5, 1)
    rgbe = np.zeros((H, W, 4), np.uint8)
    ok = v >= 1e-32
    scale = np.where(ok, mant * 256.0 / np.where(ok, v, 1.0), 0.0)
    rgbe[..., :3] = np.clip(np.rint(arr * scale[..., None]), 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(ok, np.clip(exp + 128, 0, 255), 0).astype(np.uint8)
    head = _HDR_MAGIC + b"\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {H} +X {W}\n".encode()
    with atomic_path(path) as tmp:
        tmp.write_bytes(head + rgbe.tobytes())


def read_hdr(path: str | os.PathLike) -> np.ndarray:
    """Read a `.hdr` written by `write_hdr` (flat RGBE, `-Y H +X W`) as float32 (H, W, 3); other layouts raise."""
    path = Path(path)
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    data = path.read_bytes()
    if not data.startswith(_HDR_MAGIC) and not data.startswith(b"#?RGBE"):
        raise ImageFileError(f"{path}: not a Radiance .hdr file")
    end = data.find(b"\n\n")
    nl = data.find(b"\n", end + 2) if end >= 0 else -1
    try:
        ydir, H, xdir, W = data[end + 2:nl].decode().split()
        H, W = int(H), int(W)
    except ValueError:
        raise ImageFileError(f"{path}: unreadable .hdr resolution line") from None
    body = np.frombuffer(data, np.uint8, offset=nl + 1)
    if (ydir, xdir) != ("-Y", "+X") or body.size != H * W * 4:
        raise ImageFileError(f"{path}: only flat '-Y H +X W' RGBE .hdr files are read here (write them with "
                             f"rh_common.imageio.write_hdr)")
    rgbe = body.reshape(H, W, 4).astype(np.float64)
    f = np.where(rgbe[..., 3] > 0, np.ldexp(1.0, rgbe[..., 3].astype(np.int64) - (128 + 8)), 0.0)
    return (rgbe[..., :3] * f[..., None]).astype(np.float32)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")


def dumps_json(obj: Any) -> str:
    """Canonical JSON text: sorted keys, 2-space indent, NaN refused (strict JSON), trailing newline."""
    return json.dumps(obj, sort_keys=True, indent=2, default=_json_default, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, obj: Any) -> None:
    text = dumps_json(obj)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def read_json(path: str | os.PathLike) -> Any:
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from exc


def sha256_file(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
