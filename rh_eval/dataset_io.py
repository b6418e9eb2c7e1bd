"""Reading one scored split of the dataset (`test` unless told another, e.g. `olat`) and a predictions folder, per
docs/ARCHITECTURE.md (names and frame records through `rh_common.layout`), with every check that keeps a bad
prediction set from producing a silently different score.

Ground truth, per frame (`<dataset>/<subject>/protocol_<p>/<split>/`, or `<split>/cam_NN/` for each camera of a
multi-view split, protocol c): `frame_%06d.json` (complete frames only: the JSON is written last) with `exposure`,
`width`, `height`; layers `frame_%06d_{image.exr, mask.png, albedo.exr, normal.exr}`.

Predictions (`<pred>/<subject>/protocol_<p>/<split>/[cam_NN/]frame_%06d_{image,albedo,normal}.{exr,png}`, the
camera folder exactly where the dataset has one): the image is
required, albedo and normal optional but all-or-none across the frames. Refused, with the file named: a missing
frame (unless `allow_incomplete`), an extra or unrecognised file, a layer given both as EXR and PNG, a wrong
resolution, a wrong channel count, NaN/Inf, a PNG that is not 8-bit RGB/RGBA (16-bit, grey, palette), an
unreadable file.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.colourspace import srgb_decode, to_display
from rh_common.imageio import ImageFileError, read_exr, read_json, read_png, sha256_file
from rh_common.layout import protocol_dir

__all__ = [
    "PredictionError",
    "GTFrame",
    "DatasetIndex",
    "PredFrame",
    "PredictionIndex",
    "load_dataset",
    "scan_predictions",
    "read_gt_display",
    "read_gt_mask",
    "read_gt_albedo",
    "read_gt_normal",
    "read_pred_display",
    "read_pred_albedo",
    "read_pred_normal",
    "decode_normal_png",
    "protocol_dir",
    "check_header",
    "decode_layer",
    "display_from_stored",
    "albedo_from_stored",
    "normal_from_stored",
    "read_gt_image_stored",
]

LAYERS = layout.PREDICTION_LAYERS
_PRED_RE = layout.PREDICTION_FILE_RE


class PredictionError(ValueError):
    """Problems with a predictions folder; `problems` lists them, each naming its file."""

    def __init__(self, root: Path, problems: list[str]) -> None:
        self.problems = list(problems)
        shown = "\n".join(f"  - {p}" for p in self.problems[:50])
        more = f"\n  ... and {len(self.problems) - 50} more" if len(self.problems) > 50 else ""
        super().__init__(f"{len(self.problems)} problem(s) with predictions {root}:\n{shown}{more}")


@dataclass(frozen=True)
class GTFrame:
    subject: str
    index: int
    folder: Path
    width: int
    height: int
    exposure: float
    view: str | None = None
    """The camera (cam_NN) of a multi-view split's frame; None for a single-camera split."""

    @property
    def key(self) -> str:
        return layout.frame_key(self.subject, self.index, self.view)

    def layer(self, name: str) -> Path:
        """`name` is '<layer>.<ext>', e.g. 'image.exr'."""
        stem, ext = name.rsplit(".", 1)
        return self.folder / layout.layer_file_name(self.index, stem, ext)

    @property
    def json_path(self) -> Path:
        return layout.frame_json_path(self.folder, self.index)


@dataclass
class DatasetIndex:
    root: Path
    protocol: str  # "a", "b", ...
    frames: list[GTFrame]
    manifest_sha256: str
    subjects: list[str]
    split: str = layout.TEST_SPLIT  # the scored split: "test", or another such as "olat"


@dataclass
class PredFrame:
    gt: GTFrame
    image: Path | None = None
    albedo: Path | None = None
    normal: Path | None = None


@dataclass
class PredictionIndex:
    root: Path
    method: dict
    frames: list[PredFrame]  # frames with an image prediction, in dataset order
    missing: list[str] = field(default_factory=list)  # human-readable, each naming the expected file
    has_albedo: bool = False
    has_normal: bool = False


