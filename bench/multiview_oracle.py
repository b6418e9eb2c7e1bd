"""What the Lambertian-SH bound (`rana-oracle`) scores on protocol c's held-out cameras, under the training light
(`novel_view`) and under novel lights (`test`), per split and per camera, and what the dataset cost to render.

    rh-generate --protocol c --out D --subjects 1 --frames 4 --resolution 128 --preset draft
    python bench/multiview_oracle.py D --out W

In: a protocol-c dataset (its logs/rh-generate.log gives the render time). Out: the bound's predictions and rh-eval
results under W (rana-oracle and rh-eval, the commands a user runs), and on stdout a markdown table: frames scored,
image PSNR / SSIM / LPIPS means over the split, then over each held-out camera; and the run's seconds per frame
(all cameras) and per camera-frame, with the load average now.
"""
from __future__ import annotations

import argparse
import csv
import json
import re
from collections import defaultdict
from pathlib import Path

from rh_common import layout

METRICS = "psnr,ssim,lpips"


def _mean(rows: list[dict], key: str) -> float:
    v = [float(r[key]) for r in rows if r[key] not in ("", "inf")]
    return sum(v) / len(v) if v else float("nan")


def _cost(dataset: Path) -> str:
    """Seconds per frame from the last completed run in the dataset's log (frames rendered, seconds)."""
    log = dataset / layout.LOG_DIR / "rh-generate.log"
    done = re.findall(r"done: (\d+) frames rendered, \d+ already complete, ([\d.]+) s", log.read_text()) \
        if log.is_file() else []
    ds = json.loads((dataset / layout.DATASET_JSON).read_text())
    spec = ds["protocols"]["protocol_c"]["spec"]
    cams = sum(len(s["cameras"]) * s["frames"] for s in spec["splits"])
    frames = sum(s["frames"] for s in spec["splits"])
    if not done or int(done[-1][0]) == 0:
        return "render cost: no complete run in the log"
    n, sec = int(done[-1][0]), float(done[-1][1])
    per_frame = sec / n
    preset = ds["protocols"]["protocol_c"]["render"]["preset"]
    return (f"render cost (its log, {spec['width']}x{spec['height']}, {preset} preset, subject build included): "
            f"{sec:.0f} s for {n} frames = {per_frame:.1f} s per frame of all "
            f"its cameras, {sec * frames / n / cams:.2f} s per camera-frame ({cams * n // frames} camera-frames)")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("dataset", type=Path, help="a dataset holding protocol c")
    p.add_argument("--out", type=Path, required=True, help="folder for the predictions and results")
    p.add_argument("--metrics", default=METRICS,
                   help=f"comma-separated metrics, passed to rh-eval --metrics (default {METRICS}: the table's "
                        "columns)")
    args = p.parse_args(argv)
    from rana.oracle import main as oracle_main
    from rh_eval.cli import main as eval_main

    print("| split | camera | frames | image PSNR | image SSIM | image LPIPS |\n|---|---|---|---|---|---|")
    for split in ("novel_view", "test"):
        pred, result = args.out / f"oracle_{split}", args.out / f"oracle_{split}.json"
        if oracle_main(["--dataset", str(args.dataset), "--protocol", "c", "--split", split, "--out", str(pred)]):
            return 2
        if eval_main([str(pred), "--dataset", str(args.dataset), "--protocol", "c", "--split", split, "--out",
                      str(result), "--metrics", args.metrics, "--no-progress", "--no-thumbnails"]):
            return 2
        with open(result.with_name(result.stem + ".frames.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
        by_view: dict[str, list[dict]] = defaultdict(list)
        for r in rows:
            by_view[r["view"]].append(r)
        for name, rs in [("all", rows), *sorted(by_view.items())]:
            print(f"| {split} | {name} | {len(rs)} | {_mean(rs, 'image_psnr'):.2f} | {_mean(rs, 'image_ssim'):.4f} | "
                  f"{_mean(rs, 'image_lpips'):.4f} |")
    print(f"\n{_cost(args.dataset)}; load average {' '.join(Path('/proc/loadavg').read_text().split()[:3])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
