"""Throughput of rh-eval at 512x512: frame pairs per second per metric and for the whole set, and the ratio of the
pipeline's time to the bare backbone forward passes measured in the same run.

    python bench/bench_eval.py [--frames 8] [--size 512] [--batch-size 4] [--region full] [--repeat 3]
                               [--only lpips] [--profile]

What is timed:
- `bare`: the backbone alone on in-memory tensors, two forward passes per pair (prediction and ground truth),
  batched like the pipeline: AlexNet taps for LPIPS, VGG16 with L2 pooling for DISTS.
- `pipeline cold`: `Evaluator.evaluate` on a synthetic dataset written to disk (the up-front check of every
  prediction file, EXR/PNG reading, display transform, region, batching, metric heads, result aggregation), with
  an empty ground-truth feature cache: a fresh `Evaluator` per repetition (the networks themselves are loaded once
  per process, as in rh-eval).
- `pipeline warm`: the same with the ground-truth features already cached (a second method against the same
  dataset): one forward pass per pair.
- CPU metrics (SSIM, PSNR, FLIP, normal error) through the pipeline alone.
The overhead ratio is pipeline cold / bare (goal <= 1.3x); warm / bare shows the cache's gain. Every time is the
best of `--repeat` runs (the machine is shared: the best run is the least disturbed); bare and pipeline use the
same torch threads. The load average is printed with the table. `--profile` prints where the cold LPIPS
pipeline spends its time (cProfile, main thread; the worker threads show up as lock waits).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the fake-dataset writer shared with the tests

from rh_eval.conventions import Convention  # noqa: E402
from rh_eval.evaluate import EvalOptions, Evaluator  # noqa: E402
from rh_eval.metrics.dists import get_dists_net  # noqa: E402
from rh_eval.metrics.lpips import get_lpips_net  # noqa: E402
from test_eval_fake import make_dataset, make_predictions  # noqa: E402


def _time(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bare_forward(net, n: int, size: int, batch: int, repeat: int) -> float:
    rng = np.random.default_rng(0)
    xs = [torch.from_numpy(rng.uniform(0, 1, (min(batch, n - s), 3, size, size)).astype(np.float32))
          for s in range(0, n, batch)]

    def run():
        for x in xs:
            net.backbone_forward(x)  # prediction
            net.backbone_forward(x)  # ground truth
    run()  # warm-up (allocator, threads)
    return _time(run, repeat)


def pipeline(ds: Path, pred: Path, metrics, conv: Convention, batch: int, repeat: int,
             **options) -> tuple[float, float]:
    def evaluator():
        return Evaluator(EvalOptions(convention=conv, metrics=tuple(metrics), batch_size=batch, progress=False,
                                     **options))

    evaluator().evaluate(pred, ds)  # warm-up: imports, file system cache, allocator
    t_cold = _time(lambda: evaluator().evaluate(pred, ds), repeat)  # a fresh, empty ground-truth feature cache
    ev = evaluator()
    ev.evaluate(pred, ds)
    t_warm = _time(lambda: ev.evaluate(pred, ds), repeat)  # ground-truth features cached
    return t_cold, t_warm


def profile_cold(ds: Path, pred: Path, conv: Convention, batch: int) -> None:
    import cProfile
    import pstats

    ev = Evaluator(EvalOptions(convention=conv, metrics=("lpips",), batch_size=batch, progress=False))
    prof = cProfile.Profile()
    prof.enable()
    ev.evaluate(pred, ds)
    prof.disable()
    pstats.Stats(prof).sort_stats("tottime").print_stats(15)


def _load() -> str:
    try:
        return "load average " + " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "load average unknown"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=8, help="frame pairs (default 8)")
    p.add_argument("--size", type=int, default=512, help="frame size in pixels (default 512)")
    p.add_argument("--batch-size", type=int, default=4)
    p.add_argument("--region", default="full", choices=("full", "default", "mask"),
                   help="region convention (default full: the networks see the whole 512x512 frame, like the bare "
                        "passes; 'default' crops to the person's dilated box and is faster)")
    p.add_argument("--repeat", type=int, default=3, help="runs per measurement; the best is kept (default 3)")
    p.add_argument("--only", choices=("lpips", "all"), default="all",
                   help="lpips: only the LPIPS rows (quick); all: every metric and the whole set (default)")
    p.add_argument("--profile", action="store_true", help="also print a cProfile of one cold LPIPS run")
    p.add_argument("--compare-overlap", action="store_true",
                   help="also time the LPIPS pipeline with the workers in turns with the networks and overlapping "
                        "them (EvalOptions.overlap False/True), against the same bare passes")
    args = p.parse_args(argv)
    n, size, bs, rep = args.frames, args.size, args.batch_size, args.repeat
    conv = Convention(region=args.region)
    print(f"rh-eval bench: {n} frame pairs at {size}x{size}, batch {bs}, region {args.region}, "
          f"torch {torch.__version__} with {torch.get_num_threads()} threads, best of {rep}; {_load()} at start")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        per = max(1, n // 2)
        ds = make_dataset(tmp / "ds", size=size, subjects=("subject_000", "subject_001"), frames=tuple(range(per)))
        # per-metric rows: image-only predictions (one image pair per frame); whole set: image + albedo + normal
        pred_img = make_predictions(ds, tmp / "pred_img", name="bench", noise=0.03, fmt="png", layers=("image",))
        pred_all = make_predictions(ds, tmp / "pred_all", name="bench", noise=0.03, fmt="png")
        n = 2 * per
        lp, dn = get_lpips_net("alex"), get_dists_net()
        rows = []
        nets = (("lpips (alex)", lp, "lpips"),) if args.only == "lpips" else \
            (("lpips (alex)", lp, "lpips"), ("dists (vgg16)", dn, "dists"))
        for name, net, metric in nets:
            bare = bare_forward(net, n, size, bs, rep)
            cold, warm = pipeline(ds, pred_img, [metric], conv, bs, rep)
            rows.append((name, n / cold, n / warm, n / bare, cold / bare, warm / bare))
        if args.only == "all":
            for metric in ("ssim", "psnr", "flip", "normal"):
                cold, warm = pipeline(ds, pred_img if metric != "normal" else pred_all, [metric], conv, bs, rep)
                rows.append((metric, n / cold, n / warm, None, None, None))
            # whole set: every frame has an image and an albedo pair through both networks (2 pairs per frame)
            bare_all = bare_forward(lp, 2 * n, size, bs, rep) + bare_forward(dn, 2 * n, size, bs, rep)
            cold, warm = pipeline(ds, pred_all, ["lpips", "dists", "ssim", "psnr", "flip", "normal"], conv, bs, rep)
            rows.append(("whole set (all 6)", n / cold, n / warm, n / bare_all, cold / bare_all, warm / bare_all))
        if args.compare_overlap:
            bare = bare_forward(lp, n, size, bs, rep)
            for ov in (False, True):
                cold, warm = pipeline(ds, pred_img, ["lpips"], conv, bs, rep, overlap=ov)
                rows.append((f"lpips overlap={ov}", n / cold, n / warm, n / bare, cold / bare, warm / bare))
        if args.profile:
            profile_cold(ds, pred_img, conv, bs)
    print(f"{'metric':20s} {'pairs/s cold':>13s} {'pairs/s warm':>13s} {'bare pairs/s':>13s} "
          f"{'cold/bare':>10s} {'warm/bare':>10s}")
    for name, c, w, b, rc, rw in rows:
        def cell(v, width, suffix=""):
            return f"{'—':>{width}s}" if v is None else f"{v:{width - len(suffix)}.2f}{suffix}"
        print(f"{name:20s} {cell(c, 13)} {cell(w, 13)} {cell(b, 13)} {cell(rc, 10, 'x')} {cell(rw, 10, 'x')}")
    print(f"{_load()} at the end. pairs/s = frames per second. cold = empty ground-truth feature cache (2 forward "
          "passes per pair); warm = cached GT features (a second method on the same dataset). The whole set "
          "evaluates image, albedo and normal per frame; its bare time is both backbones on both pairs, and its "
          "ratio also carries SSIM, PSNR, FLIP and normal error, which have no network counterpart.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
