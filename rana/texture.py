"""Coarse albedo texture (paper Sec. 3.2): back-project training pixels to anny's UV space, keep per texel the
median of its most camera-facing observations, then TextureNet turns that shaded, holey map into an albedo map.

UV convention: anny's per-corner texture coordinates, v up (OBJ). A texture array's row 0 is v = 1, column 0 is
u = 0; texel (i, j) has its centre at u = (j + 0.5)/S, v = 1 − (i + 0.5)/S. `uv_to_grid` maps UVs to
`grid_sample` coordinates (align_corners=False) under exactly this convention; everything samples through it.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from rh_common import sh

from .body import BodyTopology, vertex_normals
from .config import TextureConfig
from .data import FrameData
from .raster import Raster, interpolate, project, rasterize

__all__ = ["UVRaster", "uv_raster", "uv_to_grid", "sample_texture", "TexelObservations", "texel_observations",
           "extract_texture", "exposure_sh_delight", "EXPOSURE_L0", "fill_holes", "grey_world_delight",
           "uv_coordinate_image"]


@dataclass
class UVRaster:
    """Which triangle covers each texel centre, and where (barycentrics of the triangle's UV corners)."""

    raster: Raster  # (S, S) over texture space
    size: int

    @property
    def valid(self) -> torch.Tensor:
        return self.raster.mask


def uv_to_grid(uv: torch.Tensor) -> torch.Tensor:
    """(..., 2) UV in [0, 1] (v up) → grid_sample coordinates in [-1, 1] (x right, y down)."""
    return torch.stack([uv[..., 0] * 2 - 1, 1 - uv[..., 1] * 2], dim=-1)


@functools.lru_cache(maxsize=8)
def _uv_raster_cached(size: int) -> UVRaster:
    from .body import body_topology

    topo = body_topology()
    # Texture space as a screen: x = u S, y = (1 - v) S, constant depth (so barycentrics stay affine).
    screen = torch.stack([topo.uv[:, 0] * size, (1 - topo.uv[:, 1]) * size, torch.ones(len(topo.uv))], 1)
    return UVRaster(rasterize(screen, topo.face_uv, size, size), size)


def uv_raster(size: int) -> UVRaster:
    return _uv_raster_cached(int(size))


def uv_coordinate_image(size: int) -> torch.Tensor:
    """(S, S, 2) the UV of every texel centre (TextureNet's extra input)."""
    c = (torch.arange(size, dtype=torch.float32) + 0.5) / size
    v, u = torch.meshgrid(1 - c, c, indexing="ij")
    return torch.stack([u, v], -1)


def sample_texture(tex: torch.Tensor, uv: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Bilinear lookup of `tex` (C, S, S) at `uv` (..., H, W, 2) → (..., C, H, W); zero where mask is False."""
    lead = uv.shape[:-3]
    g = uv_to_grid(uv.reshape(-1, *uv.shape[-3:]))
    t = tex[None].expand(g.shape[0], -1, -1, -1) if tex.dim() == 3 else tex
    out = F.grid_sample(t, g, mode="bilinear", padding_mode="border", align_corners=False)
    if mask is not None:
        out = out * mask.reshape(-1, 1, *mask.shape[-2:]).to(out.dtype)
    return out.reshape(*lead, *out.shape[1:]) if lead else out[0]


def _texel_points(uvr: UVRaster, topo: BodyTopology, vertices: torch.Tensor, normals: torch.Tensor):
    sel = uvr.valid.reshape(-1)
    tri = uvr.raster.tri.reshape(-1)[sel]
    b = uvr.raster.bary.reshape(-1, 3)[sel]
    f = topo.faces[tri]
    p = (b[..., None] * vertices[f]).sum(1)
    n = F.normalize((b[..., None] * normals[f]).sum(1), dim=-1, eps=1e-12)
    return sel, p, n


@dataclass
class TexelObservations:
    """Every training frame's view of every texel: colour, facing, world-space normal, visibility."""

    sel: torch.Tensor  # (S*S,) texels covered by the UV layout; the arrays below are over these N texels
    colour: torch.Tensor  # (F, N, 3) the frame's layer at the texel's projection
    facing: torch.Tensor  # (F, N) cos(normal, direction to the camera); -1 where not visible
    normal: torch.Tensor  # (F, N, 3) unit world-space normal of the posed SMPL+D surface
    size: int


@torch.no_grad()
def texel_observations(frames: list[FrameData], topo: BodyTopology, offsets: torch.Tensor | None,
                       cfg: TextureConfig, layer: str = "image", depth_tol: float = 0.03) -> TexelObservations:
    """Back-project the frames' `layer` ('image' or 'albedo') to anny's UV space.

    A texel is observed in a frame when its surface point projects inside the person mask, passes a depth test
    against the frame's z-buffer of the same mesh, and faces the camera by more than `cfg.min_facing`.
    """
    uvr = uv_raster(cfg.size)
    cols, facings, normals = [], [], []
    sel = None
    for fr in frames:
        img = getattr(fr, layer)
        if img is None:
            raise ValueError(f"{fr.path}: frame has no {layer} layer loaded")
        verts = fr.body.vertices(offsets)
        vn = vertex_normals(verts, topo.faces)
        sel, p, n = _texel_points(uvr, topo, verts, vn)
        screen = project(p, fr.K, fr.world_to_camera)
        r = rasterize(project(verts, fr.K, fr.world_to_camera), topo.faces, fr.H, fr.W)
        px = screen[:, 0].floor().long()
        py = screen[:, 1].floor().long()
        inb = (px >= 0) & (px < fr.W) & (py >= 0) & (py < fr.H)
        pxc, pyc = px.clamp(0, fr.W - 1), py.clamp(0, fr.H - 1)
        zb = r.depth[pyc, pxc]
        vis = inb & r.mask[pyc, pxc] & ((screen[:, 2] - zb).abs() < depth_tol * zb.clamp_min(1e-3))
        if fr.mask is not None:
            vis &= fr.mask[pyc, pxc] > 0.5
        to_cam = F.normalize(fr.camera_centre[None] - p, dim=-1)
        facing = (n * to_cam).sum(-1)
        vis &= facing > cfg.min_facing
        g = torch.stack([screen[:, 0] / fr.W * 2 - 1, screen[:, 1] / fr.H * 2 - 1], -1)[None, None]
        c = F.grid_sample(img.permute(2, 0, 1)[None], g, mode="bilinear", padding_mode="border",
                          align_corners=False)[0, :, 0].T  # (N, 3)
        cols.append(c)
        facings.append(torch.where(vis, facing, torch.full_like(facing, -1.0)))
        normals.append(n)
    return TexelObservations(sel, torch.stack(cols), torch.stack(facings), torch.stack(normals), cfg.size)


def _most_facing(obs: TexelObservations, quantile: float) -> torch.Tensor:
    """(F, N) the observations whose facing is at least `quantile` x the texel's best: 'the most orthogonal'."""
    best = obs.facing.max(0).values
    return (obs.facing > 0) & (obs.facing >= quantile * best[None])


def _to_texture(obs: TexelObservations, values: torch.Tensor, ok: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    S = obs.size
    tex = torch.zeros(S * S, values.shape[-1])
    valid = torch.zeros(S * S, dtype=torch.bool)
    idx = torch.nonzero(obs.sel)[:, 0]
    tex[idx[ok]] = values[ok]
    valid[idx[ok]] = True
    return tex.view(S, S, -1).permute(2, 0, 1).contiguous(), valid.view(S, S)


@torch.no_grad()
def extract_texture(frames: list[FrameData], topo: BodyTopology, offsets: torch.Tensor | None, cfg: TextureConfig,
                    layer: str = "image", depth_tol: float = 0.03,
                    obs: TexelObservations | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Median texture (3, S, S) and its validity (S, S) from the frames' `layer` ('image' or 'albedo').

    Among a texel's observations (`texel_observations`), those whose facing is at least `facing_quantile` x the
    best one are its 'most orthogonal' ones; the texel's colour is their per-channel median.
    """
    if obs is None:
        obs = texel_observations(frames, topo, offsets, cfg, layer, depth_tol)
    use = _most_facing(obs, cfg.facing_quantile)
    vals = torch.where(use[..., None], obs.colour, torch.full_like(obs.colour, float("nan")))
    med = torch.nanmedian(vals, dim=0).values  # (N, 3)
    return _to_texture(obs, med, use.any(0))


# The training light's DC coefficient in the frames' units (docs/ARCHITECTURE.md 'Exposure'): frames are
# exposure x radiance with exposure = 1 / (mean luminance of the light over the sphere), and the mean radiance over
# the sphere is L_0 Y_0 = L_0 / (2 sqrt(pi)); so lum(L_0) = 2 sqrt(pi), and an achromatic DC term of that value
# shades every normal by exactly 1.
EXPOSURE_L0 = 2.0 * math.sqrt(math.pi)


@torch.no_grad()
def exposure_sh_delight(obs: TexelObservations, cfg: TextureConfig, iters: int = 15, ridge: float = 1e-2,
                        min_shading: float = 0.05) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Training light (order-2 SH, world axes, the frames' units) and per-texel albedo fitted jointly to
    ``observed = albedo x S(n)`` with the coarse SMPL+D normals; returns (albedo (3, S, S), valid (S, S),
    light (9, 3)).

    Scale: albedo x light has one free scale per channel. The exposure convention fixes it: frames are
    exposure x radiance with exposure = 1 / (the light's mean luminance over the sphere), and that mean is
    L_0 Y_0, so lum(L_0) = 2 sqrt(pi) exactly; we take the DC term white (the one prior), which shades every
    normal by exactly 1. Bands 1-2: alternating least squares over every visible observation, starting from the
    uniform light (albedo = observed), per texel albedo given the light, then the light's bands 1-2 given the
    albedos with a ridge (`ridge` x the mean diagonal of the normal equations); the last 5 rounds down-weight
    outliers (cast shadows, highlights) Huber-style. The directional terms are weakly identified — the camera only
    ever sees normals facing it, and under a turntable the zonal terms (up-down gradients) are constant along each
    texel's path — so the ridge and the uniform start keep them small: the estimate is close to "the exposure-
    scaled observation, corrected by the left-right variation the turntable reveals". (A closed-form solve of the
    albedo-free pair equations I_f S(n_g) = I_g S(n_f) collapses to shading ~0 on the visible hemisphere; we tried
    it.)

    The albedo is then per texel the median of observed / S(n) over its most camera-facing observations.
    """
    vis = obs.facing > 0  # (F, N)
    A = torch.tensor(np.array(sh.A_HAT), dtype=torch.float32) / math.pi
    Y = sh.basis(obs.normal) * A  # (F, N, 9): shading = Y @ L
    I = obs.colour  # (F, N, 3)
    w = vis.float()[..., None].expand_as(I).clone()
    L = torch.zeros(9, 3)
    L[0] = EXPOSURE_L0
    eye = torch.eye(8)
    for it in range(iters):
        S = Y @ L  # (F, N, 3)
        a = ((w * I * S).sum(0) / (w * S * S).sum(0).clamp_min(1e-8)).clamp(0, 1.5)  # (N, 3)
        for c in range(3):
            r = I[..., c] - a[None, :, c] * Y[..., 0] * L[0, c]  # what the DC term leaves
            X = a[None, :, c, None] * Y[..., 1:]  # (F, N, 8)
            XtX = torch.einsum("fnk,fn,fnl->kl", X, w[..., c], X)
            Xtr = torch.einsum("fnk,fn,fn->k", X, w[..., c], r)
            L[1:, c] = torch.linalg.solve(XtX + ridge * XtX.diagonal().mean().clamp_min(1e-12) * eye, Xtr)
        if it >= iters - 5:
            res = (I - a[None] * (Y @ L)).abs()
            scale = 1.4826 * res[vis].median().clamp_min(1e-4)
            w = vis.float()[..., None] * torch.clamp(2.0 * scale / res.clamp_min(1e-8), max=1.0)
    S = (Y @ L).clamp_min(min_shading)
    use = _most_facing(obs, cfg.facing_quantile)
    ratio = torch.where(use[..., None], I / S, torch.full_like(I, float("nan")))
    med = torch.nanmedian(ratio, dim=0).values
    tex, valid = _to_texture(obs, med, use.any(0))
    return tex, valid, L


def fill_holes(tex: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Push-pull fill: every invalid texel takes the (weighted) mean of the nearest valid ones at the coarsest
    pyramid level that has any. (C, S, S), (S, S) → (C, S, S)."""
    w = valid.to(tex.dtype)[None, None]
    x = (tex * valid)[None]
    levels = []
    while x.shape[-1] > 1:
        levels.append((x, w))
        x = F.avg_pool2d(x, 2, ceil_mode=True)
        w = F.avg_pool2d(w, 2, ceil_mode=True)
    filled = x / w.clamp_min(1e-8)
    for x, w in reversed(levels):
        up = F.interpolate(filled, size=x.shape[-2:], mode="bilinear", align_corners=False)
        cur = x / w.clamp_min(1e-8)
        filled = torch.where(w > 0, cur, up)
    return filled[0]


def grey_world_delight(tex: torch.Tensor, valid: torch.Tensor, mean_albedo: float) -> torch.Tensor:
    """The TextureNet-less fallback: scale each channel so the observed texels average `mean_albedo`.

    The most camera-facing observations all see roughly the same shading (the light's value at a normal facing the
    camera), so dividing by one colour per channel removes the light's colour and scale, not its variation.
    """
    m = (tex * valid).sum((1, 2)) / valid.sum().clamp_min(1)
    return (tex * (mean_albedo / m.clamp_min(1e-6))[:, None, None]).clamp(0, 1)
