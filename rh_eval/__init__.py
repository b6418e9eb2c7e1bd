"""rh_eval: faithful image, albedo and normal metrics for the Relighting Humans benchmark, `rh-eval` and
`rh-leaderboard`. See docs/EVALUATION.md."""
__version__ = "0.1.0"

from .conventions import Convention  # noqa: E402
from .metrics import dists, flip, lpips, normal_angular_error, psnr, ssim  # noqa: E402

__all__ = ["__version__", "Convention", "psnr", "ssim", "lpips", "dists", "flip", "normal_angular_error"]
