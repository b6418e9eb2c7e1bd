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
The overhead ratio is pipeline cold / bare (goal <= 1.3x); warm / bare shows the cache's gain. Bare, cold and
warm runs are interleaved (bare, cold, warm, bare, cold, warm, ...) so that a change of machine load hits all three
alike; each ratio is the median over the `--repeat` rounds of that round's own ratio, and the pairs/s columns are
the best round. Bare and pipeline use the same torch threads. The load average is printed with the table. `--profile` prints where the cold LPIPS
pipeline spends its time (cProfile, main thread; the worker threads show up as lock waits).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
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


def _seconds(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def bare_pass(net, n: int, size: int, batch: int):
    """A callable running the backbone twice per pair (prediction and ground truth) on in-memory tensors."""
    rng = np.random.default_rng(0)
    xs = [torch.from_numpy(rng.uniform(0, 1, (min(batch, n - s), 3, size, size)).astype(np.float32))
          for s in range(0, n, batch)]

    def run():
        for x in xs:
            net.backbone_forward(x)  # prediction
            net.backbone_forward(x)  # ground truth
    return run


def bare_cpu_metrics(n: int, size: int):
    """A callable running the CPU metrics the whole set needs, directly on in-memory arrays: PSNR, SSIM and FLIP on
    an image and an albedo pair per frame, the normal error once per frame."""
    from rh_eval.metrics import flip, normal_angular_error, psnr, ssim

    rng = np.random.default_rng(1)
    a = rng.uniform(0, 1, (size, size, 3))
    b = np.clip(a + rng.normal(0, 0.03, a.shape), 0, 1)
    na = rng.normal(size=(size, size, 3))
    na /= np.linalg.norm(na, axis=-1, keepdims=True)
    nb = na + rng.normal(0, 0.05, na.shape)
    nb /= np.linalg.norm(nb, axis=-1, keepdims=True)

    def run():
        for _ in range(n):
            for _pair in ("image", "albedo"):
                psnr(b, a, data_range=1.0)
                ssim(b, a, data_range=1.0)
                flip(b, a, data_range=1.0)
            normal_angular_error(nb, na)
    return run


@dataclass
class Rounds:
    """Seconds per round of the interleaved bare / cold / warm measurements."""
    bare: list[float]
    cold: list[float]
    warm: list[float]
    bare_parts: list[list[float]] | None = None  # per round, the seconds of each bare callable

    def with_bare_parts(self, parts: slice) -> "Rounds":
        """The same rounds with the bare time made of a subset of the bare callables."""
        return Rounds([sum(r[parts]) for r in self.bare_parts], self.cold, self.warm)

    def row(self, name: str, n: int) -> tuple:
        has_bare = bool(self.bare)
        return (name, n / min(self.cold), n / min(self.warm), n / min(self.bare) if has_bare else None,
                statistics.median(c / b for c, b in zip(self.cold, self.bare)) if has_bare else None,
                statistics.median(w / b for w, b in zip(self.warm, self.bare)) if has_bare else None)


def interleaved(ds: Path, pred: Path, metrics, conv: Convention, batch: int, repeat: int, bare_fns=(),
                **options) -> Rounds:
    """`repeat` rounds of: the bare passes (summed), a cold pipeline run, a warm pipeline run."""
    def evaluator():
        return Evaluator(EvalOptions(convention=conv, metrics=tuple(metrics), batch_size=batch, progress=False,
                                     **options))

    for fn in bare_fns:
        fn()  # warm-up: allocator, threads
    warm_ev = evaluator()
    warm_ev.evaluate(pred, ds)  # warm-up (imports, file system cache) and fills this evaluator's GT feature cache
    out = Rounds([], [], [], [])
    for _ in range(repeat):
        if bare_fns:
            out.bare_parts.append([_seconds(fn) for fn in bare_fns])
            out.bare.append(sum(out.bare_parts[-1]))
        out.cold.append(_seconds(lambda: evaluator().evaluate(pred, ds)))  # a fresh, empty GT feature cache
        out.warm.append(_seconds(lambda: warm_ev.evaluate(pred, ds)))  # ground-truth features cached
    return out


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
    p.add_argument("--batch-size", type=int, default=4,
                   help="frames per network batch, in the pipeline (EvalOptions.batch_size) and the bare passes "
                        "alike (default 4)")
    p.add_argument("--region", default="full", choices=("full", "default", "mask"),
                   help="region convention (default full: the networks see the whole 512x512 frame, like the bare "
                        "passes; 'default' crops to the person's dilated box and is faster)")
    p.add_argument("--repeat", type=int, default=3,
                   help="interleaved rounds (bare, cold, warm) per row; ratios are the median of the per-round "
                        "ratios, pairs/s the best round (default 3)")
    p.add_argument("--only", choices=("lpips", "whole", "all"), default="all",
                   help="lpips: only the LPIPS rows (quick); whole: only the whole-set rows; all: every metric and "
                        "the whole set (default)")
    p.add_argument("--profile", action="store_true", help="also print a cProfile of one cold LPIPS run")
    p.add_argument("--compare-overlap", action="store_true",
                   help="also time the LPIPS pipeline with the workers in turns with the networks and overlapping "
                        "them (EvalOptions.overlap False/True), against the same bare passes")
    args = p.parse_args(argv)
    n, size, bs, rep = args.frames, args.size, args.batch_size, args.repeat
    conv = Convention(region=args.region)
    print(f"rh-eval bench: {n} frame pairs at {size}x{size}, batch {bs}, region {args.region}, "
          f"torch {torch.__version__} with {torch.get_num_threads()} threads, {rep} interleaved rounds; {_load()} at start")
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
        nets = {"lpips": (("lpips (alex)", lp, "lpips"),), "whole": (),
                "all": (("lpips (alex)", lp, "lpips"), ("dists (vgg16)", dn, "dists"))}[args.only]
        for name, net, metric in nets:
            r = interleaved(ds, pred_img, [metric], conv, bs, rep, bare_fns=(bare_pass(net, n, size, bs),))
            rows.append(r.row(name, n))
        if args.only == "all":
            for metric in ("ssim", "psnr", "flip", "normal"):
                r = interleaved(ds, pred_img if metric != "normal" else pred_all, [metric], conv, bs, rep)
                rows.append(r.row(metric, n))
        if args.only in ("all", "whole"):
            # whole set: every frame has an image and an albedo pair through both networks (2 pairs per frame)
            bare_nets = (bare_pass(lp, 2 * n, size, bs), bare_pass(dn, 2 * n, size, bs))
            r = interleaved(ds, pred_all, ["lpips", "dists", "ssim", "psnr", "flip", "normal"], conv, bs, rep,
                            bare_fns=bare_nets + (bare_cpu_metrics(n, size),))
            # the same runs against the backbones alone (the CPU metrics then count as overhead)
            rows.append(r.row("whole set (all 6)", n))
            rows.append(r.with_bare_parts(slice(0, 2)).row("  vs backbones only", n))
        if args.compare_overlap:
            for ov in (False, True):
                r = interleaved(ds, pred_img, ["lpips"], conv, bs, rep, bare_fns=(bare_pass(lp, n, size, bs),),
                                overlap=ov)
                rows.append(r.row(f"lpips overlap={ov}", n))
        if args.profile:
            profile_cold(ds, pred_img, conv, bs)
    print(f"{'metric':20s} {'pairs/s cold':>13s} {'pairs/s warm':>13s} {'bare pairs/s':>13s} "
          f"{'cold/bare':>10s} {'warm/bare':>10s}  (ratios: median of per-round ratios)")
    for name, c, w, b, rc, rw in rows:
        def cell(v, width, suffix=""):
            return f"{'—':>{width}s}" if v is None else f"{v:{width - len(suffix)}.2f}{suffix}"
        print(f"{name:20s} {cell(c, 13)} {cell(w, 13)} {cell(b, 13)} {cell(rc, 10, 'x')} {cell(rw, 10, 'x')}")
    print(f"{_load()} at the end. pairs/s = frames per second. cold = empty ground-truth feature cache (2 forward "
          "passes per pair); warm = cached GT features (a second method on the same dataset). The whole set "
          "evaluates image, albedo and normal per frame; its bare time is both backbones on both pairs plus SSIM, "
          "PSNR and FLIP on both pairs and the normal error, called directly on in-memory arrays; 'vs backbones "
          "only' divides the same pipeline times by the backbones alone (the CPU metrics then count as overhead).")
    return 0


if __name__ == "__main__":
    sys.exit(main())
