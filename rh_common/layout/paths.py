"""Names and paths of a dataset and of a predictions folder (docs/ARCHITECTURE.md, "Dataset layout" and
"Predictions layout").

In: a root folder and the coordinates of a frame (subject index or name, protocol, split, frame index, layer).
Out: the file and folder names every reader and writer uses, so that no module types `frame_{:06d}` itself.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Iterator

__all__ = [
    "DATASET_JSON", "MANIFEST_JSON", "CHARACTER_JSON", "CONTACT_SHEET", "LOG_DIR", "METHOD_JSON", "TEST_SPLIT",
    "subject_name", "subject_index", "protocol_dir", "protocol_of", "split_dir", "frame_stem", "frame_json_name",
    "frame_json_path", "layer_file_name", "frame_index_of", "iter_frame_jsons", "splits_of",
    "view_name", "view_index", "view_dir", "views_of", "frame_folders", "frame_key",
    "PREDICTION_LAYERS", "PREDICTION_FILE_RE", "prediction_dir", "prediction_file",
]

DATASET_JSON = "dataset.json"
MANIFEST_JSON = "manifest.json"
CHARACTER_JSON = "character.json"
CONTACT_SHEET = "contact_sheet.png"
LOG_DIR = "logs"  # run logs beside a dataset (rh_common.runlog): a record of runs, not listed in the manifest
METHOD_JSON = "method.json"
TEST_SPLIT = "test"  # the split rh-eval scores and a method predicts unless told another (`--split`)

_SUBJECT_RE = re.compile(r"^subject_(\d{3,})$")
_FRAME_JSON_RE = re.compile(r"^frame_(\d{6})\.json$")
_VIEW_RE = re.compile(r"^cam_(\d{2,})$")


def subject_name(index: int) -> str:
    """subject_000, subject_001, ... (three digits; more only past 999)."""
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise ValueError(f"subject index must be a non-negative integer, got {index!r}")
    return f"subject_{index:03d}"


def subject_index(name: str) -> int:
    """Inverse of `subject_name`."""
    m = _SUBJECT_RE.match(name)
    if not m:
        raise ValueError(f"not a subject folder name (subject_NNN): {name!r}")
    return int(m.group(1))


def protocol_dir(protocol: str) -> str:
    """'a' (or 'protocol_a') → 'protocol_a'. Protocols are short lower-case names; anything else is refused so a
    typo never becomes a folder."""
    p = protocol[len("protocol_"):] if protocol.startswith("protocol_") else protocol
    if not re.fullmatch(r"[a-z0-9]+", p):
        raise ValueError(f"protocol must look like 'a' or 'protocol_a', got {protocol!r}")
    return f"protocol_{p}"


def protocol_of(dir_name: str) -> str:
    """'protocol_a' → 'a' (inverse of `protocol_dir`)."""
    return protocol_dir(dir_name)[len("protocol_"):]


def split_dir(root: str | Path, subject: str | int, protocol: str, split: str) -> Path:
    """`<root>/<subject>/protocol_<p>/<split>`: where one split's frames live."""
    name = subject_name(subject) if isinstance(subject, int) else subject
    return Path(root) / name / protocol_dir(protocol) / split


def view_name(index: int) -> str:
    """cam_00, cam_01, ...: the folder of one camera of a multi-view split (protocol c), two digits or more."""
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise ValueError(f"view index must be a non-negative integer, got {index!r}")
    return f"cam_{index:02d}"


def view_index(name: str) -> int | None:
    """Inverse of `view_name`; None if `name` is not a camera folder's name."""
    m = _VIEW_RE.match(name)
    return int(m.group(1)) if m else None


def view_dir(root: str | Path, subject: str | int, protocol: str, split: str, view: str | None = None) -> Path:
    """Where one camera's frames of a split live: `<split>/<view>` in a multi-view split, else the split folder."""
    d = split_dir(root, subject, protocol, split)
    return d if view is None else d / view


