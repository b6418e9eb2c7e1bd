"""rh_common.sh against closed forms and the conventions of docs/ARCHITECTURE.md."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rh_common import sh

RNG_SEED = 1234


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _k2(t: np.ndarray) -> np.ndarray:
    # Order-2 truncation of the clamped cosine: Σ_{l≤2} (2l+1)/(4π) Â_l P_l(t).
    return 0.25 + 0.5 * t + (5.0 / 32.0) * (3.0 * t * t - 1.0)


# ------------------------------------------------------------------------------------------------ basis
def test_basis_matches_architecture_table_no_condon_shortley() -> None:
    d = np.array([0.48, -0.6, 0.64])  # unit: 0.2304 + 0.36 + 0.4096
    x, y, z = d
    table = [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
             0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)]
    np.testing.assert_allclose(sh.basis(d), table, atol=2e-6)  # the table rounds to 6 digits
    # No Condon-Shortley phase: the odd-m terms are positive along +y, +x, +yz, +xz.
    assert sh.basis(np.array([0.0, 1.0, 0.0]))[1] > 0
    assert sh.basis(np.array([1.0, 0.0, 0.0]))[3] > 0
    s = math.sqrt(0.5)
    assert sh.basis(np.array([0.0, s, s]))[5] > 0 and sh.basis(np.array([s, 0.0, s]))[7] > 0


def test_basis_dtype_and_shape() -> None:
    d = _unit(np.random.default_rng(RNG_SEED), 12).reshape(3, 4, 3)
    assert sh.basis(d).shape == (3, 4, 9) and sh.basis(d).dtype == np.float64
    b32 = sh.basis(d.astype(np.float32))
    assert b32.dtype == np.float32
    np.testing.assert_allclose(b32, sh.basis(d), atol=1e-6)


def test_orthonormal_under_quadrature() -> None:
    H = 64
    B = sh.basis(sh.equirect_directions(H, 2 * H)).reshape(-1, 9)
    om = sh.pixel_solid_angles(H, 2 * H).reshape(-1)
    G = B.T @ (B * om[:, None])
    # Pixel-centre (midpoint) quadrature of smooth products: error O(h²), h = π/H (measured (1/6)·h²).
    assert np.abs(G - np.eye(9)).max() < 0.2 * (math.pi / H) ** 2
    # Exact-cell projection of the point-sampled basis: a cell mean differs from the centre value by
    # (h²/24)(f_θθ + f_φφ), and band-2 functions have second derivatives up to ~l(l+1) = 6 times their size
    # → below 0.3·h² (measured 0.23·h²).
    B = sh.basis(sh.equirect_directions(H, 2 * H))
    P = np.stack([sh.project_equirect(B[..., k])[:, 0] for k in range(9)])
    assert np.abs(P - np.eye(9)).max() < 0.3 * (math.pi / H) ** 2


# ------------------------------------------------------------------------------------------------ mapping
def test_equirect_directions_follow_architecture_mapping() -> None:
    H, W = 8, 16
    d = sh.equirect_directions(H, W)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    u = np.mod(0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2 * math.pi), 1.0) * W
    v = np.arccos(d[..., 2]) / math.pi * H
    np.testing.assert_allclose(u, np.broadcast_to(np.arange(W)[None, :] + 0.5, (H, W)), atol=1e-9)
    np.testing.assert_allclose(v, np.broadcast_to(np.arange(H)[:, None] + 0.5, (H, W)), atol=1e-9)
    assert d[0, 0, 2] > 0.9  # top row = +Z
    # +X lies on the boundary between columns W/2-1 and W/2, +Y at u = W/4, -Y at u = 3W/4.
    assert d[H // 2, W // 2, 0] > 0.9 and d[H // 2, W // 2 - 1, 0] > 0.9
    assert d[H // 2, W // 4, 1] > 0.9 and d[H // 2, 3 * W // 4, 1] < -0.9


def test_pixel_solid_angles_sum_to_sphere() -> None:
    om = sh.pixel_solid_angles(7, 13)
    assert om.shape == (7, 13)
    np.testing.assert_allclose(om.sum(), 4 * math.pi, rtol=1e-14)
    np.testing.assert_allclose(om[0, 0], (2 * math.pi / 13) * (1 - math.cos(math.pi / 7)), rtol=1e-14)


# ------------------------------------------------------------------------------------------------ projection
@pytest.mark.parametrize("H", [4, 32, 512])
def test_constant_map_projects_exactly(H: int) -> None:
    L = np.array([1.0, 2.5, 0.3])
    c = sh.project_equirect(np.broadcast_to(L, (H, 2 * H, 3)))
    np.testing.assert_allclose(c[0], 2 * math.sqrt(math.pi) * L, atol=1e-6)  # 0.282095 · 4π · L
    assert np.abs(c[1:]).max() < 1e-9
    n = _unit(np.random.default_rng(RNG_SEED), 50)
    np.testing.assert_allclose(sh.irradiance(c, n), np.broadcast_to(math.pi * L, (50, 3)), atol=1e-6)
    np.testing.assert_allclose(sh.shading(c, n), np.broadcast_to(L, (50, 3)), atol=1e-6)


def test_projection_of_low_order_lighting_is_exact_to_discretisation() -> None:
    # L(ω) = Σ_k a_k Y_k(ω) sampled at pixel centres → coefficients a (up to O(h²)).
    rng = np.random.default_rng(RNG_SEED)
    a = rng.normal(size=(9, 3))
    H = 128
    L = sh.basis(sh.equirect_directions(H, 2 * H)) @ a
    np.testing.assert_allclose(sh.project_equirect(L), a, atol=0.3 * (math.pi / H) ** 2 * np.abs(a).sum(0).max())


def test_project_rejects_bad_input() -> None:
    with pytest.raises(ValueError):
        sh.project_equirect(np.zeros((4, 8, 3, 1)))
    bad = np.zeros((4, 8, 3))
    bad[1, 1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sh.project_equirect(bad)


# ------------------------------------------------------------------------------------------------ irradiance
def test_directional_light_irradiance_closed_form() -> None:
    # A delta light of power Φ from d has coefficients Φ·Y(d); its order-2 irradiance is Φ·K₂(n·d).
    rng = np.random.default_rng(RNG_SEED)
    d = _unit(rng, 1)[0]
    phi = np.array([2.0, 1.0, 0.5])
    c = sh.basis(d)[:, None] * phi[None, :]
    n = np.concatenate([_unit(rng, 200), d[None], -d[None]])
    t = n @ d
    np.testing.assert_allclose(sh.irradiance(c, n), _k2(t)[:, None] * phi, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sh.irradiance(c, d[None])[0], 1.0625 * phi, rtol=1e-12)  # K₂(1) = 17/16


def test_single_pixel_light_matches_closed_form() -> None:
    H, W = 256, 512
    j, i = 70, 300
    img = np.zeros((H, W, 3))
    om = sh.pixel_solid_angles(H, W)[j, i]
    img[j, i] = 1.0 / om  # power 1 in one pixel
    d = sh.equirect_directions(H, W)[j, i]
    n = _unit(np.random.default_rng(RNG_SEED), 100)
    E = sh.irradiance(sh.project_equirect(img), n)[:, 0]
    # The pixel's finite extent (h = π/256) smears the delta: O(h²) ≈ 1.5e-4 relative to the power.
    np.testing.assert_allclose(E, _k2(n @ d), atol=3e-4)


# ------------------------------------------------------------------------------------------------ rotation
def test_rotation_matrices_orthogonal_block_diagonal_and_compose() -> None:
    rng = np.random.default_rng(RNG_SEED)
    R1, R2 = _random_rotation(rng), _random_rotation(rng)
    M1, M2 = sh.rotation_matrix(R1), sh.rotation_matrix(R2)
    for M in (M1, M2):
        np.testing.assert_allclose(M @ M.T, np.eye(9), atol=1e-12)
        mask = np.zeros((9, 9), bool)
        for b in (slice(0, 1), slice(1, 4), slice(4, 9)):
            mask[b, b] = True
        assert np.abs(M[~mask]).max() < 1e-12
    np.testing.assert_allclose(sh.rotation_matrix(R1 @ R2), M1 @ M2, atol=1e-12)
    np.testing.assert_allclose(sh.rotation_matrix(np.eye(3)), np.eye(9), atol=1e-12)
    np.testing.assert_allclose(sh.rotation_matrix(R1.T), M1.T, atol=1e-12)
    # Definition: Y(R ω) = M Y(ω); band 1 is R itself in (y, z, x) order.
    w = _unit(rng, 30)
    np.testing.assert_allclose(sh.basis(w @ R1.T), sh.basis(w) @ M1.T, atol=1e-12)
    P = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]])
    np.testing.assert_allclose(M1[1:4, 1:4], P @ R1 @ P.T, atol=1e-12)


def test_rotation_matrix_rejects_non_rotations() -> None:
    with pytest.raises(ValueError):
        sh.rotation_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError):
        sh.rotation_matrix(2 * np.eye(3))


def _lobes(dirs: np.ndarray) -> np.ndarray:
    # A smooth but strongly non-uniform coloured environment (three lobes of different sharpness).
    centres = np.array([[0.3, -0.5, 0.81], [-0.7, 0.1, -0.2], [0.1, 0.9, 0.1]])
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    sharp = np.array([8.0, 3.0, 20.0])
    colours = np.array([[1.0, 0.8, 0.6], [0.2, 0.3, 1.0], [2.0, 1.0, 0.1]])
    w = np.exp(sharp * (dirs @ centres.T - 1.0))
    return w @ colours


def test_rotating_the_map_equals_rotating_the_coefficients() -> None:
    rng = np.random.default_rng(RNG_SEED)
    H = 128
    dirs = sh.equirect_directions(H, 2 * H)
    base = _lobes(dirs)
    c = sh.project_equirect(base)
    # About +Z by a whole number of pixels: an exact column roll (ARCHITECTURE: positive = counter-clockwise).
    shift = 32  # 45° at W = 256
    Rz = np.array([[math.cos(math.pi / 4), -math.sin(math.pi / 4), 0], [math.sin(math.pi / 4),
                   math.cos(math.pi / 4), 0], [0, 0, 1]])
    np.testing.assert_allclose(sh.project_equirect(np.roll(base, -shift, axis=1)), sh.rotate(c, Rz), atol=1e-12)
    # Arbitrary R: sample the rotated environment L(Rᵀω) directly; agreement up to discretisation, O(h²).
    R = _random_rotation(rng)
    rotated = _lobes(dirs @ R)  # row-vector form of Rᵀω
    tol = 0.2 * (math.pi / H) ** 2 * np.abs(c).max() * 9
    np.testing.assert_allclose(sh.project_equirect(rotated), sh.rotate(c, R), atol=tol)


# ------------------------------------------------------------------------------------------------ torch
def test_torch_inputs_are_supported_and_differentiable() -> None:
    import torch
    rng = np.random.default_rng(RNG_SEED)
    n = _unit(rng, 20)
    c = rng.normal(size=(9, 3))
    R = _random_rotation(rng)
    nt = torch.tensor(n, dtype=torch.float32, requires_grad=True)
    ct = torch.tensor(c, dtype=torch.float32, requires_grad=True)
    b = sh.basis(nt)
    assert isinstance(b, torch.Tensor) and b.dtype == torch.float32 and b.shape == (20, 9)
    np.testing.assert_allclose(b.detach().numpy(), sh.basis(n), atol=1e-6)
    s = sh.shading(ct, nt)
    assert isinstance(s, torch.Tensor) and s.shape == (20, 3)
    np.testing.assert_allclose(s.detach().numpy(), sh.shading(c, n), rtol=1e-5, atol=1e-5)
    s.sum().backward()
    assert nt.grad is not None and ct.grad is not None and torch.isfinite(nt.grad).all()
    # Mixed inputs: numpy coefficients with torch normals → torch.
    assert isinstance(sh.irradiance(c, nt.detach()), torch.Tensor)
    r = sh.rotate(torch.tensor(c), R)
    np.testing.assert_allclose(r.numpy(), sh.rotate(c, R), atol=1e-12)
