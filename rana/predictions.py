"""The one writer of method outputs, in the predictions layout `rh-eval` reads (docs/ARCHITECTURE.md).

In: the frames of a dataset's scored split (`test`, or another such as `olat`; read through `rh_common.layout`)
    and a method's float arrays per frame.
Out: `<out>/method.json` and `<out>/<subject>/protocol_<p>/<split>/frame_%06d_{image,albedo,normal}.exr` (in the
frame's camera folder `<split>/cam_NN/` for a multi-view split, as in the dataset).
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
    split: str = layout.TEST_SPLIT  # which split it belongs to: its predictions go to the folder of that name
    view: str | None = None  # a multi-view split's camera (cam_NN): its predictions go to that camera's folder

    def layer_path(self, layer: str, ext: str = "exr") -> Path:
        return self.split_dir / layout.layer_file_name(self.index, layer, ext)

    @property
    def json_path(self) -> Path:
        return layout.frame_json_path(self.split_dir, self.index)


def iter_test_frames(dataset: str | Path, protocol: str, split: str = layout.TEST_SPLIT) -> Iterator[TestFrame]:
    """Every frame of one protocol's scored split (default test), in subject then frame order. A split the dataset
    lacks is refused in one line listing the splits it has."""
    root = Path(dataset)
    paths = list(layout.iter_frame_jsons(root, protocol, split))
    if not paths:
        has = layout.splits_of(root, protocol)
        if has:
            raise FileNotFoundError(f"{root}: no {split!r} split for {layout.protocol_dir(protocol)}; it has: "
                                    f"{', '.join(has)} (choose one with --split)")
        pattern = f"subject_*/{layout.protocol_dir(protocol)}/{split}/frame_*.json"
        raise FileNotFoundError(f"{root}: no {split} frames of protocol {protocol} ({pattern}); generate them with "
                                f"`rh-generate --protocol {protocol} --out {root}`")
    for p in paths:
        record = layout.read_frame_record(p)
        yield TestFrame(record.subject, record.protocol, record.index, p.parent, record.to_json(), split, record.view)


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
            path = layout.prediction_file(self.out, frame.subject, frame.protocol, frame.index, layer, "exr",
                                          split=frame.split, view=frame.view)
            arr = np.asarray(arr, dtype=np.float32)
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{path}: prediction has NaN/Inf")
            write_exr(path, arr)