def load_dataset(root: str | Path, protocol: str, split: str = layout.TEST_SPLIT) -> DatasetIndex:
    """Index one split (default test) of `protocol` in the dataset at `root` (complete frames = those with a JSON).
    A split the dataset lacks is refused in one line listing the splits it has."""
    root = Path(root)
    pdir = protocol_dir(protocol)
    manifest = root / layout.MANIFEST_JSON
    if not manifest.is_file():
        raise FileNotFoundError(f"{manifest}: dataset manifest not found (is {root} a dataset folder?)")
    has = layout.splits_of(root, pdir)
    if has and split not in has:
        raise FileNotFoundError(f"{root}: no {split!r} split for {pdir}; it has: {', '.join(has)} "
                                f"(choose one with --split)")
    frames: list[GTFrame] = []
    subjects = sorted(d.name for d in root.iterdir()
                      if d.is_dir() and layout.split_dir(root, d.name, pdir, split).is_dir())
    for subject in subjects:
        for view, folder in layout.frame_folders(layout.split_dir(root, subject, pdir, split)):
            for jp in sorted(folder.iterdir()):
                index = layout.frame_index_of(jp.name)
                if index is None:
                    continue
                try:
                    rec = layout.read_frame_record(jp)
                except ValueError as exc:
                    raise ValueError(f"{jp}: not a valid frame record (width, height, exposure, ...): {exc}") from exc
                frames.append(GTFrame(subject, index, folder, rec.width, rec.height, float(rec.exposure), view))
    if not frames:
        raise FileNotFoundError(f"{root}: no {split} frames for {pdir} "
                                f"(expected <subject>/{pdir}/{split}/frame_*.json)")
    return DatasetIndex(root, layout.protocol_of(pdir), frames, sha256_file(manifest), subjects, split)


def scan_predictions(pred_root: str | Path, ds: DatasetIndex, *, allow_incomplete: bool = False) -> PredictionIndex:
    """Match the files of a predictions folder to the frames of the dataset's scored split (`ds.split`); raise
    `PredictionError` listing every problem found (missing frames are tolerated with `allow_incomplete`, reported in
    `missing`)."""
    root = Path(pred_root)
    if not root.is_dir():
        raise PredictionError(root, [f"{root}: not a folder"])
    method: dict = {"name": root.resolve().name}
    mj = root / layout.METHOD_JSON
    problems: list[str] = []
    if mj.is_file():
        try:
            loaded = read_json(mj)
            if not isinstance(loaded, dict):
                raise ValueError("not a JSON object")
            if loaded.get("kind", "method") not in ("method", "bound"):
                raise ValueError(f"'kind' must be 'method' or 'bound', got {loaded.get('kind')!r}")
            method.update(loaded)
        except ValueError as exc:
            problems.append(f"{mj}: {exc}")
    pdir = protocol_dir(ds.protocol)
    by_key = {f.key: f for f in ds.frames}
    found: dict[str, dict[str, Path]] = {}
    for entry in sorted(root.iterdir()):
        if entry.name.startswith(".") or entry.is_file():
            continue  # method.json, READMEs, dotfiles
        if entry.name not in ds.subjects:
            problems.append(f"{entry}: unexpected folder (not a subject of the dataset's {pdir} {ds.split} split)")
            continue
        views = sorted({f.view for f in ds.frames if f.subject == entry.name and f.view is not None})
        test = layout.prediction_dir(root, entry.name, pdir, ds.split)
        if not test.is_dir():
            continue  # counted as missing below
        folders = [(None, test)]
        if views:  # a multi-view split: predictions in the dataset's camera folders, nothing beside them
            folders = [(v, test / v) for v in views if (test / v).is_dir()]
            for f in sorted(test.iterdir()):
                if not f.name.startswith(".") and f.name not in views:
                    problems.append(f"{f}: unexpected {'folder' if f.is_dir() else 'file'} (this split's "
                                    f"predictions go in its camera folders: {', '.join(views)})")
        for view, folder in folders:
            for f in sorted(folder.iterdir()):
                if f.name.startswith("."):
                    continue
                m = _PRED_RE.match(f.name)
                if not m or not f.is_file():
                    problems.append(f"{f}: unexpected file (expected frame_NNNNNN_{{image,albedo,normal}}.{{exr,png}})")
                    continue
                key = layout.frame_key(entry.name, int(m.group(1)), view)
                if key not in by_key:
                    problems.append(f"{f}: extra frame (no ground-truth frame {key} in the {ds.split} split)")
                    continue
                layers = found.setdefault(key, {})
                if m.group(2) in layers:
                    problems.append(f"{f}: layer given twice ({layers[m.group(2)].name} and {f.name}); keep one")
                    continue
                layers[m.group(2)] = f
    frames: list[PredFrame] = []
    missing: list[str] = []
    any_albedo = any("albedo" in v for v in found.values())
    any_normal = any("normal" in v for v in found.values())
    for gt in ds.frames:
        layers = found.get(gt.key, {})
        if "image" not in layers:
            expected = layout.prediction_file(root, gt.subject, pdir, gt.index, "image", split=ds.split, view=gt.view)
            missing.append(f"{expected} (or .png): missing frame")
            continue
        for name, present in (("albedo", any_albedo), ("normal", any_normal)):
            if present and name not in layers:
                expected = layout.prediction_file(root, gt.subject, pdir, gt.index, name, split=ds.split, view=gt.view)
                missing.append(f"{expected} (or .png): missing {name} (other frames have one)")
        frames.append(PredFrame(gt, layers.get("image"), layers.get("albedo"), layers.get("normal")))
    if missing and not allow_incomplete:
        problems.extend(missing)
        problems.append("(use --allow-incomplete to evaluate what exists; the result is then marked incomplete)")
    if problems:
        raise PredictionError(root, problems)
    return PredictionIndex(root, method, frames, missing, any_albedo, any_normal)


