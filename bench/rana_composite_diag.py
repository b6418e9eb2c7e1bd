"""How RANA's image should meet the background: AlbedoNet's mask thresholded at 0.5, or blended by.

    python bench/rana_composite_diag.py --dataset D --protocol a --runs <runs root> [--subject subject_000,...]

For the trained runs under `--runs`, on every test frame: the distribution of AlbedoNet's mask probability p over
the ground-truth person (GT coverage >= 128), then LPIPS and PSNR of the image written both ways
(`rana predict --mask-composite threshold | probability`), in rh-eval's default region (the leaderboard's
numbers) and inside the GT mask; and the same for SMPL+D from the runs' coarse stage, blended by its rasterised
coverage (what `rana smpld` writes) and thresholded at 0.5. Nothing is retrained; predictions go to a temporary
folder.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_rana import _scores  # noqa: E402
from rh_common.imageio import read_png  # noqa: E402


def mask_probabilities(dataset: Path, protocol: str, runs: Path, subject: str) -> np.ndarray:
    """AlbedoNet's p at every GT-person pixel of the subject's test frames (working resolution = frame size)."""
    from rana.data import resize_image
    from rana.predict import _run_for, _subject_frames, load_trained, rana_outputs

    cfg, coarse, model = load_trained(_run_for(runs, subject))
    ps = []
    with torch.no_grad():
        for tf in _subject_frames(dataset, protocol, [subject])[subject]:
            out = rana_outputs(model, coarse, tf, cfg)[0]
            p = resize_image(out["mask"][0, 0][..., None], int(tf.meta["height"]), int(tf.meta["width"]))[..., 0]
            gt = read_png(tf.layer_path("mask", "png"))
            gt = (gt if gt.ndim == 2 else gt[..., 0]) >= 128
            ps.append(p.numpy()[gt])
    return np.concatenate(ps)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--dataset", required=True, type=Path, help="dataset folder written by rh-generate")
    ap.add_argument("--protocol", default="a", help="protocol letter (a or b)")
    ap.add_argument("--runs", required=True, type=Path, help="folder of trained run folders, one per subject")
    ap.add_argument("--subject", default="all", help="subject_NNN, a comma-separated list, or 'all'")
    args = ap.parse_args(argv)

    from rana.predict import predict_rana, predict_smpld

    torch.set_num_threads(1)
    subjects = (sorted(p.name for p in args.runs.glob("subject_*") if (p / "coarse.pt").is_file())
                if args.subject == "all" else args.subject.split(","))
    p = np.concatenate([mask_probabilities(args.dataset, args.protocol, args.runs, s) for s in subjects])
    q = np.quantile(p, [0.05, 0.25, 0.5])
    print(f"AlbedoNet's mask p over the GT person ({len(subjects)} subjects, {p.size} pixels): "
          f"5/25/50% quantiles {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f}; p < 0.9: {(p < 0.9).mean():.1%}; "
          f"p <= 0.5: {(p <= 0.5).mean():.1%}")
    print(f"{'method':<7} {'composite':<12} {'LPIPS':>7} {'PSNR':>7} {'PSNR(mask)':>11}   (mean over test frames)")
    runs = (("RANA", predict_rana, ("threshold", "probability")), ("SMPL+D", predict_smpld, ("coverage", "threshold")))
    with tempfile.TemporaryDirectory() as tmp:
        for method, predict, modes in runs:
            for mode in modes:
                out = Path(tmp) / f"{method}_{mode}"
                predict(args.dataset, args.protocol, args.runs, out, subjects=subjects, progress=False,
                        mask_composite=mode)
                rows = [_scores(out, args.dataset, args.protocol, s) for s in subjects]
                mean = {k: float(np.mean([r[k] for r in rows])) for k in ("lpips", "psnr", "psnr_mask")}
                print(f"{method:<7} {mode:<12} {mean['lpips']:7.4f} {mean['psnr']:7.2f} {mean['psnr_mask']:11.2f}")
    print("LPIPS (alex), PSNR: rh-eval's default region; PSNR(mask): inside the GT mask; display space.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