def views_of(folder: str | Path) -> list[str]:
    """The camera folders (cam_NN) of one subject's split folder, sorted; [] for a single-camera split."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and view_index(p.name) is not None)


def frame_folders(folder: str | Path) -> list[tuple[str | None, Path]]:
    """(view, folder holding frame JSONs) of one subject's split folder: each camera's in a multi-view split,
    else [(None, the split folder)]."""
    folder = Path(folder)
    views = views_of(folder)
    return [(v, folder / v) for v in views] if views else [(None, folder)]


def frame_key(subject: str, index: int, view: str | None = None) -> str:
    """'subject_000/frame_000000', or 'subject_000/cam_03/frame_000000' for a camera of a multi-view split: how
    the content identity, rh-eval's rows and thumbnails name a frame."""
    return f"{subject}/{frame_stem(index)}" if view is None else f"{subject}/{view}/{frame_stem(index)}"


def frame_stem(index: int) -> str:
    return f"frame_{index:06d}"


def frame_json_name(index: int) -> str:
    return f"{frame_stem(index)}.json"


def frame_json_path(folder: str | Path, index: int) -> Path:
    return Path(folder) / frame_json_name(index)


def layer_file_name(index: int, layer: str, ext: str) -> str:
    """`frame_000000_<layer>.<ext>`: the naming of dataset layers and of prediction files alike."""
    return f"{frame_stem(index)}_{layer}.{ext}"


def frame_index_of(json_name: str) -> int | None:
    """The index of a frame JSON's file name, or None if the name is not one."""
    m = _FRAME_JSON_RE.match(json_name)
    return int(m.group(1)) if m else None


def iter_frame_jsons(root: str | Path, protocol: str = "*", split: str = "*") -> Iterator[Path]:
    """Every frame JSON under a dataset root, sorted by path; `protocol` ('a') and `split` narrow the search.
    A multi-view split's frames are in its camera folders (`<split>/cam_NN/frame_*.json`)."""
    pdir = "protocol_*" if protocol == "*" else protocol_dir(protocol)
    found = list(Path(root).glob(f"subject_*/{pdir}/{split}/frame_*.json"))
    found += [p for p in Path(root).glob(f"subject_*/{pdir}/{split}/cam_*/frame_*.json")
              if view_index(p.parent.name) is not None]
    for p in sorted(found):
        if frame_index_of(p.name) is not None:
            yield p


def splits_of(root: str | Path, protocol: str) -> list[str]:
    """The splits of `protocol` that hold at least one frame JSON in some subject, sorted ('olat', 'test', ...)."""
    pdir = protocol_dir(protocol)
    return sorted({p.parent.name for p in Path(root).glob(f"subject_*/{pdir}/*/frame_*.json")
                   if frame_index_of(p.name) is not None}
                  | {p.parent.parent.name for p in Path(root).glob(f"subject_*/{pdir}/*/cam_*/frame_*.json")
                     if frame_index_of(p.name) is not None and view_index(p.parent.name) is not None})


# ------------------------------------------------------------------------------------------- predictions
PREDICTION_LAYERS = ("image", "albedo", "normal")
PREDICTION_FILE_RE = re.compile(r"^frame_(\d{6})_(image|albedo|normal)\.(exr|png)$")


def prediction_dir(root: str | Path, subject: str, protocol: str, split: str = TEST_SPLIT,
                   view: str | None = None) -> Path:
    """`<predictions>/<subject>/protocol_<p>/<split>` (`test` unless told): the mirror of that dataset split; a
    multi-view split's camera `view` adds its folder (`<split>/cam_NN`), as in the dataset."""
    return view_dir(root, subject, protocol, split, view)


def prediction_file(root: str | Path, subject: str, protocol: str, index: int, layer: str, ext: str = "exr",
                    split: str = TEST_SPLIT, view: str | None = None) -> Path:
    if layer not in PREDICTION_LAYERS or ext not in ("exr", "png"):
        raise ValueError(f"a prediction is one of {PREDICTION_LAYERS} as .exr or .png, got {layer!r}.{ext}")
    return prediction_dir(root, subject, protocol, split, view) / layer_file_name(index, layer, ext)
