"""Networks and image operators: vanilla U-Net (TextureNet, NormalNet, AlbedoNet), PatchGAN, positional
encoding, VGG16 perceptual loss with the true ImageNet weights, Gaussian blur, differentiable sRGB."""
from __future__ import annotations

import math

import torch
import torch.nn as nn
import torch.nn.functional as F

__all__ = ["UNet", "PatchDiscriminator", "positional_encoding", "pe_channels", "VGGPerceptual", "gaussian_blur",
           "srgb_encode_t", "hinge_d_loss", "hinge_g_loss", "scaled_odd"]


def _block(c_in: int, c_out: int) -> nn.Sequential:
    # Two 3x3 convs with instance norm: the 'vanilla' U-Net block (norm keeps batch-1 personalization stable).
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, padding=1), nn.InstanceNorm2d(c_out, affine=True), nn.LeakyReLU(0.2, inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1), nn.InstanceNorm2d(c_out, affine=True), nn.LeakyReLU(0.2, inplace=True),
    )


class UNet(nn.Module):
    """U-Net: `depth` max-pool levels, channels base * 2^level (capped at 8 x base), bilinear up + skip concat.

    Inputs of any size are reflect-padded to a multiple of 2^depth and cropped back."""

    def __init__(self, c_in: int, c_out: int, base: int = 32, depth: int = 4):
        super().__init__()
        self.depth = depth
        chans = [min(base * 2 ** i, base * 8) for i in range(depth + 1)]
        self.down = nn.ModuleList([_block(c_in, chans[0])] + [_block(chans[i], chans[i + 1]) for i in range(depth)])
        self.up = nn.ModuleList([_block(chans[i + 1] + chans[i], chans[i]) for i in reversed(range(depth))])
        self.head = nn.Conv2d(chans[0], c_out, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        H, W = x.shape[-2:]
        m = 2 ** self.depth
        ph, pw = (-H) % m, (-W) % m
        if ph or pw:
            x = F.pad(x, (0, pw, 0, ph), mode="replicate")
        skips = []
        h = x
        for i, blk in enumerate(self.down):
            if i > 0:
                h = F.max_pool2d(h, 2)
            h = blk(h)
            skips.append(h)
        for blk in self.up:
            skip = skips.pop(-2)
            h = F.interpolate(h, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            h = blk(torch.cat([h, skip], 1))
        return self.head(h)[..., :H, :W]


class PatchDiscriminator(nn.Module):
    """pix2pix PatchGAN (n_layers=3 gives 70x70 receptive fields); spectral norm instead of batch norm."""

    def __init__(self, c_in: int = 3, base: int = 64, n_layers: int = 3):
        super().__init__()
        sn = nn.utils.spectral_norm
        layers = [sn(nn.Conv2d(c_in, base, 4, 2, 1)), nn.LeakyReLU(0.2, True)]
        c = base
        for i in range(1, n_layers):
            c2 = min(base * 2 ** i, base * 8)
            layers += [sn(nn.Conv2d(c, c2, 4, 2, 1)), nn.LeakyReLU(0.2, True)]
            c = c2
        c2 = min(c * 2, base * 8)
        layers += [sn(nn.Conv2d(c, c2, 4, 1, 1)), nn.LeakyReLU(0.2, True), sn(nn.Conv2d(c2, 1, 4, 1, 1))]
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


def hinge_d_loss(real: torch.Tensor, fake: torch.Tensor) -> torch.Tensor:
    return F.relu(1 - real).mean() + F.relu(1 + fake).mean()


def hinge_g_loss(fake: torch.Tensor) -> torch.Tensor:
    return -fake.mean()


def pe_channels(n_freq: int) -> int:
    return 2 + 4 * n_freq


def positional_encoding(uv: torch.Tensor, n_freq: int, mask: torch.Tensor | None = None) -> torch.Tensor:
    """NeRF's gamma on UV: (B, 2, H, W) → (B, 2 + 4L, H, W): [uv, sin(2^k pi uv), cos(2^k pi uv)]; 0 off-body."""
    feats = [uv]
    for k in range(n_freq):
        a = (2.0 ** k) * math.pi * uv
        feats += [torch.sin(a), torch.cos(a)]
    out = torch.cat(feats, 1)
    return out * mask if mask is not None else out


def srgb_encode_t(x: torch.Tensor) -> torch.Tensor:
    """Differentiable sRGB curve (IEC 61966-2-1) on clip(x, 0, 1): the evaluator's display space."""
    x = x.clamp(0.0, 1.0)
    return torch.where(x <= 0.0031308, 12.92 * x, 1.055 * x.clamp_min(1e-8) ** (1 / 2.4) - 0.055)


def srgb_decode_t(x: torch.Tensor) -> torch.Tensor:
    """Inverse of `srgb_encode_t` on clip(x, 0, 1), differentiable."""
    x = x.clamp(0.0, 1.0)
    return torch.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def scaled_odd(k_at_512: int, resolution: int) -> int:
    """A kernel size given at 512 px, scaled to `resolution` and kept odd (>= 3)."""
    k = max(3, int(round(k_at_512 * resolution / 512)))
    return k if k % 2 else k + 1


def gaussian_blur(x: torch.Tensor, k: int) -> torch.Tensor:
    """Separable Gaussian, kernel k, sigma = 0.3((k-1)/2 - 1) + 0.8 (OpenCV's default for a given k); reflect pad."""
    sigma = 0.3 * ((k - 1) * 0.5 - 1) + 0.8
    r = torch.arange(k, dtype=x.dtype, device=x.device) - (k - 1) / 2
    g = torch.exp(-0.5 * (r / sigma) ** 2)
    g = g / g.sum()
    C = x.shape[1]
    pad = k // 2
    mode = "reflect" if pad < min(x.shape[-2:]) else "replicate"
    y = F.pad(x, (pad, pad, 0, 0), mode=mode)
    y = F.conv2d(y, g.view(1, 1, 1, k).expand(C, 1, 1, k), groups=C)
    y = F.pad(y, (0, 0, pad, pad), mode=mode)
    return F.conv2d(y, g.view(1, 1, k, 1).expand(C, 1, k, 1), groups=C)


class VGGPerceptual(nn.Module):
    """L1 between VGG16 features relu1_2, relu2_2, relu3_3, relu4_3 (TextureNet/RANA appendix), ImageNet weights
    from `rh_common.weights.load_backbone('vgg16')` (sha256-pinned). Inputs in [0, 1], (B, 3, H, W)."""

    TAPS = (3, 8, 15, 22)

    def __init__(self) -> None:
        super().__init__()
        from rh_common.weights import load_backbone

        feats = load_backbone("vgg16").features
        # A private copy of layers 0..22 so nothing we do (e.g. .train()) touches the evaluator's cached model.
        self.layers = nn.Sequential(*[feats[i] for i in range(self.TAPS[-1] + 1)])
        for p in self.layers.parameters():
            p.requires_grad_(False)
        self.register_buffer("mean", torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1))

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        h = (x - self.mean) / self.std
        out = []
        for i, layer in enumerate(self.layers):
            h = layer(h)
            if i in self.TAPS:
                out.append(h)
        return out

    def forward(self, pred: torch.Tensor, target: torch.Tensor | None = None,
                target_features: list[torch.Tensor] | None = None) -> torch.Tensor:
        """`target_features`: the target's `features`, when computed once beforehand (fixed training frames)."""
        fp = self.features(pred)
        if target_features is None:
            with torch.no_grad():
                target_features = self.features(target)
        return sum(F.l1_loss(a, b) for a, b in zip(fp, target_features)) / len(fp)

    @torch.no_grad()
    def target_buffers(self, image01: torch.Tensor) -> dict[str, torch.Tensor]:
        """Features of one fixed (3, H, W) target as batch-buffer entries `vgg_target_<i>` (see `from_batch`)."""
        return {f"vgg_target_{i}": f[0] for i, f in enumerate(self.features(image01[None]))}

    @staticmethod
    def from_batch(batch: dict) -> list[torch.Tensor] | None:
        keys = [f"vgg_target_{i}" for i in range(len(VGGPerceptual.TAPS))]
        return [batch[k] for k in keys] if all(k in batch for k in keys) else None
