"""rh_eval: faithful image, albedo and normal metrics for the Relighting Humans benchmark, `rh-eval` and
`rh-leaderboard`. See docs/EVALUATION.md.

A user scores images with the pure metric functions (`psnr`, `ssim`, `lpips`, `dists`, `flip`,
`normal_angular_error`) and a whole frame, exactly as `rh-eval` does, with `score_frame`; `named_convention(name)`
gives the bundle of choices a published method's own evaluation code makes (`rh-eval --convention`)."""
__version__ = "0.1.0"

from .conventions import CONVENTIONS, Convention, named_convention  # noqa: E402
from .metrics import dists, flip, lpips, normal_angular_error, psnr, ssim  # noqa: E402
from .scoring import (FrameGroundTruth, FramePrediction, FrameScores, LayerScores, read_frame,  # noqa: E402
                      score_frame)

__all__ = ["__version__", "Convention", "CONVENTIONS", "named_convention", "psnr", "ssim", "lpips", "dists", "flip",
           "normal_angular_error", "score_frame", "read_frame", "FramePrediction", "FrameGroundTruth", "FrameScores",
           "LayerScores"]
