"""What the Lambertian-SH bound (`rana-oracle`) scores under one small light: rh-eval results on the test and the
olat split, side by side, and the olat frames by where the light is.

    rana-oracle --dataset D --split test --out P/oracle_test
    rana-oracle --dataset D --split olat --out P/oracle_olat
    rh-eval P/oracle_test --dataset D --out R/oracle_test.json
    rh-eval P/oracle_olat --dataset D --split olat --out R/oracle_olat.json
    python bench/olat_oracle.py R/oracle_test.json R/oracle_olat.json

In: two rh-eval result files (their per-frame CSV beside them; the dataset and predictions they name, read again for
the brightness columns). Out: a markdown table on stdout, one row per group of frames: image PSNR and LPIPS (means
over the group's frames, from the CSV), the mean display value of the ground truth and of the bound inside the
person's mask, and the share of the person's unlit pixels (ground truth below DARK in display space) that the bound
lights (above DARK): order-2 SH gives the shadowed side up to ~7% of the facing irradiance (bench/sh_truncation.py
--olat), which shows there. 'Test, the olat poses' are the test frames whose poses the olat split reuses (olat
frame i = test pose i // 16); 'light in front / to the side / behind': the angle between the light's and the
camera's horizontal directions (under 85 degrees, 85 to 95, over 95).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_eval.dataset_io import load_dataset, read_gt_display, read_gt_mask, read_pred_display

DARK = 0.02  # display value (sRGB) under which a pixel counts as unlit; 8-bit level 5


def _rows(result_path: Path) -> tuple[dict, list[dict]]:
    result = json.loads(result_path.read_text())
    csv_path = result_path.with_name(result_path.stem + ".frames.csv")
    with open(csv_path, newline="") as f:
        return result, list(csv.DictReader(f))


def _brightness(result: dict) -> dict[tuple[str, int], tuple[float, float, int, int]]:
    """Per frame: (GT mean display in mask, bound's mean display in mask, unlit mask pixels, of those lit by it,
    mask pixels)."""
    d = result["dataset"]
    ds = load_dataset(d["root"], d["protocol"], d.get("split", layout.TEST_SPLIT))
    out = {}
    for fr in ds.frames:
        pred = layout.prediction_file(result["predictions"], fr.subject, ds.protocol, fr.index, "image",
                                      split=ds.split)
        mask = read_gt_mask(fr) > 127
        gt, pr = read_gt_display(fr).mean(-1)[mask], read_pred_display(pred, fr).mean(-1)[mask]
        dark = gt < DARK
        out[(fr.subject, fr.index)] = (float(gt.mean()), float(pr.mean()), int(dark.sum()),
                                       int((pr[dark] >= DARK).sum()), int(mask.sum()))
    return out


def _side(result: dict, row: dict) -> str:
    """'front', 'side' or 'behind': the angle between the light's and the camera's horizontal directions (under
    85 degrees, 85 to 95, over 95; the subject stands at the origin, z up)."""
    meta = _meta(result, row)
    cam = np.asarray(meta["camera"]["camera_to_world"], dtype=np.float64)[:2, 3]
    light = np.asarray(meta["light"]["olat"]["direction_world"], dtype=np.float64)[:2]
    deg = math.degrees(math.acos(float(np.clip(cam @ light / np.linalg.norm(cam) / np.linalg.norm(light), -1, 1))))
    return "front" if deg < 85.0 else "behind" if deg > 95.0 else "side"


def _meta(result: dict, row: dict) -> dict:
    d = result["dataset"]
    folder = layout.split_dir(d["root"], row["subject"], d["protocol"], d["split"])
    return json.loads(layout.frame_json_path(folder, int(row["frame"])).read_text())


def _line(name: str, rows: list[dict], bright: dict) -> str:
    def mean(key):
        v = [float(r[key]) for r in rows if r[key] not in ("", "inf")]
        return sum(v) / len(v) if v else math.nan

    b = [bright[(r["subject"], int(r["frame"]))] for r in rows]
    dark, lit, person = sum(x[2] for x in b), sum(x[3] for x in b), sum(x[4] for x in b)
    share = f"{100.0 * lit / dark:.1f}%" if dark else "—"
    return (f"| {name} | {len(rows)} | {mean('image_psnr'):.2f} | {mean('image_lpips'):.4f} | "
            f"{np.mean([x[0] for x in b]):.3f} | {np.mean([x[1] for x in b]):.3f} | "
            f"{100.0 * dark / max(person, 1):.1f}% | {share} |")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("test", type=Path, help="rh-eval result of the bound on the test split")
    p.add_argument("olat", type=Path, help="rh-eval result of the bound on the olat split")
    args = p.parse_args(argv)
    (rt, test), (ro, olat) = _rows(args.test), _rows(args.olat)
    for r, want in ((rt, "test"), (ro, "olat")):
        if r["dataset"].get("split", layout.TEST_SPLIT) != want:
            raise SystemExit(f"{args.test if want == 'test' else args.olat}: scored the "
                             f"{r['dataset'].get('split')!r} split, expected {want!r}")
    bt, bo = _brightness(rt), _brightness(ro)
    n_dirs = len({_meta(ro, r)["light"]["olat"]["direction_index"] for r in olat})
    poses = {(r["subject"], int(r["frame"]) // n_dirs) for r in olat}
    side = {id(r): _side(ro, r) for r in olat}
    print("| frames | n | image PSNR ↑ | image LPIPS ↓ | GT mean (display) | bound mean (display) | "
          f"person unlit in GT (< {DARK}) | of those, lit by the bound |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    print(_line("test split", test, bt))
    print(_line("test, the olat poses", [r for r in test if (r["subject"], int(r["frame"])) in poses], bt))
    print(_line("olat split", olat, bo))
    for where in ("front", "side", "behind"):
        print(_line(f"olat, light {dict(front='in front', side='to the side').get(where, where)}",
                    [r for r in olat if side[id(r)] == where], bo))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
