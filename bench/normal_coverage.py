"""rh-eval's normal error, split into where a prediction has a normal and where it has none.

    python bench/normal_coverage.py --dataset D --protocol a PRED [PRED ...]

rh-eval's `normal_deg` averages the angle over the ground-truth mask, and a pixel where the prediction has no
normal (a zero vector: outside the method's own silhouette) counts 90°. So a method that covers more of the
person scores better even if its normals are no better. For each predictions folder this prints the mean over
frames of: the error as rh-eval computes it, the error only where the prediction has a normal, and the share of
the ground-truth person left without one; and, to compare directions on the same pixels, the error where every
listed folder has a normal. Read with rh-eval's own readers and mask threshold, so the first column equals
`normal_deg` (frames missing from any folder are left out of every column).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def split(pred_roots: list[Path], dataset: Path, protocol: str) -> list[dict]:
    from rh_eval.conventions import Convention
    from rh_eval.dataset_io import load_dataset, read_gt_mask, read_gt_normal, read_pred_normal, scan_predictions
    from rh_eval.metrics.normal import angular_error_map

    ds = load_dataset(dataset, protocol)
    preds = [scan_predictions(r, ds) for r in pred_roots]
    for r, pred in zip(pred_roots, preds):
        if not pred.has_normal:
            raise SystemExit(f"{r}: no normal predictions")
    threshold = Convention().mask_threshold
    by_frame = [{pf.gt.key: pf for pf in pred.frames} for pred in preds]
    cols = {k: [[] for _ in preds] for k in ("total", "covered", "common", "missing")}
    for gt in ds.frames:
        if any(gt.key not in bf or bf[gt.key].normal is None for bf in by_frame):
            continue
        inside = read_gt_mask(gt) >= threshold
        if not inside.any():
            continue
        g = read_gt_normal(gt)
        normals = [read_pred_normal(bf[gt.key].normal, gt) for bf in by_frame]
        has = [inside & np.any(n != 0, axis=-1) for n in normals]
        common = np.logical_and.reduce(has)
        for i, (n, h) in enumerate(zip(normals, has)):
            ang = angular_error_map(n, g)
            cols["total"][i].append(ang[inside].mean())
            cols["covered"][i].append(ang[h].mean() if h.any() else np.nan)
            cols["common"][i].append(ang[common].mean() if common.any() else np.nan)
            cols["missing"][i].append(1.0 - h.sum() / inside.sum())
    return [{"name": pred.method.get("name", r.name), "normal_deg": float(np.mean(cols["total"][i])),
             "deg_where_predicted": float(np.nanmean(cols["covered"][i])),
             "deg_where_all_predict": float(np.nanmean(cols["common"][i])),
             "missing": float(np.mean(cols["missing"][i])), "frames": len(cols["total"][i])}
            for i, (r, pred) in enumerate(zip(pred_roots, preds))]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("predictions", nargs="+", type=Path, help="predictions folders (as rh-eval reads them)")
    ap.add_argument("--dataset", required=True, type=Path, help="dataset folder written by rh-generate")
    ap.add_argument("--protocol", default="a", help="protocol letter (a or b)")
    args = ap.parse_args(argv)
    rows = split(args.predictions, args.dataset, args.protocol)
    w = max(len(r["name"]) for r in rows)
    print(f"{'method':<{w}}  normal° (rh-eval)  ° where predicted  ° where all predict  person without a normal"
          "  frames")
    for r in rows:
        print(f"{r['name']:<{w}}  {r['normal_deg']:17.2f}  {r['deg_where_predicted']:17.2f}  "
              f"{r['deg_where_all_predict']:19.2f}  {r['missing']:23.1%}  {r['frames']:6d}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
