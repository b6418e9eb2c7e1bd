"""The one writer of method outputs, in the predictions layout `rh-eval` reads (docs/ARCHITECTURE.md).

In: a dataset's test frames (read through `rh_common.layout`) and a method's float arrays per frame.
Out: `<out>/method.json` and `<out>/<subject>/protocol_<p>/test/frame_%06d_{image,albedo,normal}.exr`.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from rh_common import layout
from rh_common.imageio import write_exr, write_json

__all__ = ["TestFrame", "iter_test_frames", "PredictionWriter"]


@dataclass(frozen=True)
class TestFrame:
    subject: str
    protocol: str
    index: int
    split_dir: Path
    meta: dict

    def layer_path(self, layer: str, ext: str = "exr") -> Path:
        return self.split_dir / layout.layer_file_name(self.index, layer, ext)

    @property
    def json_path(self) -> Path:
        return layout.frame_json_path(self.split_dir, self.index)


def iter_test_frames(dataset: str | Path, protocol: str) -> Iterator[TestFrame]:
    """Every test frame of one protocol, in subject then frame order."""
    root = Path(dataset)
    paths = list(layout.iter_frame_jsons(root, protocol, layout.TEST_SPLIT))
    if not paths:
        pattern = f"subject_*/{layout.protocol_dir(protocol)}/{layout.TEST_SPLIT}/frame_*.json"
        raise FileNotFoundError(f"{root}: no test frames of protocol {protocol} ({pattern}); generate them with "
                                f"`rh-generate --protocol {protocol} --out {root}`")
    for p in paths:
        record = layout.read_frame_record(p)
        yield TestFrame(record.subject, record.protocol, record.index, p.parent, record.to_json())


class PredictionWriter:
    """Writes `<out>/method.json` once, then per frame `layout.prediction_file(...)` for each layer given."""

    def __init__(self, out: str | Path, method: dict):
        if "name" not in method:
            raise ValueError("method description needs a 'name'")
        self.out = Path(out)
        write_json(self.out / layout.METHOD_JSON, method)

    def write(self, frame: TestFrame, *, image: np.ndarray, albedo: np.ndarray | None = None,
              normal: np.ndarray | None = None) -> None:
        for layer, arr in (("image", image), ("albedo", albedo), ("normal", normal)):
            if arr is None:
                continue
            path = layout.prediction_file(self.out, frame.subject, frame.protocol, frame.index, layer, "exr")
            arr = np.asarray(arr, dtype=np.float32)
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{path}: prediction has NaN/Inf")
            write_exr(path, arr)
