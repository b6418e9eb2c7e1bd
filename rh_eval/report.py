"""Summarising and writing a result: per-metric means and stds, the JSON summary and the per-frame CSV beside it.

In: per-frame values (`summarise`); the result dict, rows and columns of `Evaluator.evaluate` and its
    `Evaluator.thumbnails` (`write_result`).
Out: summary dicts; the JSON, the CSV and the `<stem>.thumbs/` folder of pictures beside it."""
from __future__ import annotations

import csv
import io
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from rh_common.imageio import atomic_path, write_json

from .thumbnails import ThumbnailSet, thumbs_dir_for, write_thumbnails

__all__ = ["summarise", "write_result", "csv_path_for", "format_value"]


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not math.isnan(v)


def summarise(values: list, *, psnr_like: bool) -> dict:
    """Mean and population std (ddof=0) of the defined values of one metric.

    `None`/NaN values (undefined: empty mask) are counted in `n_undefined`, never averaged. PSNR: +inf values
    (identical images) are counted in `n_infinite` and left out of the mean and std, which are over the finite
    values; when every defined value is infinite, mean is the string "inf" and std is null.
    """
    defined = [float(v) for v in values if _is_num(v)]
    out: dict[str, Any] = {"n": len(defined), "n_undefined": len(values) - len(defined)}
    if psnr_like:
        finite = [v for v in defined if math.isfinite(v)]
        out["n_infinite"] = len(defined) - len(finite)
        if finite:
            out["mean"] = float(np.mean(finite))
            out["std"] = float(np.std(finite))
        elif defined:
            out["mean"], out["std"] = "inf", None
        else:
            out["mean"], out["std"] = None, None
        return out
    if defined:
        out["mean"] = float(np.mean(defined))
        out["std"] = float(np.std(defined))
    else:
        out["mean"], out["std"] = None, None
    return out


def csv_path_for(json_path: Path) -> Path:
    return json_path.with_name(json_path.stem + ".frames.csv")


def format_value(v) -> str:
    """CSV cell: repr of a float (round-trips exactly), 'inf' for +inf, '' for undefined."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, (list, tuple)):
        return " ".join(format_value(x) for x in v)
    return str(v)


def write_result(out: Path, result: dict, rows: list[dict], cols: list[str], csv_path: Path | None = None,
                 thumbnails: ThumbnailSet | None = None) -> Path:
    """Write `out` (JSON), the per-frame CSV (default `<out stem>.frames.csv`) and, given `thumbnails`, the
    `<out stem>.thumbs/` folder (first: the JSON, written last, names it only once it is whole); returns the CSV
    path."""
    out = Path(out)
    result = dict(result)
    if thumbnails is not None:
        result["thumbnails"] = write_thumbnails(thumbs_dir_for(out), thumbnails)
    elif (thumbs_dir_for(out) / "index.json").is_file():  # an earlier run's pictures: not of this result
        shutil.rmtree(thumbs_dir_for(out))
    csv_path = Path(csv_path) if csv_path else csv_path_for(out)
    extra = ["albedo_scale"] if any("albedo_scale" in r for r in rows) else []
    view = ["view"] if any("view" in r for r in rows) else []  # a multi-view split's camera column
    header = ["subject", *view, "frame", "empty_mask"] + cols + extra
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([format_value(r.get(h)) for h in header])
    with atomic_path(csv_path) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
    result["per_frame_csv"] = csv_path.name
    write_json(out, result)
    return csv_path
