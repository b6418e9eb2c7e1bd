"""`rh-eval`: score one predictions folder against one split of the dataset (`test`, or `--split`, e.g. `olat`).
See docs/EVALUATION.md."""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from rh_common.interrupt import add_debug_flag, checkpoint, command, on_stop

__all__ = ["main", "build_parser"]

_EPILOG = """\
output: OUT (JSON: per-subject and overall means and population stds, convention, weight sha256s, dataset manifest
sha256, versions, frame counts) and OUT's stem + '.frames.csv' (one row per frame). PSNR of identical images is
+inf: 'inf' in the CSV; JSON means are over finite frames with n_infinite counting the rest ("inf" if all are).
Exit status: 0 on success, 2 when the inputs are refused (the message names each offending file), 1 otherwise.
"""


def _ppd(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number of pixels per degree, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    from .conventions import ALIGNMENTS, BACKGROUNDS, CONVENTIONS, REGIONS
    from .evaluate import ALL_METRICS
    from .metrics.flip import FLIP_PPD

    p = argparse.ArgumentParser(
        prog="rh-eval", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_EPILOG,
        description="Evaluate relighting predictions on the Relighting Humans benchmark with the metrics as "
                    "published: LPIPS (v0.1), DISTS, SSIM (Wang 2004), PSNR, FLIP (LDR) on images and albedo, "
                    "mean angular error on normals.")
    p.add_argument("predictions", type=Path,
                   help="predictions folder: <subject>/protocol_<p>/<split>/frame_NNNNNN_{image,albedo,normal}"
                        ".{exr,png} (+ optional method.json with a 'name' and optional 'kind': method|bound)")
    p.add_argument("--dataset", type=Path, required=True, help="dataset folder (holds manifest.json and subjects)")
    p.add_argument("--protocol", default="a", help="protocol to evaluate: 'a' or 'protocol_a' (default: a)")
    p.add_argument("--split", default="test",
                   help="the dataset split to score, and the predictions' folder name (default: test; e.g. olat "
                        "for the one-light-at-a-time split of the olat_a/olat_b scenes); recorded in the result")
    p.add_argument("--out", type=Path, required=True, help="result JSON to write (folders are created)")
    p.add_argument("--csv", type=Path, default=None, help="per-frame CSV path (default: <out stem>.frames.csv)")
    p.add_argument("--convention", choices=tuple(CONVENTIONS), default="rana",
                   help="the bundle of evaluation choices: rana (default: region, compositing, Wang SSIM, LPIPS as "
                        "published for this dataset), intrinsicavatar or relightableavatar (as those methods' own "
                        "evaluation code scores; docs/EVALUATION.md lists every choice); the flags below override "
                        "single choices, and the result records them all")
    p.add_argument("--backbone", choices=("alex", "vgg"), default=None,
                   help="LPIPS backbone (rana: alex, the official default; recorded in the output)")
    p.add_argument("--region", choices=REGIONS, default=None,
                   help="default (rana): GT-mask bounding box dilated by round(50*min(H,W)/720) px, prediction and "
                        "GT composited over --background (the published protocol); full: whole frame, no "
                        "compositing; mask: tight box, PSNR/SSIM/FLIP averaged inside the mask only; box100: the "
                        "box of the mask dilated by a 100x100 kernel (intrinsicavatar)")
    p.add_argument("--background", choices=sorted(BACKGROUNDS), default=None,
                   help="background for compositing (rana: white)")
    p.add_argument("--albedo-space", choices=("srgb", "linear"), default=None,
                   help="space albedo is compared in (rana: srgb, linear albedo sRGB-encoded)")
    p.add_argument("--align-albedo", nargs="?", const="lsq", choices=ALIGNMENTS, default=None,
                   help="also report albedo after a per-channel scale onto the GT (linear, inside the mask, then "
                        "clipped to [0,1]): lsq (least squares; the value when the flag is given alone) or median "
                        "(of GT / prediction); none turns it off; reported as albedo_aligned_* beside the raw "
                        "scores (rana: none, intrinsicavatar: lsq, relightableavatar: median)")
    p.add_argument("--align-image", nargs="?", const="median", choices=("none", "median"), default=None,
                   help="also report the relit image scaled per channel by the median of GT / prediction over the "
                        "mask (display space, clipped to [0,1]) as image_aligned_* (relightableavatar: median)")
    p.add_argument("--flip-ppd", type=_ppd, default=None, metavar="PPD",
                   help=f"FLIP pixels per degree of the assumed viewing condition (default {FLIP_PPD:.4f}, FLIP's "
                        f"default: 0.7 m from a 0.7 m wide 3840-px monitor); recorded in the result, and results "
                        f"with different values are not combined by rh-leaderboard")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="evaluate the frames that exist when some are missing; the result is marked incomplete "
                        "and lists them (invalid files are still refused)")
    p.add_argument("--metrics", default=",".join(ALL_METRICS),
                   help=f"comma-separated subset of {','.join(ALL_METRICS)} (default: all)")
    p.add_argument("--batch-size", type=int, default=4,
                   help="frames per network batch (crops of equal size are batched; default 4)")
    p.add_argument("--cache-dir", type=Path, default=None,
                   help="folder for ground-truth network features, reused across runs and methods (keyed by GT "
                        "file sha256 + convention + weights); default: in-memory only")
    p.add_argument("--cache-mb", type=int, default=2048, help="in-memory feature cache bound in MB (default 2048)")
    p.add_argument("--kind", choices=("method", "bound"), default=None,
                   help="override method.json's kind: 'bound' marks an oracle, listed apart on the leaderboard")
    p.add_argument("--name", default=None, help="override the method name from method.json")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument("--workers", type=int, default=None,
                   help="threads that decode and check files and compute SSIM/PSNR/FLIP/normal error beside the "
                        "networks (default: as many as torch's threads)")
    p.add_argument("--preload-mb", type=int, default=1024,
                   help="prediction pixels decoded by the up-front check are kept up to this many MB instead of "
                        "decoded a second time (default 1024; 0 = always decode again)")
    p.add_argument("--no-thumbnails", action="store_true",
                   help="write no pictures (<out stem>.thumbs/: display-space tiles of the evaluated region, error "
                        "maps, albedo and normal for a seeded set of frames, shown by rh-leaderboard)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_debug_flag(p)
    return p


@command("rh-eval")
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    on_stop(lambda: f"no result was written ({args.out} is written whole at the end)")
    from .conventions import named_convention
    from .dataset_io import PredictionError
    from .evaluate import EvalOptions, Evaluator
    from .report import write_result
    from rh_common.imageio import ImageFileError, read_json
    from rh_common.threads import torch_threads
    from rh_common.weights import WeightError

    try:
        metrics = tuple(m.strip() for m in args.metrics.split(",") if m.strip())
        conv = named_convention(args.convention, region=args.region, background=args.background,
                                albedo_space=args.albedo_space, align_albedo=args.align_albedo,
                                align_image=args.align_image, backbone=args.backbone, flip_ppd=args.flip_ppd)
        opts = EvalOptions(convention=conv, metrics=metrics, batch_size=args.batch_size, cache_dir=args.cache_dir,
                           cache_mb=args.cache_mb, allow_incomplete=args.allow_incomplete,
                           progress=False if args.no_progress else None, threads=args.threads,
                           workers=args.workers, preload_mb=args.preload_mb, thumbnails=not args.no_thumbnails)
        with torch_threads(opts.threads):  # the command's own count; the Evaluator never changes it
            ev = Evaluator(opts)
            result, rows, cols = ev.evaluate(args.predictions, args.dataset, args.protocol, split=args.split)
    except (PredictionError, ImageFileError, WeightError, FileNotFoundError, ValueError) as exc:
        checkpoint()  # an error that follows a stop lost in a C callback is that stop (rh_common.interrupt)
        print(f"rh-eval: error: {exc}", file=sys.stderr)
        return 2
    if args.kind:
        result["kind"] = args.kind
    if args.name:
        result["method"] = dict(result["method"], name=args.name)
    csv_path = write_result(args.out, result, rows, cols, args.csv, thumbnails=ev.thumbnails)
    ov = result["overall"]
    status = "complete" if result["complete"] else f"INCOMPLETE ({len(result['missing'])} missing)"
    print(f"rh-eval: {result['method'].get('name')}: {result['n_frames_evaluated']} frames, {status}; "
          f"convention={conv.name} backbone={conv.backbone} region={conv.region} flip_ppd={conv.flip_ppd:.6g}")
    for c in cols:
        s = ov[c]
        extra = f" (+{s['n_infinite']} inf)" if s.get("n_infinite") else ""
        mean = s["mean"] if isinstance(s["mean"], str) or s["mean"] is None else f"{s['mean']:.6g}"
        print(f"  {c:24s} {mean}{extra}")
    thumbs = read_json(args.out).get("thumbnails")  # the record write_result added
    pics = f" and {thumbs['n_frames']} frames' pictures in {thumbs['dir']}/ ({thumbs['tile_bytes']} bytes)" \
        if thumbs else ""
    print(f"rh-eval: wrote {args.out}, {csv_path}{pics}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
