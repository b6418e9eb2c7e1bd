"""Our rasterisers: exact pixel-centre coverage, perspective-correct barycentrics, the soft silhouette's gradient."""
from __future__ import annotations

import torch

from rana.raster import interpolate, rasterize, soft_silhouette

# A quad from (2.3, 3.1) to (11.6, 9.4) in pixels (y down), two triangles wound as anny's front faces (negative area).
QUAD = torch.tensor([[2.3, 3.1, 2.0], [2.3, 9.4, 2.0], [11.6, 9.4, 2.0], [11.6, 3.1, 2.0]], dtype=torch.float64)
FACES = torch.tensor([[0, 1, 2], [0, 2, 3]])


def _centres_inside(x0, x1, y0, y1, H, W):
    v, u = torch.meshgrid(torch.arange(H) + 0.5, torch.arange(W) + 0.5, indexing="ij")
    return (u >= x0) & (u <= x1) & (v >= y0) & (v <= y1)


def test_hard_coverage_is_the_pixel_centres_inside():
    r = rasterize(QUAD, FACES, 14, 16)
    assert torch.equal(r.mask, _centres_inside(2.3, 11.6, 3.1, 9.4, 14, 16))
    assert torch.allclose(r.depth[r.mask], torch.full_like(r.depth[r.mask], 2.0))


def test_nearest_triangle_wins_and_barycentrics_are_perspective_correct():
    near = QUAD.clone()
    far = QUAD.clone()
    far[:, 2] = 5.0
    verts = torch.cat([far, near])
    faces = torch.cat([FACES, FACES + 4])
    r = rasterize(verts, faces, 14, 16)
    assert (r.tri[r.mask] >= 2).all()  # the near copy
    # Perspective: a triangle tilted in depth; interpolating camera-space z with the barycentrics must give the
    # z-buffer depth (1/z is affine in screen space, z itself is not).
    tilt = torch.tensor([[1.0, 1.0, 1.0], [1.0, 12.0, 4.0], [12.0, 12.0, 2.0]], dtype=torch.float64)
    r2 = rasterize(tilt, torch.tensor([[0, 1, 2]]), 14, 14)
    z = interpolate(r2, torch.tensor([[0, 1, 2]]), tilt[:, 2:3].float())[..., 0]
    assert r2.mask.sum() > 20
    assert torch.allclose(z[r2.mask], r2.depth[r2.mask], rtol=1e-4)


def test_soft_silhouette_is_half_on_the_contour_and_hard_elsewhere():
    s = soft_silhouette(QUAD, FACES, 14, 16, sigma=0.3)
    inside = _centres_inside(2.3, 11.6, 3.1, 9.4, 14, 16)
    assert (s[inside] > 0.5).all() and (s[~inside] < 0.5).all()
    assert s[6, 7] == 1.0 and s[0, 0] == 0.0  # deep inside / far outside: saturated
    edge = QUAD.clone()
    edge[:, 0] += 0.2  # x0 = 2.5: the column-2 pixel centres lie exactly on the left contour edge
    s2 = soft_silhouette(edge, FACES, 14, 16, sigma=0.3)
    assert torch.allclose(s2[5, 2], torch.tensor(0.5, dtype=s2.dtype), atol=1e-3)


def test_soft_silhouette_gradient_matches_finite_differences():
    w = torch.randn(14, 16, dtype=torch.float64, generator=torch.Generator().manual_seed(0))

    def f(v):
        return (soft_silhouette(v, FACES, 14, 16, sigma=0.5) * w).sum()

    x = QUAD.clone().requires_grad_(True)
    f(x).backward()
    eps = 1e-6
    for i in range(4):
        for j in range(2):
            a, b = QUAD.clone(), QUAD.clone()
            a[i, j] += eps
            b[i, j] -= eps
            num = (f(a) - f(b)) / (2 * eps)
            assert torch.allclose(x.grad[i, j], num, rtol=1e-4, atol=1e-6), (i, j, x.grad[i, j], num)
