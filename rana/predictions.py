"""The one writer of method outputs, in the predictions layout `rh-eval` reads (docs/ARCHITECTURE.md)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from rh_common.imageio import read_json, write_exr, write_json

__all__ = ["TestFrame", "iter_test_frames", "PredictionWriter"]


@dataclass(frozen=True)
class TestFrame:
    subject: str
    protocol: str
    index: int
    split_dir: Path
    meta: dict

    def layer_path(self, layer: str, ext: str = "exr") -> Path:
        return self.split_dir / f"frame_{self.index:06d}_{layer}.{ext}"


def iter_test_frames(dataset: str | Path, protocol: str) -> Iterator[TestFrame]:
    """Every test frame of one protocol, in subject then frame order."""
    root = Path(dataset)
    pattern = f"subject_*/protocol_{protocol}/test/frame_*.json"
    paths = sorted(root.glob(pattern))
    if not paths:
        raise FileNotFoundError(f"{root}: no test frames of protocol {protocol} ({pattern}); generate them with "
                                f"`rh-generate --protocol {protocol} --out {root}`")
    for p in paths:
        meta = read_json(p)
        yield TestFrame(meta["subject"], meta["protocol"], int(meta["index"]), p.parent, meta)


class PredictionWriter:
    """Writes `<out>/method.json` once, then per frame `<subject>/protocol_<p>/test/frame_%06d_<layer>.exr`."""

    def __init__(self, out: str | Path, method: dict):
        if "name" not in method:
            raise ValueError("method description needs a 'name'")
        self.out = Path(out)
        write_json(self.out / "method.json", method)

    def write(self, frame: TestFrame, *, image: np.ndarray, albedo: np.ndarray | None = None,
              normal: np.ndarray | None = None) -> None:
        d = self.out / frame.subject / f"protocol_{frame.protocol}" / "test"
        stem = f"frame_{frame.index:06d}"
        for layer, arr in (("image", image), ("albedo", albedo), ("normal", normal)):
            if arr is None:
                continue
            arr = np.asarray(arr, dtype=np.float32)
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{d / stem}_{layer}.exr: prediction has NaN/Inf")
            write_exr(d / f"{stem}_{layer}.exr", arr)
