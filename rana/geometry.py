"""Coarse geometry (paper Sec. 3.1): one set of per-vertex offsets D per subject, fitted to the training masks.

    D = argmin  mean_f |S_f(D) - mask_f|  +  w_lap mean_v ||(L D)_v||^2  +  w_off mean_v ||D_v||^2

S_f is the soft silhouette of the posed anny+D mesh (`raster.soft_silhouette`, a soft edge at the contour); pose and shape come from each
frame's metadata, so nothing but D is optimised and no ground-truth geometry is used. The smoothness term is the
Laplacian of the offsets, i.e. it keeps the template's own Laplacian (the usual SMPL+D form): a literal ||L M_f||
would also flatten the naked body's curvature. The small ||D||^2 term keeps unobserved vertices (soles, inner
thighs) on the body instead of drifting.
"""
from __future__ import annotations

import numpy as np
import torch

from .body import BodyTopology, uniform_laplacian
from .config import GeometryConfig
from .data import FrameData
from .raster import project, rasterize, soft_silhouette

__all__ = ["fit_offsets", "silhouette_iou"]


def fit_offsets(frames: list[FrameData], topo: BodyTopology, cfg: GeometryConfig, *, seed: int = 0,
                progress: bool = False, log: list | None = None) -> torch.Tensor:
    """Fit D (V, 3) metres in anny's rest space. Frames need `mask`; they may be at any resolution (masks are
    resampled to `cfg.resolution`)."""
    from .data import resize_image

    rng = np.random.default_rng(seed)
    if 0 < cfg.max_frames < len(frames):
        frames = [frames[i] for i in np.unique(np.round(np.linspace(0, len(frames) - 1, cfg.max_frames)).astype(int))]
    V = topo.n_vertices
    D = torch.zeros(V, 3, requires_grad=True)
    opt = torch.optim.Adam([D], lr=cfg.lr)
    L = uniform_laplacian(V, topo.faces)
    targets = []
    for fr in frames:
        s = cfg.resolution / fr.H
        H, W = cfg.resolution, max(2, int(round(fr.W * s)))
        K = fr.K.clone()
        K[0] *= W / fr.W
        K[1] *= H / fr.H
        targets.append((resize_image(fr.mask[..., None], H, W)[..., 0], K, H, W))
    it = range(cfg.steps)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="fit SMPL+D offsets", unit="step", leave=False)
    for step in it:
        pick = rng.choice(len(frames), size=min(cfg.frames_per_step, len(frames)), replace=False)
        sil = 0.0
        for i in pick:
            mask, K, H, W = targets[i]
            screen = project(frames[i].body.vertices(D), K, frames[i].world_to_camera)
            # |S - mask| summed over pixels, per mask pixel: a relative area error (~1 - IoU), so the weights below
            # do not depend on the resolution or on how much of the frame the person fills.
            err = (soft_silhouette(screen, topo.faces, H, W, sigma=cfg.sigma_px) - mask).abs().sum()
            sil = sil + err / mask.sum().clamp_min(1.0)
        sil = sil / len(pick)
        Dcm = D * 100.0  # regularisers in cm^2 per vertex, so their weights are O(1e-3 .. 1)
        lap = (torch.sparse.mm(L, Dcm) ** 2).sum(1).mean()
        off = (Dcm ** 2).sum(1).mean()
        loss = sil + cfg.laplacian_weight * lap + cfg.offset_weight * off
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if log is not None:
            log.append({"step": step, "silhouette": float(sil.detach()), "laplacian": float(lap.detach()),
                        "offset": float(off.detach())})
        if progress:
            it.set_postfix(sil=f"{float(sil.detach()):.4f}")  # type: ignore[attr-defined]
    return D.detach()


@torch.no_grad()
def silhouette_iou(frames: list[FrameData], topo: BodyTopology, D: torch.Tensor | None) -> float:
    """Mean IoU of the hard raster of anny(+D) with the masks (coverage > 0.5), at the frames' resolution."""
    ious = []
    for fr in frames:
        r = rasterize(project(fr.body.vertices(D), fr.K, fr.world_to_camera), topo.faces, fr.H, fr.W)
        gt = fr.mask > 0.5
        inter = (r.mask & gt).sum().item()
        union = (r.mask | gt).sum().item()
        ious.append(inter / max(union, 1))
    return float(np.mean(ious))
