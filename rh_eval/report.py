"""Writing a result: the JSON summary and the per-frame CSV beside it."""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from rh_common.imageio import atomic_path, write_json

__all__ = ["write_result", "csv_path_for", "format_value"]


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


def write_result(out: Path, result: dict, rows: list[dict], cols: list[str], csv_path: Path | None = None) -> Path:
    """Write `out` (JSON) and the per-frame CSV (default `<out stem>.frames.csv`); returns the CSV path."""
    out = Path(out)
    csv_path = Path(csv_path) if csv_path else csv_path_for(out)
    extra = ["albedo_scale"] if any("albedo_scale" in r for r in rows) else []
    header = ["subject", "frame", "empty_mask"] + cols + extra
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([format_value(r.get(h)) for h in header])
    with atomic_path(csv_path) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
    result = dict(result)
    result["per_frame_csv"] = csv_path.name
    write_json(out, result)
    return csv_path
