"""Throughput of rh-eval at 512x512: frame pairs per second per metric and for the whole set, and the ratio of the
pipeline's time to the bare backbone forward passes measured in the same run.

    python bench/bench_eval.py [--frames 8] [--size 512] [--batch-size 4] [--region full]

What is timed:
- `bare`: the backbone alone on in-memory tensors, two forward passes per pair (prediction and ground truth),
  batched like the pipeline: AlexNet taps for LPIPS, VGG16 with L2 pooling for DISTS.
- `pipeline cold`: `Evaluator.evaluate` on a synthetic dataset written to disk (EXR/PNG reading, display
  transform, region, validation, batching, metric heads, result aggregation), empty ground-truth feature cache.
- `pipeline warm`: the same with the ground-truth features already cached (a second method against the same
  dataset): one forward pass per pair.
- CPU metrics (SSIM, PSNR, FLIP, normal error) through the pipeline alone.
The overhead ratio is pipeline cold / bare (goal <= 1.3x); warm / bare shows the cache's gain.
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


def _time(fn, repeat: int = 2) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bare_forward(net, n: int, size: int, batch: int) -> float:
    rng = np.random.default_rng(0)
    xs = [torch.from_numpy(rng.uniform(0, 1, (min(batch, n - s), 3, size, size)).astype(np.float32))
          for s in range(0, n, batch)]

    def run():
        for x in xs:
            net.backbone_forward(x)  # prediction
            net.backbone_forward(x)  # ground truth
    run()  # warm-up (allocator, threads)
    return _time(run)


def pipeline(ds: Path, pred: Path, metrics, conv: Convention, batch: int) -> tuple[float, float]:
    ev = Evaluator(EvalOptions(convention=conv, metrics=tuple(metrics), batch_size=batch, progress=False))
    t0 = time.perf_counter()
    ev.evaluate(pred, ds)  # cold: empty ground-truth feature cache
    t_cold = time.perf_counter() - t0
    t_warm = _time(lambda: ev.evaluate(pred, ds))
    return t_cold, t_warm


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=8, help="frame pairs (default 8)")
    p.add_argument("--size", type=int, default=512, help="frame size in pixels (default 512)")
    p.add_argument("--batch-size", type=int, default=4)
    p.add_argument("--region", default="full", choices=("full", "default", "mask"),
                   help="region convention (default full: the networks see the whole 512x512 frame, like the bare "
                        "passes; 'default' crops to the person's dilated box and is faster)")
    args = p.parse_args(argv)
    n, size, bs = args.frames, args.size, args.batch_size
    conv = Convention(region=args.region)
    print(f"rh-eval bench: {n} frame pairs at {size}x{size}, batch {bs}, region {args.region}, "
          f"torch {torch.__version__} with {torch.get_num_threads()} threads")
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
        for name, net, metric in (("lpips (alex)", lp, "lpips"), ("dists (vgg16)", dn, "dists")):
            bare = bare_forward(net, n, size, bs)
            cold, warm = pipeline(ds, pred_img, [metric], conv, bs)
            rows.append((name, n / cold, n / warm, n / bare, cold / bare, warm / bare))
        for metric in ("ssim", "psnr", "flip", "normal"):
            cold, warm = pipeline(ds, pred_img if metric != "normal" else pred_all, [metric], conv, bs)
            rows.append((metric, n / cold, n / warm, None, None, None))
        # whole set: every frame has an image and an albedo pair through both networks (2 pairs per frame)
        bare_all = bare_forward(lp, 2 * n, size, bs) + bare_forward(dn, 2 * n, size, bs)
        cold, warm = pipeline(ds, pred_all, ["lpips", "dists", "ssim", "psnr", "flip", "normal"], conv, bs)
        rows.append(("whole set (all 6)", n / cold, n / warm, n / bare_all, cold / bare_all, warm / bare_all))
    print(f"{'metric':20s} {'pairs/s cold':>13s} {'pairs/s warm':>13s} {'bare pairs/s':>13s} "
          f"{'cold/bare':>10s} {'warm/bare':>10s}")
    for name, c, w, b, rc, rw in rows:
        f = lambda v, fmt: ("—" if v is None else format(v, fmt))  # noqa: E731
        print(f"{name:20s} {f(c, '13.2f')} {f(w, '13.2f')} {f(b, '13.2f')} {f(rc, '9.2f')}x {f(rw, '9.2f')}x")
    print("pairs/s = frames per second. cold = empty ground-truth feature cache (2 forward passes per pair); warm "
          "= cached GT features (a second method on the same dataset). The whole set evaluates image, albedo and "
          "normal per frame; its bare time is both backbones on both pairs, and its ratio also carries SSIM, PSNR, "
          "FLIP and normal error, which have no network counterpart.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
