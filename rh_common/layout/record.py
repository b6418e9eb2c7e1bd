"""The frame record: the typed form of `frame_%06d.json` (docs/ARCHITECTURE.md, "Frame JSON").

In: the JSON object a frame file holds (or the generator's metadata plus the written file list).
Out: a `FrameRecord` whose `to_json()` gives back the same object key for key, so that reading then writing a
frame reproduces its bytes; `read_frame_record` / `write_frame_record` do the file I/O.

Top-level keys are typed and checked; the nested sections (camera, body, light, render, versions) stay plain
JSON objects, because each has its own reader (`body.pose`: `rh_common.layout.pose`) and the generator adds to
them (a motion record, the scene model) without a format change.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, Mapping

from rh_common.imageio import read_json, write_json

from .paths import view_index
from .pose import PoseArrays, read_body_pose

__all__ = ["FRAME_FORMAT", "FileEntry", "FrameRecord", "read_frame_record", "write_frame_record"]

FRAME_FORMAT = "rh-frame/1"

_OPTIONAL = ("camera", "body", "light", "render", "versions")
_KEYS = {"format", "subject", "protocol", "split", "index", "width", "height", "exposure", "files", "view",
         *_OPTIONAL}


@dataclasses.dataclass(frozen=True)
class FileEntry:
    """One file a frame lists: the layer it belongs to and its sha256."""

    layer: str
    sha256: str


@dataclasses.dataclass(frozen=True)
class FrameRecord:
    """One frame's JSON. `camera`, `body`, `light`, `render`, `versions` are None when a writer records none (a
    test fake of the evaluator has no body); `rh-generate` and `rana.synthetic` always write all five."""

    subject: str
    protocol: str
    split: str
    index: int
    width: int
    height: int
    exposure: float
    files: Mapping[str, FileEntry]
    camera: Mapping[str, Any] | None = None
    body: Mapping[str, Any] | None = None
    light: Mapping[str, Any] | None = None
    render: Mapping[str, Any] | None = None
    versions: Mapping[str, Any] | None = None
    view: str | None = None
    """The camera (cam_NN, its folder) of a frame of a multi-view split (protocol c); None (absent) otherwise."""
    format: str = FRAME_FORMAT

    def __post_init__(self) -> None:
        if self.format != FRAME_FORMAT:
            raise ValueError(f"frame format {self.format!r} is not {FRAME_FORMAT!r}")
        for name in ("subject", "protocol", "split"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"frame record: {name!r} must be a non-empty string, got {getattr(self, name)!r}")
        for name in ("index", "width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ValueError(f"frame record: {name!r} must be a non-negative integer, got {v!r}")
        if self.view is not None and (not isinstance(self.view, str) or view_index(self.view) is None):
            raise ValueError(f"frame record: 'view' must be a camera folder name (cam_NN), got {self.view!r}")
        if isinstance(self.exposure, bool) or not isinstance(self.exposure, (int, float)) or not self.exposure > 0:
            raise ValueError(f"frame record: 'exposure' must be a positive number, got {self.exposure!r}")
        for name, entry in self.files.items():
            if not isinstance(entry, FileEntry):
                raise ValueError(f"frame record: files[{name!r}] must be a FileEntry, got {type(entry).__name__}")

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FrameRecord:
        """From the JSON object; unknown keys are refused (a misspelt key would otherwise vanish on rewrite)."""
        if not isinstance(data, Mapping):
            raise ValueError(f"frame record: expected a JSON object, got {type(data).__name__}")
        if unknown := set(data) - _KEYS:
            raise ValueError(f"frame record: unknown keys {sorted(unknown)}")
        if missing := {"subject", "protocol", "split", "index", "width", "height", "exposure", "files"} - set(data):
            raise ValueError(f"frame record: missing keys {sorted(missing)}")
        try:
            files = {str(n): FileEntry(str(e["layer"]), str(e["sha256"])) for n, e in data["files"].items()}
        except (AttributeError, KeyError, TypeError) as exc:
            raise ValueError(f"frame record: 'files' must map file names to {{layer, sha256}} ({exc!r})") from exc
        return cls(subject=data["subject"], protocol=data["protocol"], split=data["split"], index=data["index"],
                   width=data["width"], height=data["height"], exposure=data["exposure"], files=files,
                   format=data.get("format", ""), view=data.get("view"), **{k: data.get(k) for k in _OPTIONAL})

    def to_json(self) -> dict[str, Any]:
        """The JSON object (dumped with sorted keys by `rh_common.imageio.write_json`)."""
        out: dict[str, Any] = {
            "format": self.format, "subject": self.subject, "protocol": self.protocol, "split": self.split,
            "index": self.index, "width": self.width, "height": self.height, "exposure": self.exposure,
            "files": {n: {"layer": e.layer, "sha256": e.sha256} for n, e in self.files.items()},
        }
        out.update({k: getattr(self, k) for k in _OPTIONAL if getattr(self, k) is not None})
        if self.view is not None:
            out["view"] = self.view
        return out

    def files_of(self, layer: str) -> list[str]:
        """The file names of one layer, sorted (EXR before PNG)."""
        return sorted(n for n, e in self.files.items() if e.layer == layer)

    @property
    def layers(self) -> set[str]:
        return {e.layer for e in self.files.values()}

    def pose(self) -> PoseArrays:
        """`body.pose` read into arrays (anny bodies only: an imported rig's pose has its own skeleton)."""
        if not self.body or self.body.get("model") != "anny":
            raise ValueError(f"frame {self.subject}/{self.split}/{self.index}: no anny body pose recorded")
        return read_body_pose(self.body["pose"])


def read_frame_record(path: str | os.PathLike) -> FrameRecord:
    path = Path(path)
    try:
        return FrameRecord.from_json(read_json(path))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from exc


def write_frame_record(path: str | os.PathLike, record: FrameRecord) -> Path:
    write_json(path, record.to_json())
    return Path(path)