# --------------------------------------------------------------------------------------------- file checks
def _png_header(path: Path) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from the IHDR chunk. Pillow reads a 16-bit RGB PNG as 8-bit RGB
    without saying so, hence this check before decoding."""
    try:
        with open(path, "rb") as f:
            head = f.read(33)
    except OSError as exc:
        raise ImageFileError(f"{path}: cannot read ({exc})") from exc
    if len(head) < 33 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        raise ImageFileError(f"{path}: not a PNG file (bad signature or header)")
    w, h, depth, ctype = struct.unpack(">IIBB", head[16:26])
    return w, h, depth, ctype


_PNG_CTYPES = {0: "greyscale (1 channel)", 2: "RGB", 3: "palette", 4: "greyscale+alpha (2 channels)", 6: "RGBA"}


def _read_rgb_png(path: Path, frame: GTFrame, smaller_ok: bool = False) -> np.ndarray:
    w, h, depth, ctype = _png_header(path)
    _check_png_type(path, depth, ctype)
    _check_size(path, (h, w), frame, smaller_ok)
    arr = read_png(path)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.dtype != np.uint8:
        raise ImageFileError(f"{path}: decoded to shape {arr.shape} {arr.dtype}; expected 8-bit RGB or RGBA")
    return arr[..., :3]


def _check_size(path: Path, hw: tuple[int, int], frame: GTFrame, smaller_ok: bool = False) -> None:
    if smaller_ok and 0 < hw[0] <= frame.height and 0 < hw[1] <= frame.width:
        return  # a convention that resamples the ground truth to the prediction's size (`resampling="area"`)
    if tuple(hw) != (frame.height, frame.width):
        raise ImageFileError(f"{path}: resolution {hw[1]}x{hw[0]} (WxH) differs from the ground truth's "
                             f"{frame.width}x{frame.height}; write it at {frame.width}x{frame.height}")


def _exr_header(path: Path) -> tuple[list[str], tuple[int, int]]:
    """(channel names, (height, width) of the data window) without decoding any pixel."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path), header_only=True) as f:
            parts = f.parts
            if len(parts) != 1:
                raise ImageFileError(f"{path}: multi-part EXR ({len(parts)} parts); write one RGB part")
            head = parts[0].header
            names = [c.name for c in head["channels"]]
            lo, hi = head["dataWindow"]
    except ImageFileError:
        raise
    except Exception as exc:  # OpenEXR raises plain Exceptions for corrupt files
        raise ImageFileError(f"{path}: not a readable EXR file ({exc}); re-export it") from exc
    return names, (int(hi[1]) - int(lo[1]) + 1, int(hi[0]) - int(lo[0]) + 1)


def check_header(path: Path, frame: GTFrame, smaller_ok: bool = False) -> None:
    """Everything about a prediction file that its header tells, without decoding pixels: it exists, it is a PNG or
    EXR, its resolution, channel count and (PNG) bit depth. Raises `ImageFileError` naming the file."""
    if not path.is_file():
        raise ImageFileError(f"{path}: no such file")
    if path.suffix == ".png":
        w, h, depth, ctype = _png_header(path)
        _check_png_type(path, depth, ctype)
        _check_size(path, (h, w), frame, smaller_ok)
        return
    names, hw = _exr_header(path)
    if sorted(names) not in (["B", "G", "R"], ["A", "B", "G", "R"]):
        raise ImageFileError(f"{path}: {len(names)} channel(s) ({','.join(sorted(names))}); expected R,G,B (or "
                             f"R,G,B,A, alpha ignored)")
    _check_size(path, hw, frame, smaller_ok)


def _check_png_type(path: Path, depth: int, ctype: int) -> None:
    if depth != 8:
        raise ImageFileError(f"{path}: {depth}-bit PNG; predictions must be 8-bit RGB or RGBA (or float32 EXR)")
    if ctype not in (2, 6):
        raise ImageFileError(f"{path}: PNG colour type {_PNG_CTYPES.get(ctype, ctype)}; expected 8-bit RGB or RGBA "
                             f"(3 or 4 channels)")


def _check_finite(path: Path, arr: np.ndarray) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        per_pixel = bad.any(axis=-1)
        y, x = (int(v[0]) for v in np.nonzero(per_pixel))
        raise ImageFileError(f"{path}: {int(per_pixel.sum())} pixel(s) with NaN or Inf (first at x={x}, y={y}); "
                             f"write finite values")


