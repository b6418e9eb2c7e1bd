"""LPIPS v0.1 (Zhang et al. 2018), the official `lpips.LPIPS(net=..., version='0.1')` forward pass:

    x in [-1, 1] -> scaling layer ((x - shift) / scale, shift = (-.030, -.088, -.188), scale = (.458, .448, .450))
    -> backbone taps (AlexNet relu1..5 or VGG16 relu1_2..relu5_3, ImageNet weights)
    -> unit-normalise each feature vector over channels (f / (||f|| + 1e-10))
    -> squared difference, 1x1 linear head (v0.1 weights, no bias), spatial mean, sum over the five taps.

No resizing (the official default). AlexNet is the default backbone. The public functions take display-space
images in [0, data_range] (converted here to [-1, 1]). The squared difference of normalised features is symmetric,
so lpips(a, b) == lpips(b, a) up to round-off.

A `mask` is refused: LPIPS is defined on a rectangle; the region convention (`rh_eval.conventions`) crops and
composites before the network runs.
"""
from __future__ import annotations

import functools

import numpy as np
import torch

from rh_common.weights import load_backbone, load_lpips_heads

from ._validate import _validate

__all__ = ["lpips", "LPIPSNet", "get_lpips_net", "BACKBONES"]

BACKBONES = {"alex": "alexnet", "vgg": "vgg16"}
_SHIFT = torch.tensor([-0.030, -0.088, -0.188]).view(1, 3, 1, 1)
_SCALE = torch.tensor([0.458, 0.448, 0.450]).view(1, 3, 1, 1)
_EPS = 1e-10


class LPIPSNet:
    """Backbone + heads, loaded once. `features` -> list of normalised taps; `distance(f0, f1)` -> (N,)."""

    def __init__(self, backbone: str = "alex") -> None:
        if backbone not in BACKBONES:
            raise ValueError(f"lpips: backbone must be one of {sorted(BACKBONES)}, got {backbone!r}")
        self.backbone = backbone
        self.net = load_backbone(BACKBONES[backbone])
        self.heads = [h.view(1, -1, 1, 1) for h in load_lpips_heads(BACKBONES[backbone])]

    @torch.inference_mode()
    def backbone_forward(self, x01: torch.Tensor) -> list[torch.Tensor]:
        """Raw taps for (N, 3, H, W) images in [0, 1] (used by the bench as the bare cost)."""
        x = x01 * 2.0 - 1.0
        return self.net((x - _SHIFT) / _SCALE)

    @torch.inference_mode()
    def features(self, x01: torch.Tensor) -> list[torch.Tensor]:
        taps = self.backbone_forward(x01)
        # In place: the taps are fresh ReLU outputs nobody else holds, and these heads cost a quarter of AlexNet
        # at 512x512 when every step allocates. Same operations in the same order: the same bits as
        # f / (sqrt(sum(f * f)) + eps).
        for f in taps:
            norm = torch.sum(f * f, dim=1, keepdim=True)
            f.div_(norm.sqrt_().add_(_EPS))
        return taps

    @torch.inference_mode()
    def distance(self, f0: list[torch.Tensor], f1: list[torch.Tensor]) -> torch.Tensor:
        total = None
        for a, b, w in zip(f0, f1, self.heads):
            d = a - b
            d.mul_(d).mul_(w)  # torch computes x ** 2 as x * x: the same bits, two fewer allocations
            d = d.sum(dim=1).mean(dim=(1, 2), dtype=torch.float64)
            total = d if total is None else total + d
        return total


@functools.lru_cache(maxsize=None)
def get_lpips_net(backbone: str = "alex") -> LPIPSNet:
    """One `LPIPSNet` per backbone per process."""
    return LPIPSNet(backbone)


def to_tensor01(x: np.ndarray, data_range: float) -> torch.Tensor:
    """(H, W, 3) or (N, H, W, 3) in [0, data_range] -> (N, 3, H, W) float32 in [0, 1]."""
    if x.ndim == 3:
        x = x[None]
    return torch.from_numpy(np.ascontiguousarray((x / data_range).transpose(0, 3, 1, 2), dtype=np.float32))


def lpips(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, mask=None,
          backbone: str = "alex") -> float | np.ndarray:
    """LPIPS v0.1 distance; (H, W, 3) -> float, (N, H, W, 3) -> (N,) array. 0 for identical inputs."""
    p, t = _validate(pred, target, data_range=data_range, name="lpips", batch=True)
    if mask is not None:
        raise ValueError("lpips: a mask is not supported (LPIPS is defined on a rectangle); crop and composite "
                         "with rh_eval.conventions first")
    if backbone not in BACKBONES:
        raise ValueError(f"lpips: backbone must be one of {sorted(BACKBONES)}, got {backbone!r}")
    net = get_lpips_net(backbone)
    d = net.distance(net.features(to_tensor01(p, data_range)), net.features(to_tensor01(t, data_range)))
    out = d.numpy()
    return float(out[0]) if pred.ndim == 3 else out
