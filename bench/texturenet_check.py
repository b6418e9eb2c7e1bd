"""Does TextureNet help? Train it on some pretraining characters and score held-out ones: the display-space L1 and
the PSNR of its albedo texture against the ground-truth albedo texture, beside those of its input (the de-lit
or shaded median texture) — the estimate it has to beat.

    python bench/texturenet_check.py --dataset PRETRAIN_DATA --cache OUT/cache --steps 40,80 --holdout 2

The characters are prepared exactly as `rana-pretrain` does (same config flags) and cached in `--cache`, the
folder `rana-pretrain --out OUT` reuses. Each entry of `--steps` is a separate training run with its own cosine
schedule (what a run of that length gives); prints one row per run and the CPU seconds they took.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path

import torch

from rana.config import PRESETS, get_preset
from rana.config_flags import add_config_flags, apply_config_flags
from rana.data import subjects_of
from rana.nets import srgb_encode_t
from rana.pretrain import load_or_prepare_character, train_texturenet
from rana.texturenet import TextureNet


def score(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> tuple[float, float]:
    """(display L1, display PSNR) over the texels whose target is known."""
    d = (srgb_encode_t(pred) - srgb_encode_t(target))[:, valid]
    mse = float((d ** 2).mean())
    return float(d.abs().mean()), 10 * math.log10(1 / max(mse, 1e-12))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("--dataset", required=True, type=Path, help="AOV-only pretraining dataset")
    p.add_argument("--protocol", default="a", help="protocol folder of the --dataset (default a)")
    p.add_argument("--cache", required=True, type=Path, help="character cache folder (rana-pretrain's OUT/cache)")
    p.add_argument("--preset", default="cpu", choices=sorted(PRESETS),
                   help="starting configuration (default cpu); the --<section>.<field> flags override it")
    p.add_argument("--steps", default="80", help="TextureNet run lengths, comma-separated (default 80)")
    p.add_argument("--holdout", type=int, default=2, help="the last N characters are held out")
    add_config_flags(p)
    args = p.parse_args()
    cfg = apply_config_flags(get_preset(args.preset), args)
    if cfg.threads > 0:
        torch.set_num_threads(cfg.threads)
    subjects = subjects_of(args.dataset, args.protocol, "train")
    if cfg.pretrain.max_subjects > 0:
        subjects = subjects[: cfg.pretrain.max_subjects]
    if len(subjects) <= args.holdout:
        raise SystemExit(f"{args.dataset}: {len(subjects)} characters, need more than --holdout {args.holdout}")
    chars = [load_or_prepare_character(args.dataset, s, args.protocol, cfg, args.cache) for s in subjects]
    train, held = chars[: -args.holdout], chars[-args.holdout:]

    def row(label: str, f) -> None:
        l1, psnr = zip(*[score(f(c), c["target"], c["target_valid"]) for c in held])
        print(f"{label:>26} | {sum(l1) / len(l1):.4f} | {sum(psnr) / len(psnr):6.2f}")

    print(f"TextureNet ({cfg.texture.texturenet_input} input, lambda_gan {cfg.texture.lambda_gan}), "
          f"{len(train)} training / {len(held)} held-out characters")
    print(f"{'albedo texture':>26} | L1 ↓   | PSNR ↑")
    row("input (no TextureNet)", lambda c: c["net_input"].clamp(0, 1))
    t0 = time.process_time()
    for steps in [int(x) for x in args.steps.split(",")]:
        c2 = dataclasses.replace(cfg, texture=dataclasses.replace(cfg.texture, steps=steps))
        net = train_texturenet(train, c2, progress=False)
        row(f"TextureNet, {steps} steps", lambda c, n=net: n.apply(c["net_input"], c["valid"]))
    print(f"CPU seconds: {time.process_time() - t0:.0f}")


if __name__ == "__main__":
    main()
