"""LPIPS v0.1 (Zhang et al. 2018), the official `lpips.LPIPS(net=..., version='0.1')` forward pass:

    x in [-1, 1] -> scaling layer ((x - shift) / scale, shift = (-.030, -.088, -.188), scale = (.458, .448, .450))
    -> backbone taps (AlexNet relu1..5 or VGG16 relu1_2..relu5_3, ImageNet weights)
    -> unit-normalise each feature vector over channels (f / (||f|| + 1e-10))
    -> squared difference, 1x1 linear head (v0.1 weights, no bias), spatial mean, sum over the five taps.

No resizing (the official default). AlexNet is the default backbone. The public functions take display-space
images in [0, data_range] (converted here to [-1, 1]). The squared difference of normalised features is symmetric,
so lpips(a, b) == lpips(b, a) up to round-off.

`normalize=False` feeds the [0, 1] values to the network as they are, as code that calls the official
`lpips.LPIPS()(a, b)` on [0, 1] images without `normalize=True` does (rh_eval.conventions: relightableavatar); it
departs from LPIPS's documented [-1, 1] input range, and its numbers are not LPIPS's usual scale.

A `mask` is refused: LPIPS is defined on a rectangle; the region convention (`rh_eval.conventions`) crops and
composites before the network runs.

`lpips` scores a batch ((N, H, W, 3) or a list of equal-shape images; one image is the batch of one). The reference
side may be given as `lpips_features(target)` instead of the images: rh-eval keeps the ground truth's features in a
cache and passes them back, through this same function.
"""
from __future__ import annotations

import functools

import numpy as np
import torch

from rh_common.weights import load_backbone, load_lpips_heads

from ._validate import _deep_inputs, _stack, _validate

__all__ = ["lpips", "lpips_features", "LPIPSNet", "get_lpips_net", "BACKBONES"]

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
    def backbone_forward(self, x01: torch.Tensor, normalize: bool = True) -> list[torch.Tensor]:
        """Raw taps for (N, 3, H, W) images in [0, 1] (used by the bench as the bare cost); `normalize=False`:
        the values taken as already in [-1, 1]."""
        x = x01 * 2.0 - 1.0 if normalize else x01
        return self.net((x - _SHIFT) / _SCALE)

    @torch.inference_mode()
    def features(self, x01: torch.Tensor, normalize: bool = True) -> list[torch.Tensor]:
        taps = self.backbone_forward(x01, normalize)
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


def _check_backbone(backbone: str) -> None:
    if backbone not in BACKBONES:
        raise ValueError(f"lpips: backbone must be one of {sorted(BACKBONES)}, got {backbone!r}")


def check_same_features(name: str, got: list, want: list) -> None:
    """Reference features given to `lpips`/`dists` must be those of images shaped like `pred`: a feature set of
    another batch size would broadcast silently (N=1 against N) instead of failing."""
    shapes = [tuple(t.shape) for t in got]
    if shapes != [tuple(t.shape) for t in want]:
        raise ValueError(f"{name}: target_features do not match pred (tap shapes {shapes} != "
                         f"{[tuple(t.shape) for t in want]}): compute them from targets shaped like pred")


def lpips_features(target, *, data_range: float = 1.0, backbone: str = "alex",
                   normalize: bool = True) -> list[torch.Tensor]:
    """LPIPS's normalised features of reference images ((H, W, 3), (N, H, W, 3) or a list of equal-shape (H, W, 3)
    in [0, data_range]): one (N, C, h, w) tensor per tap, batch first. `lpips(pred, target_features=...)` takes
    them instead of the target images, so a reference scored many times (rh-eval's ground truth) runs once."""
    _check_backbone(backbone)
    t, _ = _validate(_stack(target, name="lpips", label="target"), None, data_range=data_range, name="lpips",
                     batch=True)
    return _features(t, data_range, backbone, normalize)


def _features(checked: np.ndarray, data_range: float, backbone: str, normalize: bool = True) -> list[torch.Tensor]:
    net, x = get_lpips_net(backbone), to_tensor01(checked, data_range)
    return net.features(x) if normalize else net.features(x, normalize=False)


def lpips(pred, target=None, *, data_range: float = 1.0, mask=None, backbone: str = "alex",
          target_features: list[torch.Tensor] | None = None, normalize: bool = True) -> float | np.ndarray:
    """LPIPS v0.1 distance; (H, W, 3) -> float, (N, H, W, 3) or a list of equal-shape (H, W, 3) -> (N,) array. 0 for
    identical inputs. One image is the batch of one. Give the reference as `target` images or as their
    `lpips_features` (same backbone, data range and `normalize`), not both. `normalize=False`: see the module
    docstring."""
    _check_backbone(backbone)
    single, p, t = _deep_inputs(pred, target, target_features, mask, data_range=data_range, name="lpips")
    if t is not None:
        target_features = _features(t, data_range, backbone, normalize)
    net = get_lpips_net(backbone)
    fp = _features(p, data_range, backbone, normalize)
    check_same_features("lpips", target_features, fp)
    out = net.distance(fp, target_features).numpy()
    return float(out[0]) if single else out
