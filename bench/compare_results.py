"""The same predictions scored against two references: how every method's image scores move, and whether the
ranking holds.

    python bench/compare_results.py BOARD/results_a OTHER/results_a [--metrics psnr,lpips,ssim]

In: two folders of rh-eval result JSONs with the same file names (one per method), e.g. a board's `results_a/` and
the same predictions evaluated (`rh-eval PRED --dataset REF ...`) against a reference rendered with more samples
(`rh-generate ... --spp 132`: the same poses, lights, cameras and AOVs, a less noisy image). Out: a markdown table on
stdout, per method and metric the two means and their difference, then per metric the methods' order under each
reference (methods only: bounds, rh-eval's `kind` "bound", are left out of the order). The conventions must match:
results of different conventions are not comparable and are refused with a one-line error.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

LOWER_IS_BETTER = {"lpips", "dists", "flip", "normal"}


def load(folder: Path) -> dict[str, dict]:
    """{file stem: result JSON} of every rh-eval result in `folder` (files with an `overall` block)."""
    out = {}
    for f in sorted(folder.glob("*.json")):
        try:
            d = json.loads(f.read_text())
        except (OSError, ValueError) as e:
            raise SystemExit(f"compare_results: {f}: not a readable JSON ({e})") from None
        if isinstance(d, dict) and "overall" in d:
            out[f.stem] = d
    return out


def order(rows: list[tuple[str, float]], metric: str) -> list[str]:
    """Method names best first (ties keep the given order)."""
    sign = 1.0 if metric in LOWER_IS_BETTER else -1.0
    return [n for n, _ in sorted(rows, key=lambda r: sign * r[1])]


def compare(a: dict[str, dict], b: dict[str, dict], metrics: list[str]) -> str:
    common = [k for k in a if k in b]
    if not common:
        raise SystemExit("compare_results: no result file name is in both folders")
    for k in common:
        ca, cb = a[k].get("convention", {}).get("name"), b[k].get("convention", {}).get("name")
        if ca != cb:
            raise SystemExit(f"compare_results: {k}: convention {ca!r} against {cb!r}; compare one convention")
    lines = ["| method | " + " | ".join(f"image {m} A | B | B - A" for m in metrics) + " |",
             "|---|" + "---:|---:|---:|" * len(metrics)]
    for k in common:
        name = a[k].get("method", {}).get("name", k)
        cells = []
        for m in metrics:
            va, vb = a[k]["overall"][f"image_{m}"]["mean"], b[k]["overall"][f"image_{m}"]["mean"]
            digits = 2 if m == "psnr" else 4
            cells.append(f"{va:.{digits}f} | {vb:.{digits}f} | {vb - va:+.{digits}f}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    methods = [k for k in common if a[k].get("kind") != "bound"]
    lines.append("")
    for m in metrics:
        ra = order([(a[k].get("method", {}).get("name", k), a[k]["overall"][f"image_{m}"]["mean"]) for k in methods], m)
        rb = order([(b[k].get("method", {}).get("name", k), b[k]["overall"][f"image_{m}"]["mean"]) for k in methods], m)
        same = "the same order" if ra == rb else "THE ORDER CHANGES"
        lines.append(f"- image {m}, methods best first: A: {' > '.join(ra)}; B: {' > '.join(rb)} ({same})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("a", type=Path, help="folder of rh-eval result JSONs (reference A)")
    p.add_argument("b", type=Path, help="folder of rh-eval result JSONs of the same predictions (reference B)")
    p.add_argument("--metrics", default="psnr,lpips,ssim",
                   help="comma-separated image metrics present in both (default psnr,lpips,ssim)")
    args = p.parse_args(argv)
    for f in (args.a, args.b):
        if not f.is_dir():
            raise SystemExit(f"compare_results: {f}: no such folder")
    metrics = [m.strip() for m in args.metrics.split(",") if m.strip()]
    a, b = load(args.a), load(args.b)
    for k in (k for k in a if k in b):
        for m in metrics:
            if f"image_{m}" not in a[k]["overall"] or f"image_{m}" not in b[k]["overall"]:
                raise SystemExit(f"compare_results: {k}: no image_{m} in both results; evaluate it or drop it from "
                                 "--metrics")
    print(compare(a, b, metrics))
    return 0


if __name__ == "__main__":
    sys.exit(main())
