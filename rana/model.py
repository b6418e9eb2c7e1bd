"""The relightable articulated neural avatar (paper Sec. 3.3) and the coarse render buffers it consumes.

Model interface (nerfstudio's): `get_outputs(batch)` → images; `get_loss_dict(outputs, batch)` → weighted terms;
`get_metrics_dict(outputs, batch)`. A batch is a dict of (B, C, H, W) tensors made by `coarse_buffers` +
`stack_batch`.

Image formation: ``image = albedo * max(0, S(normal; E))`` with S = `rh_common.sh.shading` (E/pi). The clamp is
ours: order-2 SH can ring negative under directional light, and radiance cannot be negative.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from rh_common import sh

from .body import BodyTopology, vertex_normals
from .config import LossConfig, ModelConfig, PretrainConfig
from .data import FrameData
from .nets import (PatchDiscriminator, UNet, VGGPerceptual, gaussian_blur, hinge_d_loss, hinge_g_loss, pe_channels,
                   positional_encoding, scaled_odd, srgb_encode_t)
from .raster import interpolate, project, rasterize
from .texture import sample_texture

__all__ = ["RanaModel", "coarse_buffers", "stack_batch", "shade", "AMBIENT_L0"]

# Radiance coefficient L_0 of a uniform white environment whose shading is exactly 1: S = L_0 Y_0 = 1.
AMBIENT_L0 = 2.0 * math.sqrt(math.pi)
# Mask logit of the SMPL+D coverage in the residual parameterisation: sigmoid(+-4) = 0.982 / 0.018.
MASK_LOGIT = 4.0
# Scale of the default initialisation of the U-Nets' last (1x1) layers when they output corrections.
HEAD_INIT_SCALE = 1e-2
# Albedo range kept away from 0 and 1 before the logit (a coarse albedo of exactly 0 or 1 would be unreachable).
_ALBEDO_EPS = 1e-3


def _logit(x: torch.Tensor) -> torch.Tensor:
    x = x.clamp(_ALBEDO_EPS, 1 - _ALBEDO_EPS)
    return torch.log(x) - torch.log1p(-x)


@torch.no_grad()
def coarse_buffers(frame: FrameData, topo: BodyTopology, offsets: torch.Tensor | None,
                   albedo_tex: torch.Tensor | None) -> dict:
    """Rasterise the SMPL+D mesh of one frame: UV, coarse normals (OpenGL camera), coarse albedo, mask, face box.

    Not differentiable (geometry is fixed once fitted); what RANA learns enters through `grid_sample` of Z at these
    UVs, so gradients still reach Z and the networks.
    """
    verts = frame.body.vertices(offsets)
    r = rasterize(project(verts, frame.K, frame.world_to_camera), topo.faces, frame.H, frame.W)
    m = r.mask
    uv = interpolate(r, topo.face_uv, topo.uv)
    n = interpolate(r, topo.faces, vertex_normals(verts, topo.faces) @ frame.world_to_opengl.T)
    n = F.normalize(n, dim=-1, eps=1e-12) * m[..., None]
    out = {
        "uv": uv.permute(2, 0, 1).contiguous(),
        "smpl_mask": m[None].float(),
        "coarse_normal": n.permute(2, 0, 1).contiguous(),
    }
    if albedo_tex is not None:
        out["coarse_albedo"] = sample_texture(albedo_tex, uv, m)
    head = verts[topo.head_vertices].mean(0, keepdim=True)
    c = project(head, frame.K, frame.world_to_camera)[0, :2]
    out["face_centre"] = c
    if frame.image is not None:
        out["image"] = frame.image.permute(2, 0, 1).contiguous()
    if frame.mask is not None:
        out["mask"] = frame.mask[None].contiguous()
    if frame.albedo is not None:
        out["albedo"] = frame.albedo.permute(2, 0, 1).contiguous()
    if frame.normal is not None:
        out["normal"] = frame.normal.permute(2, 0, 1).contiguous()
    return out


def stack_batch(items: list[dict], **extra) -> dict:
    keys = set(items[0])
    for it in items[1:]:
        keys &= set(it)
    out = {k: torch.stack([it[k] for it in items]) for k in keys}
    out.update(extra)
    return out


def shade(coeffs: torch.Tensor, normal: torch.Tensor) -> torch.Tensor:
    """(B, 9, 3) light, (B, 3, H, W) normals → (B, 3, H, W) shading, clamped at 0 (see module docstring)."""
    outs = [sh.shading(coeffs[b], normal[b].permute(1, 2, 0)).permute(2, 0, 1) for b in range(normal.shape[0])]
    return torch.stack(outs).clamp_min(0.0)


class RanaModel(nn.Module):
    """Z (per subject), E (per training video), NormalNet G_N, AlbedoNet G_A."""

    def __init__(self, cfg: ModelConfig, n_subjects: int = 1, n_lights: int = 1, seed: int = 0):
        super().__init__()
        self.cfg = cfg
        g = torch.Generator().manual_seed(seed)
        self.Z = nn.Parameter(0.01 * torch.randn(n_subjects, cfg.latent_channels, cfg.latent_size, cfg.latent_size,
                                                 generator=g))
        E = torch.zeros(n_lights, 9, 3)
        # 'From scratch' = a uniform white light giving shading 1 (zero light would give zero shading, where the
        # clamp at 0 has no gradient).
        E[:, 0, :] = AMBIENT_L0
        self.E = nn.Parameter(E)
        c_in = cfg.latent_channels + 3 + pe_channels(cfg.pe_frequencies)
        self.G_N = UNet(c_in, 3, cfg.unet_base, cfg.unet_depth)
        self.G_A = UNet(c_in, 4, cfg.unet_base, cfg.unet_depth)
        if cfg.residual_coarse:
            # Near-zero heads: at initialisation the outputs are the coarse normal, albedo and mask (SMPL+D) up to
            # ~1e-2 in logit / normal units. Not exactly zero: a zero head would stop every gradient to Z while
            # G_A is frozen (the first `freeze_albedo_steps`).
            with torch.no_grad():
                for net in (self.G_N, self.G_A):
                    net.head.weight.mul_(HEAD_INIT_SCALE)
                    net.head.bias.zero_()

    # ------------------------------------------------------------------------------------------ forward
    def network_inputs(self, batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
        uv, m = batch["uv"], batch["smpl_mask"]
        subj = batch.get("subject")
        Z = self.Z[subj] if subj is not None else self.Z[:1].expand(uv.shape[0], -1, -1, -1)
        grid = torch.stack([uv[:, 0] * 2 - 1, 1 - uv[:, 1] * 2], -1)  # = texture.uv_to_grid
        feats = F.grid_sample(Z, grid, mode="bilinear", padding_mode="border", align_corners=False) * m
        pe = positional_encoding(uv, self.cfg.pe_frequencies, m)
        x_n = torch.cat([feats, batch["coarse_normal"], pe], 1)
        x_a = torch.cat([feats, batch["coarse_albedo"], pe], 1)
        return x_n, x_a

    def get_outputs(self, batch: dict, light: torch.Tensor | None = None) -> dict:
        """`light` (B, 9, 3) radiance SH in OpenGL camera axes; default = the learned E of `batch['light']`."""
        x_n, x_a = self.network_inputs(batch)
        dn = self.G_N(x_n)
        a = self.G_A(x_a)
        if self.cfg.residual_coarse:
            # Corrections of the coarse stage: the normal is offset, the albedo and mask shifted in logit space.
            normal = F.normalize(batch["coarse_normal"] + dn, dim=1, eps=1e-6)
            albedo = torch.sigmoid(_logit(batch["coarse_albedo"]) + a[:, :3])
            mask_logit = MASK_LOGIT * (2 * batch["smpl_mask"] - 1) + a[:, 3:4]
        else:
            normal = F.normalize(dn, dim=1, eps=1e-6)
            albedo = torch.sigmoid(a[:, :3])
            mask_logit = a[:, 3:4]
        if light is None:
            idx = batch.get("light")
            light = self.E[idx] if idx is not None else self.E[:1].expand(normal.shape[0], -1, -1)
        shading = shade(light, normal)
        image = albedo * shading
        mask = torch.sigmoid(mask_logit)
        out = {"normal": normal, "albedo": albedo, "mask_logit": mask_logit, "mask": mask, "shading": shading,
               "image": image}
        if "image" in batch:
            # Training: the person is overlaid on the frame's own background (the mask gets gradients from this too).
            out["composite"] = mask * image + (1 - mask) * batch["image"]
        return out

    # ------------------------------------------------------------------------------------------ losses
    def get_loss_dict(self, outputs: dict, batch: dict, cfg: LossConfig, vgg: VGGPerceptual | None,
                      disc: PatchDiscriminator | None) -> dict:
        res = batch["uv"].shape[-2]
        pred = srgb_encode_t(outputs["composite"])
        gt = srgb_encode_t(batch["image"])
        L: dict[str, torch.Tensor] = {}
        L["pixel"] = F.l1_loss(pred, gt)
        if cfg.lambda_face > 0:
            L["face"] = _face_l1(pred, gt, batch["face_centre"], max(8, round(cfg.face_crop_px * res / 512)))
        L["mask"] = F.binary_cross_entropy_with_logits(outputs["mask_logit"], batch["mask"])
        if cfg.lambda_vgg > 0 and vgg is not None:
            L["vgg"] = vgg(pred, gt, VGGPerceptual.from_batch(batch))
        if cfg.lambda_gan > 0 and disc is not None:
            L["gan"] = hinge_g_loss(disc(pred))
        k = scaled_odd(cfg.blur_kernel, res)
        L["albedo_reg"] = F.mse_loss(gaussian_blur(outputs["albedo"], k), gaussian_blur(batch["coarse_albedo"], k))
        m = batch["smpl_mask"]
        L["normal_reg"] = F.l1_loss(m * outputs["normal"], m * batch["coarse_normal"])
        w = {"pixel": cfg.lambda_pixel, "face": cfg.lambda_face, "mask": cfg.lambda_mask, "vgg": cfg.lambda_vgg,
             "gan": cfg.lambda_gan, "albedo_reg": cfg.lambda_albedo_reg, "normal_reg": cfg.lambda_normal_reg}
        L["total"] = sum(w[k_] * v for k_, v in L.items())
        return L

    def get_pretrain_loss_dict(self, outputs: dict, batch: dict, cfg: PretrainConfig, vgg: VGGPerceptual | None,
                               disc_n: PatchDiscriminator | None, disc_a: PatchDiscriminator | None) -> dict:
        """Appendix: L_normal + lambda_a L_albedo + lambda_m BCE, each of L1 + lambda_VGG VGG + lambda_GAN GAN.
        Normals are compared as (n+1)/2 images so VGG and the discriminator see [0, 1] inputs."""
        gm = batch["mask"]
        n_pred = (outputs["normal"] * 0.5 + 0.5) * gm
        n_gt = (batch["normal"] * 0.5 + 0.5) * gm
        a_pred = srgb_encode_t(outputs["albedo"] * gm)
        a_gt = srgb_encode_t(batch["albedo"] * gm)
        L: dict[str, torch.Tensor] = {"normal_l1": F.l1_loss(n_pred, n_gt), "albedo_l1": F.l1_loss(a_pred, a_gt)}
        if cfg.lambda_vgg > 0 and vgg is not None:
            L["normal_vgg"] = vgg(n_pred, n_gt)
            L["albedo_vgg"] = vgg(a_pred, a_gt)
        if cfg.lambda_gan > 0 and disc_n is not None:
            L["normal_gan"] = hinge_g_loss(disc_n(n_pred))
            L["albedo_gan"] = hinge_g_loss(disc_a(a_pred))
        L["mask"] = F.binary_cross_entropy_with_logits(outputs["mask_logit"], gm)
        ln = L["normal_l1"] + cfg.lambda_vgg * L.get("normal_vgg", 0) + cfg.lambda_gan * L.get("normal_gan", 0)
        la = L["albedo_l1"] + cfg.lambda_vgg * L.get("albedo_vgg", 0) + cfg.lambda_gan * L.get("albedo_gan", 0)
        L["total"] = ln + cfg.lambda_albedo * la + cfg.lambda_mask * L["mask"]
        L["_disc_inputs"] = (n_pred, n_gt, a_pred, a_gt)
        return L

    @torch.no_grad()
    def get_metrics_dict(self, outputs: dict, batch: dict) -> dict:
        pred = srgb_encode_t(outputs["composite"])
        gt = srgb_encode_t(batch["image"])
        mse = F.mse_loss(pred, gt).clamp_min(1e-12)
        return {"psnr": float(-10 * torch.log10(mse))}


def _face_l1(pred: torch.Tensor, gt: torch.Tensor, centre: torch.Tensor, size: int) -> torch.Tensor:
    """L1 over a size x size crop around each image's projected head (clamped to stay inside the image)."""
    B, _, H, W = pred.shape
    size = min(size, H, W)
    losses = []
    for b in range(B):
        x0 = int(np.clip(round(float(centre[b, 0]) - size / 2), 0, W - size))
        y0 = int(np.clip(round(float(centre[b, 1]) - size / 2), 0, H - size))
        losses.append(F.l1_loss(pred[b, :, y0:y0 + size, x0:x0 + size], gt[b, :, y0:y0 + size, x0:x0 + size]))
    return torch.stack(losses).mean()