def decode_layer(path: Path, frame: GTFrame, smaller_ok: bool = False) -> np.ndarray:
    """A prediction layer decoded and fully checked, in its stored form: uint8 (H, W, 3) for a PNG, finite float32
    (H, W, 3) for an EXR (alpha dropped). `read_pred_*` turn it into values; the evaluator decodes every prediction
    file this way before it computes anything."""
    if path.suffix == ".png":
        return _read_rgb_png(path, frame, smaller_ok)
    return _read_rgb_exr32(path, frame, smaller_ok)


def _read_rgb_exr32(path: Path, frame: GTFrame, smaller_ok: bool = False) -> np.ndarray:
    arr = read_exr(path)
    _check_size(path, arr.shape[:2], frame, smaller_ok)
    if arr.shape[2] not in (3, 4):
        raise ImageFileError(f"{path}: {arr.shape[2]} channel(s); expected R,G,B (or R,G,B,A, alpha ignored)")
    arr = arr[..., :3]
    _check_finite(path, arr)
    return arr


def _read_rgb_exr(path: Path, frame: GTFrame) -> np.ndarray:
    return _read_rgb_exr32(path, frame).astype(np.float64)


# --------------------------------------------------------------------------------------------- ground truth
def read_gt_display(frame: GTFrame) -> np.ndarray:
    return display_from_stored(_read_rgb_exr32(frame.layer("image.exr"), frame), frame).astype(np.float64)


def read_gt_mask(frame: GTFrame) -> np.ndarray:
    path = frame.layer("mask.png")
    arr = read_png(path)
    if arr.ndim == 3:  # tolerate an RGB-saved mask whose channels agree
        if not np.all(arr[..., :3] == arr[..., :1]):
            raise ImageFileError(f"{path}: mask has differing colour channels; expected 8-bit greyscale")
        arr = arr[..., 0]
    _check_size(path, arr.shape, frame)
    return arr.astype(np.uint8)


def read_gt_image_stored(frame: GTFrame) -> np.ndarray:
    """The ground-truth radiance, finite float32 (H, W, 3)."""
    return _read_rgb_exr32(frame.layer("image.exr"), frame)


def read_gt_albedo(frame: GTFrame) -> np.ndarray:
    """Linear albedo, float64 in [0, 1]."""
    return np.clip(_read_rgb_exr(frame.layer("albedo.exr"), frame), 0.0, 1.0)


def read_gt_normal(frame: GTFrame) -> np.ndarray:
    return _read_rgb_exr(frame.layer("normal.exr"), frame)


# --------------------------------------------------------------------------------------------- predictions
# Each `*_from_stored` takes what `decode_layer` returned (or a crop of it: every conversion is per pixel, so the
# evaluator crops to the evaluated region first and converts only that).
_PNG_TO_UNIT = np.arange(256, dtype=np.float64) / 255.0  # the exact values of v / 255.0, looked up


def display_from_stored(stored: np.ndarray, frame: GTFrame) -> np.ndarray:
    """Display-space image: EXR radiance with the ground truth's exposure (float32), PNG as is (float64)."""
    if stored.dtype == np.uint8:
        return _PNG_TO_UNIT[stored]
    return to_display(stored, frame.exposure)


def albedo_from_stored(stored: np.ndarray) -> np.ndarray:
    """Linear albedo, float64 in [0, 1]: EXR clipped to [0, 1] (the albedo range), PNG sRGB-decoded."""
    if stored.dtype == np.uint8:
        return srgb_decode(_PNG_TO_UNIT[stored]).astype(np.float64)
    return np.clip(stored.astype(np.float64), 0.0, 1.0)


def normal_from_stored(stored: np.ndarray) -> np.ndarray:
    """Normal vectors, float64, not yet renormalised."""
    if stored.dtype == np.uint8:
        return decode_normal_png(stored)
    return stored.astype(np.float64)


def read_pred_display(path: Path, frame: GTFrame) -> np.ndarray:
    """An image prediction in display space: EXR radiance with the ground truth's exposure, PNG as is."""
    return display_from_stored(decode_layer(path, frame), frame).astype(np.float64)


def read_pred_albedo(path: Path, frame: GTFrame) -> np.ndarray:
    """Linear albedo: EXR as stored (clipped to [0, 1], the albedo range), PNG sRGB-decoded."""
    return albedo_from_stored(decode_layer(path, frame))


def decode_normal_png(v: np.ndarray) -> np.ndarray:
    """8-bit encoded normals to vectors: 2 v / 255 - 1 (renormalised by the metric)."""
    return 2.0 * np.asarray(v, dtype=np.float64) / 255.0 - 1.0


def read_pred_normal(path: Path, frame: GTFrame) -> np.ndarray:
    """Camera-space normal vectors (OpenGL convention), not yet renormalised."""
    return normal_from_stored(decode_layer(path, frame))
