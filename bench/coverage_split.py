"""rh-eval's normal (or albedo) error, split into where a prediction has the layer and where it has none.

    python bench/coverage_split.py --dataset D --protocol a PRED [PRED ...]                  # normals
    python bench/coverage_split.py --dataset D --protocol a --layer albedo PRED [PRED ...]   # albedo

A method writes no normal (a zero vector) and no albedo (zero) outside its own silhouette. rh-eval's `normal_deg`
averages the angle over the ground-truth mask and counts such a pixel as 90°, and its albedo metrics compare the
zero with the true albedo. So a method that covers more of the person scores better even if what it predicts is
no better. For each predictions folder this prints the mean over frames of: the error over the ground-truth mask,
the error only where the prediction has the layer, the error where every listed folder has it (the same pixels
for every method), and the share of the person without it.

Normals: the angle in degrees, with rh-eval's readers and mask threshold, so the first column equals
`normal_deg`. Albedo: PSNR in rh-eval's default albedo space (sRGB) over the pixels named, so the first column
is *not* rh-eval's `albedo_psnr` (that one is over the person's dilated box); "has albedo" means any channel > 0.
Frames missing from any folder are left out of every column.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def split(pred_roots: list[Path], dataset: Path, protocol: str, layer: str = "normal") -> list[dict]:
    from rh_eval.conventions import Convention, albedo_to_space
    from rh_eval.dataset_io import (load_dataset, read_gt_albedo, read_gt_mask, read_gt_normal, read_pred_albedo,
                                    read_pred_normal, scan_predictions)
    from rh_eval.metrics import psnr
    from rh_eval.metrics.normal import angular_error_map

    if layer not in ("normal", "albedo"):
        raise ValueError(f"layer {layer!r}: expected 'normal' or 'albedo'")
    ds = load_dataset(dataset, protocol)
    preds = [scan_predictions(r, ds) for r in pred_roots]
    for r, pred in zip(pred_roots, preds):
        if not (pred.has_normal if layer == "normal" else pred.has_albedo):
            raise SystemExit(f"{r}: no {layer} predictions")
    conv = Convention()
    by_frame = [{pf.gt.key: pf for pf in pred.frames} for pred in preds]
    cols = {k: [[] for _ in preds] for k in ("total", "covered", "common", "missing")}
    for gt in ds.frames:
        if any(gt.key not in bf or getattr(bf[gt.key], layer) is None for bf in by_frame):
            continue
        inside = read_gt_mask(gt) >= conv.mask_threshold
        if not inside.any():
            continue
        if layer == "normal":
            g = read_gt_normal(gt)
            values = [read_pred_normal(getattr(bf[gt.key], layer), gt) for bf in by_frame]
            errors = [angular_error_map(v, g) for v in values]
            score = lambda err, where: float(err[where].mean()) if where.any() else float("nan")  # noqa: E731
        else:
            g = albedo_to_space(read_gt_albedo(gt), conv)
            values = [read_pred_albedo(getattr(bf[gt.key], layer), gt) for bf in by_frame]
            errors = [albedo_to_space(v, conv) for v in values]
            score = lambda a, where: psnr(a, g, data_range=1.0, mask=where)  # noqa: E731
        has = [inside & np.any(v != 0, axis=-1) for v in values]
        common = np.logical_and.reduce(has)
        for i, (err, h) in enumerate(zip(errors, has)):
            cols["total"][i].append(score(err, inside))
            cols["covered"][i].append(score(err, h))
            cols["common"][i].append(score(err, common))
            cols["missing"][i].append(1.0 - h.sum() / inside.sum())
    return [{"name": pred.method.get("name", r.name), "layer": layer, "total": float(np.mean(cols["total"][i])),
             "where_predicted": float(np.nanmean(cols["covered"][i])),
             "where_all_predict": float(np.nanmean(cols["common"][i])),
             "missing": float(np.mean(cols["missing"][i])), "frames": len(cols["total"][i])}
            for i, (r, pred) in enumerate(zip(pred_roots, preds))]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("predictions", nargs="+", type=Path, help="predictions folders (as rh-eval reads them)")
    ap.add_argument("--dataset", required=True, type=Path, help="dataset folder written by rh-generate")
    ap.add_argument("--protocol", default="a", help="protocol letter (a or b)")
    ap.add_argument("--layer", default="normal", choices=["normal", "albedo"],
                    help="normal: angle in degrees (lower is better); albedo: sRGB PSNR in dB (higher is better)")
    args = ap.parse_args(argv)
    rows = split(args.predictions, args.dataset, args.protocol, args.layer)
    unit = "normal °" if args.layer == "normal" else "albedo PSNR"
    w = max(len(r["name"]) for r in rows)
    print(f"{'method':<{w}}  {unit + ' in GT mask':>22}  {'where predicted':>15}  {'where all predict':>17}  "
          f"{'person without ' + args.layer:>22}  frames")
    for r in rows:
        print(f"{r['name']:<{w}}  {r['total']:22.2f}  {r['where_predicted']:15.2f}  {r['where_all_predict']:17.2f}  "
              f"{r['missing']:22.1%}  {r['frames']:6d}")
    if args.layer == "normal":
        print("The first column equals rh-eval's normal_deg (a person pixel without a normal counts 90°).")
    else:
        print("PSNR over the named pixels in sRGB; not rh-eval's albedo_psnr, which is over the dilated box.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
