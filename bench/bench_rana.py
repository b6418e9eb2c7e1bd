"""RANA's speed/accuracy trade: personalization time vs image error on a held-out split, across working resolution
and iteration count. Prints a table (and writes it as JSON with --out).

    python bench/bench_rana.py                                   # synthetic subject (our rasteriser), quick grid
    python bench/bench_rana.py --dataset /tmp/rh_demo --subject subject_000 --resolutions 64,128 --steps 100,300,1000
    python bench/bench_rana.py --pretrained pre/pretrained.pt    # personalize from pretrained G_N/G_A

For each (resolution, steps): the coarse stage (timed once per resolution; cached), personalization from scratch
(or from --pretrained), prediction for every test frame, then rh-eval's scores of each frame
(`rh_eval.score_frame`): LPIPS (alex) and PSNR in the default region, PSNR in the `full` region (the whole frame)
and in the `mask` region (inside the GT mask). Also reports the SMPL+D baseline at each resolution (no
personalization: its time is the coarse stage alone).
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


def _scores(pred_root: Path, dataset: Path, protocol: str, subject: str) -> dict:
    """rh-eval's numbers for one subject, from `rh_eval.score_frame`: LPIPS (alex) and PSNR in the default region
    (the person's dilated box, both images composited over the same background by the ground-truth coverage: the
    leaderboard's convention), PSNR in the `full` region (the whole frame) and in the `mask` region (the tight box,
    composited, averaged over the ground-truth mask's pixels)."""
    from rh_eval import Convention, read_frame, score_frame
    from rh_eval.dataset_io import load_dataset, scan_predictions

    index = scan_predictions(pred_root, load_dataset(dataset, protocol), allow_incomplete=True)  # one subject
    lp, ps, ps_full, psm = [], [], [], []
    for frame in (f for f in index.frames if f.gt.subject == subject):
        pred, gt = read_frame(frame, ("lpips", "psnr"), layers=("image",))
        box = score_frame(pred, gt, Convention(), ("lpips", "psnr")).image
        lp.append(box.lpips)
        ps.append(box.psnr)
        ps_full.append(score_frame(pred, gt, Convention(region="full"), ("psnr",)).image.psnr)
        psm.append(score_frame(pred, gt, Convention(region="mask"), ("psnr",)).image.psnr)
    return {"lpips": float(np.mean(lp)), "psnr": float(np.mean(ps)), "psnr_full": float(np.mean(ps_full)),
            "psnr_mask": float(np.mean(psm)), "frames": len(lp)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--dataset", type=Path, default=None, help="dataset (default: a synthetic one in a temp dir)")
    ap.add_argument("--subject", default="subject_000", help="subject personalized and scored (default subject_000)")
    ap.add_argument("--protocol", default="a",
                    help="protocol letter (a or b): the subject's train split personalizes, its test frames are "
                         "scored (default a)")
    ap.add_argument("--resolutions", default="48,96",
                    help="working resolutions in pixels, comma-separated (model.resolution; the coarse stage's "
                         "geometry at min(res, 128); default 48,96)")
    ap.add_argument("--steps", default="20,100",
                    help="personalization step counts, comma-separated: a run each at every resolution "
                         "(default 20,100)")
    ap.add_argument("--preset", default="cpu",
                    help="rana preset the runs start from: paper, cpu, demo or tiny (default cpu)")
    ap.add_argument("--pretrained", type=Path, default=None,
                    help="pretrained.pt from rana-pretrain to personalize from (default: from scratch)")
    ap.add_argument("--threads", type=int, default=0, help="torch intra-op threads (default 0: torch's default)")
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
            t0, c0 = time.perf_counter(), time.process_time()
            run = personalize(dataset, args.subject, args.protocol, run_dir, cfg, pretrained=args.pretrained,
                              progress=False)
            t_train, c_train = time.perf_counter() - t0, time.process_time() - c0
            coarse_rec = [r for r in run.read_log() if r["step"] == -1]
            if not (runs / "coarse.pt").is_file():
                (runs / "coarse.pt").write_bytes((run_dir / "coarse.pt").read_bytes())
                t_coarse = coarse_rec[0]["seconds"] if coarse_rec else float("nan")
                # the coarse stage's share of the CPU time, in proportion to its share of the wall time
                c_coarse = c_train * t_coarse / t_train
                pred_s = tmp / f"pred_smpld_{res}"
                predict_smpld(dataset, args.protocol, runs / f"s{steps}", pred_s, subjects=[args.subject],
                              progress=False)
                rows.append({"method": "SMPL+D", "resolution": res, "steps": 0, "train_s": t_coarse,
                             "train_cpu_s": c_coarse,
                             **_scores(pred_s, dataset, args.protocol, args.subject)})
                print(rows[-1])
                t_train_only, c_train_only = t_train - t_coarse, c_train - c_coarse
            else:
                t_train_only, c_train_only = t_train, c_train
            t0 = time.perf_counter()
            pred = tmp / f"pred_{res}_{steps}"
            predict_rana(dataset, args.protocol, runs / f"s{steps}", pred, subjects=[args.subject], progress=False)
            t_pred = time.perf_counter() - t0
            rows.append({"method": "RANA", "resolution": res, "steps": steps, "train_s": t_train_only,
                         "train_cpu_s": c_train_only, "s_per_step": t_train_only / steps,
                         "cpu_s_per_step": c_train_only / steps, "predict_s": t_pred,
                         **_scores(pred, dataset, args.protocol, args.subject)})
            print(rows[-1])
            prev_steps = steps
    print()
    print(f"{'method':8s} {'res':>4s} {'steps':>6s} {'train s':>8s} {'CPU s':>8s} {'CPU s/step':>10s} {'LPIPS':>7s} "
          f"{'PSNR':>6s} {'PSNR(full)':>10s} {'PSNR(mask)':>10s}")
    for r in rows:
        print(f"{r['method']:8s} {r['resolution']:4d} {r['steps']:6d} {r['train_s']:8.1f} {r['train_cpu_s']:8.1f} "
              f"{r.get('cpu_s_per_step', float('nan')):10.3f} {r['lpips']:7.4f} {r['psnr']:6.2f} "
              f"{r['psnr_full']:10.2f} {r['psnr_mask']:10.2f}")
    print("LPIPS, PSNR: rh-eval's default region (the leaderboard's convention), mean over the subject's test frames; "
          "PSNR(full): whole frame; PSNR(mask): inside the ground-truth mask (rh-eval's regions). train s: wall seconds of "
          "personalization (SMPL+D: its coarse stage); CPU s: the process's CPU seconds for the same (with one torch "
          "thread, what an otherwise idle core takes, whatever else runs); "
          f"{torch.get_num_threads()} torch threads; load average at the end "
          f"{' '.join(Path('/proc/loadavg').read_text().split()[:3])}.")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
