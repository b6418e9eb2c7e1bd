"""RANA's speed/accuracy trade: personalization time vs image error on a held-out split, across working resolution
and iteration count. Prints a table (and writes it as JSON with --out).

    python bench/bench_rana.py                                   # synthetic subject (our rasteriser), quick grid
    python bench/bench_rana.py --dataset /tmp/rh_demo --subject subject_000 --resolutions 64,128 --steps 100,300,1000
    python bench/bench_rana.py --pretrained pre/pretrained.pt    # personalize from pretrained G_N/G_A

For each (resolution, steps): the coarse stage (timed once per resolution; cached), personalization from scratch
(or from --pretrained), prediction for every test frame, then LPIPS (alex) and PSNR from `rh_eval.metrics` on the
display-space images (exposure from the GT frame), over the whole frame and inside the GT mask. Also reports the
SMPL+D baseline at each resolution (no personalization: its time is the coarse stage alone).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rh_common.colourspace import to_display  # noqa: E402
from rh_common.imageio import read_exr, read_png  # noqa: E402


def _scores(pred_root: Path, dataset: Path, protocol: str, subject: str) -> dict:
    from rh_eval.metrics import lpips, psnr

    lp, ps, psm = [], [], []
    for jp in sorted((dataset / subject / f"protocol_{protocol}" / "test").glob("frame_*.json")):
        meta = json.loads(jp.read_text())
        stem = jp.stem
        gt = to_display(read_exr(jp.parent / f"{stem}_image.exr")[..., :3], meta["exposure"])
        pr = to_display(read_exr(pred_root / subject / f"protocol_{protocol}" / "test" / f"{stem}_image.exr"),
                        meta["exposure"])
        m = read_png(jp.parent / f"{stem}_mask.png")
        m = (m if m.ndim == 2 else m[..., 0]) >= 128
        lp.append(float(lpips(pr, gt, data_range=1.0)))
        ps.append(float(psnr(pr, gt, data_range=1.0)))
        psm.append(float(psnr(pr, gt, data_range=1.0, mask=m)))
    return {"lpips": float(np.mean(lp)), "psnr": float(np.mean(ps)), "psnr_mask": float(np.mean(psm)),
            "frames": len(lp)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--dataset", type=Path, default=None, help="dataset (default: a synthetic one in a temp dir)")
    ap.add_argument("--subject", default="subject_000")
    ap.add_argument("--protocol", default="a")
    ap.add_argument("--resolutions", default="48,96")
    ap.add_argument("--steps", default="20,100")
    ap.add_argument("--preset", default="cpu")
    ap.add_argument("--pretrained", type=Path, default=None)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="also write the rows as JSON")
    args = ap.parse_args(argv)

    from rana.config import get_preset
    from rana.predict import predict_rana, predict_smpld
    from rana.synthetic import make_dataset
    from rana.train import personalize

    if args.threads > 0:
        torch.set_num_threads(args.threads)
    tmp = Path(tempfile.mkdtemp(prefix="bench_rana_"))
    dataset = args.dataset
    if dataset is None:
        t0 = time.perf_counter()
        dataset = make_dataset(tmp / "ds", subjects=1, train_frames=24, test_frames=6, resolution=128, seed=1)
        print(f"synthetic dataset: {time.perf_counter() - t0:.1f} s → {dataset}")
    base = get_preset(args.preset)
    rows = []
    for res in [int(x) for x in args.resolutions.split(",")]:
        prev_steps = 0
        runs = tmp / f"runs_{res}"
        for steps in sorted(int(x) for x in args.steps.split(",")):
            pc = dataclasses.replace(base.personalize, steps=steps, freeze_albedo_steps=min(base.personalize.
                                     freeze_albedo_steps, steps // 10), checkpoint_every=steps, log_every=10)
            cfg = dataclasses.replace(base, threads=args.threads, personalize=pc,
                                      model=dataclasses.replace(base.model, resolution=res),
                                      geometry=dataclasses.replace(base.geometry, resolution=min(res, 128)))
            run_dir = runs / f"s{steps}" / args.subject
            if (runs / "coarse.pt").is_file():  # share the coarse stage between step counts
                run_dir.mkdir(parents=True, exist_ok=True)
                (run_dir / "coarse.pt").write_bytes((runs / "coarse.pt").read_bytes())
            t0 = time.perf_counter()
            run = personalize(dataset, args.subject, args.protocol, run_dir, cfg, pretrained=args.pretrained,
                              progress=False)
            t_train = time.perf_counter() - t0
            coarse_rec = [r for r in run.read_log() if r["step"] == -1]
            if not (runs / "coarse.pt").is_file():
                (runs / "coarse.pt").write_bytes((run_dir / "coarse.pt").read_bytes())
                t_coarse = coarse_rec[0]["seconds"] if coarse_rec else float("nan")
                pred_s = tmp / f"pred_smpld_{res}"
                predict_smpld(dataset, args.protocol, runs / f"s{steps}", pred_s, subjects=[args.subject],
                              progress=False)
                rows.append({"method": "SMPL+D", "resolution": res, "steps": 0, "train_s": t_coarse,
                             **_scores(pred_s, dataset, args.protocol, args.subject)})
                print(rows[-1])
                t_train_only = t_train - t_coarse
            else:
                t_train_only = t_train
            t0 = time.perf_counter()
            pred = tmp / f"pred_{res}_{steps}"
            predict_rana(dataset, args.protocol, runs / f"s{steps}", pred, subjects=[args.subject], progress=False)
            t_pred = time.perf_counter() - t0
            rows.append({"method": "RANA", "resolution": res, "steps": steps, "train_s": t_train_only,
                         "s_per_step": t_train_only / steps, "predict_s": t_pred,
                         **_scores(pred, dataset, args.protocol, args.subject)})
            print(rows[-1])
            prev_steps = steps
    print()
    print(f"{'method':8s} {'res':>4s} {'steps':>6s} {'train s':>8s} {'s/step':>7s} {'LPIPS':>7s} {'PSNR':>6s} "
          f"{'PSNR(mask)':>10s}")
    for r in rows:
        print(f"{r['method']:8s} {r['resolution']:4d} {r['steps']:6d} {r['train_s']:8.1f} "
              f"{r.get('s_per_step', float('nan')):7.3f} {r['lpips']:7.4f} {r['psnr']:6.2f} {r['psnr_mask']:10.2f}")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
