"""One pure function per metric: `fn(pred, target, *, data_range=..., mask=None, ...)`, numpy in, float out
(LPIPS and DISTS: also a batch in, an array out).

Every function first runs the shared `_validate` (ValueError on bad input). See docs/EVALUATION.md.
"""
from .dists import dists, dists_features
from .flip import FLIP_PPD, flip
from .lpips import lpips, lpips_features
from .normal import normal_angular_error
from .psnr import mse, psnr
from .ssim import ssim

__all__ = ["psnr", "mse", "ssim", "lpips", "lpips_features", "dists", "dists_features", "flip", "FLIP_PPD",
           "normal_angular_error"]
