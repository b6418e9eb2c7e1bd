"""DISTS (Ding et al. 2020), the official `DISTS_pytorch.DISTS` forward pass:

    x in [0, 1], no resizing -> ImageNet normalisation -> VGG16 conv stages with every max-pool (indices 4, 9,
    16, 23) replaced by L2 pooling (3x3 Hann window [.5, 1, .5]^2 normalised, stride 2, padding 1,
    sqrt(conv(x^2) + 1e-12)) -> taps [x, relu1_2, relu2_2, relu3_3, relu4_3, relu5_3]
    -> per channel: S1 = (2 mx my + c1) / (mx^2 + my^2 + c1), S2 = (2 cov + c2) / (vx + vy + c2), c1 = c2 = 1e-6
       (means, variances, covariance over the whole map, population form)
    -> 1 - sum(alpha S1 + beta S2) with alpha, beta the published weights divided by their joint sum.

Identical inputs give 0 (up to round-off). A `mask` is refused, as for LPIPS. Batches and reference features
(`dists_features`) as for LPIPS.
"""
from __future__ import annotations

import functools

import numpy as np
import torch
from torch import nn

from rh_common.weights import load_backbone, load_dists_alpha_beta

from ._validate import _deep_inputs, _stack, _validate
from .lpips import check_same_features, to_tensor01

__all__ = ["dists", "dists_features", "DISTSNet", "get_dists_net"]

_MEAN = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
_STD = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
_CHANNELS = (3, 64, 128, 256, 512, 512)
_C1 = 1e-6
_C2 = 1e-6


class L2Pool(nn.Module):
    def __init__(self, channels: int) -> None:
        super().__init__()
        a = np.hanning(5)[1:-1]
        g = torch.tensor(a[:, None] * a[None, :], dtype=torch.float32)
        g = g / g.sum()
        self.register_buffer("filter", g[None, None].repeat(channels, 1, 1, 1))
        self.channels = channels

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = nn.functional.conv2d(x * x, self.filter, stride=2, padding=1, groups=self.channels)
        return torch.sqrt(out + 1e-12)


class DISTSNet:
    """VGG16 (shared with LPIPS-vgg's backbone object) with L2 pooling, and alpha/beta. `features` returns the six
    taps; `prepare` their per-channel statistics; `distance_prepared` the score (the GT side may come from a cache)."""

    def __init__(self) -> None:
        vgg = load_backbone("vgg16").features
        layers: list[nn.Module] = []
        taps = []
        for i in range(30):
            if i in (4, 9, 16, 23):
                layers.append(L2Pool({4: 64, 9: 128, 16: 256, 23: 512}[i]))
            else:
                layers.append(vgg[i])
            if i in (3, 8, 15, 22, 29):
                taps.append(i)
        self.layers = nn.Sequential(*layers).eval()
        self.taps = tuple(taps)
        alpha, beta = load_dists_alpha_beta()
        alpha, beta = alpha.double(), beta.double()
        w_sum = alpha.sum() + beta.sum()
        self.alpha = [a.view(1, -1) for a in torch.split(alpha / w_sum, _CHANNELS, dim=1)]
        self.beta = [b.view(1, -1) for b in torch.split(beta / w_sum, _CHANNELS, dim=1)]

    @torch.inference_mode()
    def backbone_forward(self, x01: torch.Tensor) -> list[torch.Tensor]:
        h = (x01 - _MEAN) / _STD
        out = [x01]
        for i, layer in enumerate(self.layers):
            h = layer(h)
            if i in self.taps:
                out.append(h)
        return out

    features = backbone_forward

    @staticmethod
    @torch.inference_mode()
    def prepare(feats: list[torch.Tensor]) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """Per tap: (mean (N, C), centred features, variance (N, C)), float32 as the official code. This is what
        the ground-truth cache keeps."""
        out = []
        for i, f in enumerate(feats):
            m = f.mean(dim=(2, 3), keepdim=True)
            # Taps after the input are fresh activations held by no one else: centred in place, which spares a
            # copy of the largest tensors (relu1_2 is 64 x H x W); tap 0 is the caller's input batch.
            c = f.sub_(m) if i > 0 else f - m
            v = (c * c).mean(dim=(2, 3))
            out.append((m.flatten(1), c, v))
        return out

    @torch.inference_mode()
    def distance_prepared(self, p0, p1) -> torch.Tensor:
        """DISTS from two `prepare`d feature sets, (N,) float64.

        Written as sum(alpha (1 - S1) + beta (1 - S2)), equal to the official 1 - sum(alpha S1 + beta S2) because
        the normalised weights sum to 1, but exactly 0 for identical inputs. The covariance is the mean of the
        product of centred features (the official mean(xy) - mx my, in a form without cancellation, and bitwise
        equal to the variance when the inputs are equal); the weighted sums are accumulated in float64.
        """
        total = None
        for k in range(len(_CHANNELS)):
            mx, cx, vx = p0[k]
            my, cy, vy = p1[k]
            cov = (cx * cy).mean(dim=(2, 3))
            s1 = ((2 * mx * my + _C1) / (mx ** 2 + my ** 2 + _C1)).double()
            s2 = ((2 * cov + _C2) / (vx + vy + _C2)).double()
            term = (self.alpha[k] * (1 - s1)).sum(1) + (self.beta[k] * (1 - s2)).sum(1)
            total = term if total is None else total + term
        return total

    def distance(self, f0: list[torch.Tensor], f1: list[torch.Tensor]) -> torch.Tensor:
        return self.distance_prepared(self.prepare(f0), self.prepare(f1))


@functools.lru_cache(maxsize=None)
def get_dists_net() -> DISTSNet:
    return DISTSNet()


def dists_features(target, *, data_range: float = 1.0) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
    """DISTS's per-tap statistics (`DISTSNet.prepare`) of reference images ((H, W, 3), (N, H, W, 3) or a list of
    equal-shape (H, W, 3) in [0, data_range]), batch first. `dists(pred, target_features=...)` takes them instead of
    the target images, so a reference scored many times (rh-eval's ground truth) runs once."""
    t, _ = _validate(_stack(target, name="dists", label="target"), None, data_range=data_range, name="dists",
                     batch=True)
    return _features(t, data_range)


def _features(checked: np.ndarray, data_range: float):
    net = get_dists_net()
    return net.prepare(net.features(to_tensor01(checked, data_range)))


def dists(pred, target=None, *, data_range: float = 1.0, mask=None,
          target_features: list | None = None) -> float | np.ndarray:
    """DISTS of `pred` against the reference `target`; (H, W, 3) -> float, (N, H, W, 3) or a list of equal-shape
    (H, W, 3) -> (N,). 0 if identical. One image is the batch of one. Give the reference as `target` images or as
    their `dists_features` (same data range), not both."""
    single, p, t = _deep_inputs(pred, target, target_features, mask, data_range=data_range, name="dists")
    if t is not None:
        target_features = _features(t, data_range)
    fp = _features(p, data_range)
    check_same_features("dists", [c for _, c, _ in target_features], [c for _, c, _ in fp])
    # official argument order: D(ref, dist)
    out = get_dists_net().distance_prepared(target_features, fp).numpy()
    return float(out[0]) if single else out
