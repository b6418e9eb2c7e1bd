"""TextureNet (paper Sec. 3.2, appendix): U-Net from a shaded, holey UV texture (+ UV coordinates, + which texels
were observed) to the albedo texture, trained with L1 + VGG + PatchGAN on pairs from pretraining characters.

The validity channel is our addition to the paper's input (texture + UV): the network is told which texels are
hole-filled guesses rather than observations. So is the 'exposure-sh' input mode (`TextureConfig.texturenet_input`):
the texture is de-lit before TextureNet sees it, and the network outputs a correction to it.
"""
from __future__ import annotations

import typing

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from .config import TextureConfig, TextureNetInput
from .nets import PatchDiscriminator, UNet, VGGPerceptual, hinge_d_loss, hinge_g_loss, srgb_decode_t, srgb_encode_t
from .texture import TexelObservations, exposure_sh_delight, extract_texture, fill_holes, uv_coordinate_image

__all__ = ["TextureNet", "input_texture", "texturenet_input", "augment", "texturenet_loss"]


INPUT_MODES = typing.get_args(TextureNetInput)  # defined once, in the config


class TextureNet(nn.Module):
    """(B, 6, S, S) `texturenet_input` → (B, 3, S, S) linear albedo.

    `input_mode` 'shaded': the paper's network, albedo = sigmoid(U-Net). 'exposure-sh': the input texture is
    already de-lit, and albedo = decode(clip(input + U-Net)) in display space, with the U-Net's last layer
    initialised to zero, so an untrained network returns its input."""

    def __init__(self, cfg: TextureConfig, input_mode: str | None = None):
        super().__init__()
        self.input_mode = cfg.texturenet_input if input_mode is None else input_mode
        if self.input_mode not in INPUT_MODES:
            raise ValueError(f"texture.texturenet_input: expected one of {INPUT_MODES}, got {self.input_mode!r}")
        self.net = UNet(6, 3, cfg.unet_base, cfg.unet_depth)
        if self.residual:
            nn.init.zeros_(self.net.head.weight)
            nn.init.zeros_(self.net.head.bias)

    @property
    def residual(self) -> bool:
        return self.input_mode == "exposure-sh"

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.residual:
            return srgb_decode_t(x[:, :3] + self.net(x))
        return torch.sigmoid(self.net(x))

    @torch.no_grad()
    def apply(self, texture: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        """(3, S, S) median texture (exposure-scaled radiance; de-lit in 'exposure-sh' mode), (S, S) validity →
        (3, S, S) albedo."""
        self.eval()
        return self(texturenet_input(texture, valid)[None])[0]


def input_texture(mode: str, obs: TexelObservations, cfg: TextureConfig):
    """The texture TextureNet starts from, for a subject's back-projected observations: (3, S, S) texture,
    (S, S) validity, and the de-lighting's (9, 3) light ('exposure-sh') or None ('shaded')."""
    if mode == "exposure-sh":
        return exposure_sh_delight(obs, cfg, ridge=cfg.delight_ridge)
    if mode == "shaded":
        tex, valid = extract_texture([], None, None, cfg, obs=obs)
        return tex, valid, None
    raise ValueError(f"texture.texturenet_input: expected one of {INPUT_MODES}, got {mode!r}")


def texturenet_input(shaded: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """(6, S, S): hole-filled texture in display space, UV coordinates, validity."""
    S = shaded.shape[-1]
    filled = srgb_encode_t(fill_holes(shaded, valid))
    uv = uv_coordinate_image(S).permute(2, 0, 1)
    return torch.cat([filled, uv, valid[None].float()], 0)


def augment(x: torch.Tensor, rng: np.random.Generator) -> torch.Tensor:
    """Appendix augmentations of the texture channels: coarse dropout, Gaussian noise, random brightness."""
    x = x.clone()
    S = x.shape[-1]
    tex = x[:, :3]
    tex = tex * float(rng.uniform(0.7, 1.3))
    tex = tex + float(rng.uniform(0, 0.03)) * torch.from_numpy(rng.standard_normal(tex.shape).astype(np.float32))
    for _ in range(int(rng.integers(0, 6))):
        h = int(rng.integers(S // 32 + 1, S // 8 + 2))
        y0, x0 = int(rng.integers(0, S - h + 1)), int(rng.integers(0, S - h + 1))
        tex[:, :, y0:y0 + h, x0:x0 + h] = 0
        x[:, 5, y0:y0 + h, x0:x0 + h] = 0
    x[:, :3] = tex.clamp(0, 1)
    return x


def texturenet_loss(net: TextureNet, disc: PatchDiscriminator | None, vgg: VGGPerceptual | None, x: torch.Tensor,
                    target: torch.Tensor, target_valid: torch.Tensor, cfg: TextureConfig) -> dict:
    """L1 + lambda_VGG VGG + lambda_GAN GAN, compared in display space over texels whose target is known."""
    m = target_valid[:, None].float()
    pred = srgb_encode_t(net(x)) * m
    gt = srgb_encode_t(target) * m
    L = {"l1": F.l1_loss(pred, gt)}
    if vgg is not None and cfg.lambda_vgg > 0:
        L["vgg"] = vgg(pred, gt)
    if disc is not None and cfg.lambda_gan > 0:
        L["gan"] = hinge_g_loss(disc(pred))
    L["total"] = L["l1"] + cfg.lambda_vgg * L.get("vgg", 0) + cfg.lambda_gan * L.get("gan", 0)
    L["_pred"], L["_gt"] = pred, gt
    return L
