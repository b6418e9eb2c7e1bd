"""Coarse albedo texture (paper Sec. 3.2): back-project training pixels to anny's UV space, keep per texel the
median of its most camera-facing observations, then TextureNet turns that shaded, holey map into an albedo map.

UV convention: anny's per-corner texture coordinates, v up (OBJ). A texture array's row 0 is v = 1, column 0 is
u = 0; texel (i, j) has its centre at u = (j + 0.5)/S, v = 1 − (i + 0.5)/S. `uv_to_grid` maps UVs to
`grid_sample` coordinates (align_corners=False) under exactly this convention; everything samples through it.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from .body import BodyTopology, vertex_normals
from .config import TextureConfig
from .data import FrameData
from .raster import Raster, interpolate, project, rasterize

__all__ = ["UVRaster", "uv_raster", "uv_to_grid", "sample_texture", "extract_texture", "fill_holes",
           "grey_world_delight", "uv_coordinate_image"]


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


@torch.no_grad()
def extract_texture(frames: list[FrameData], topo: BodyTopology, offsets: torch.Tensor | None, cfg: TextureConfig,
                    layer: str = "image", depth_tol: float = 0.03) -> tuple[torch.Tensor, torch.Tensor]:
    """Median texture (3, S, S) and its validity (S, S) from the frames' `layer` ('image' or 'albedo').

    A texel is observed in a frame when its surface point projects inside the person mask and passes a depth test
    against the frame's z-buffer of the same mesh. Among its observations, those whose facing (cosine between
    normal and direction to the camera) is at least `facing_quantile` x the best one are its 'most orthogonal'
    ones; the texel's colour is their per-channel median.
    """
    uvr = uv_raster(cfg.size)
    S = cfg.size
    cols, facings = [], []
    sel = None
    for fr in frames:
        img = getattr(fr, layer)
        if img is None:
            raise ValueError(f"{fr.path}: frame has no {layer} layer loaded")
        verts = fr.body.vertices(offsets)
        normals = vertex_normals(verts, topo.faces)
        sel, p, n = _texel_points(uvr, topo, verts, normals)
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
    fac = torch.stack(facings)  # (F, N)
    col = torch.stack(cols)  # (F, N, 3)
    best = fac.max(0).values
    use = (fac > 0) & (fac >= cfg.facing_quantile * best[None])
    vals = torch.where(use[..., None], col, torch.full_like(col, float("nan")))
    med = torch.nanmedian(vals, dim=0).values  # (N, 3)
    ok = use.any(0)
    tex = torch.zeros(S * S, 3)
    valid = torch.zeros(S * S, dtype=torch.bool)
    idx = torch.nonzero(sel)[:, 0]
    tex[idx[ok]] = med[ok]
    valid[idx[ok]] = True
    return tex.view(S, S, 3).permute(2, 0, 1).contiguous(), valid.view(S, S)


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
