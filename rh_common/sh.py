"""The one order-2 real spherical-harmonics module (9 coefficients per colour channel).

Conventions (docs/ARCHITECTURE.md, "Spherical harmonics" and "Environment lights"):

* Basis: real SH **without the Condon–Shortley phase**, index order
  ``0:(0,0) 1:(1,-1)~y 2:(1,0)~z 3:(1,1)~x 4:(2,-2)~xy 5:(2,-1)~yz 6:(2,0)~3z²-1 7:(2,1)~xz 8:(2,2)~x²-y²``.
  The constants are the exact values (1/(2√π), √(3/4π), √(15/4π), √(5/16π), √(15/16π)); the table in
  ARCHITECTURE.md shows them rounded to 6 digits.
* Coefficients are of **radiance**: ``L_i = ∫ L(ω) Y_i(ω) dω``, shape (9, C) (C = 3 for RGB).
* Irradiance ``E(n) = Σ_i Â_l(i) L_i Y_i(n)`` with ``Â = (π, 2π/3, π/4)``; a constant radiance L gives E = πL.
  **Shading** ``S = E / π`` (so a Lambertian albedo a reflects a·S). Both are returned raw: order-2 ringing can make
  them negative; callers that need a physical value clamp and say so.
* Equirectangular mapping: world direction ``d = (x, y, z)`` (+Z up) ↔ ``φ = atan2(y, x)``, ``θ = arccos z``,
  column ``u = (0.5 − φ/2π)·W`` (wrapped), row ``v = θ/π·H``; pixel (row j, column i) covers
  ``[i, i+1) x [j, j+1)`` in (u, v) and its centre is at ``(i + 0.5, j + 0.5)``.
* Rotations: "rotating the environment by R" means ``L'(ω) = L(Rᵀω)`` (a light arriving from direction d now
  arrives from R·d). Its coefficients are ``M(R) @ c``. The same matrix re-expresses coefficients in another frame
  whose coordinates are ``ω' = R ω`` (e.g. world → OpenGL camera: pass that camera's 3x3 world-to-camera rotation).

`basis`, `irradiance`, `shading` and `rotate` accept numpy arrays (computed in float64, returned as float32 when
the input was float32, else float64) or torch tensors (computed in the tensor's dtype/device, differentiable).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "SH_CONSTANTS",
    "A_HAT",
    "N_COEFFS",
    "basis",
    "project_equirect",
    "irradiance",
    "shading",
    "rotation_matrix",
    "rotate",
    "equirect_directions",
    "pixel_solid_angles",
    "fibonacci_sphere",
]

N_COEFFS = 9

# Exact normalisation constants (the ARCHITECTURE.md table rounds them to 6 digits).
_K0 = 0.5 / math.sqrt(math.pi)  # 0.282095
_K1 = math.sqrt(3.0 / (4.0 * math.pi))  # 0.488603
_K2 = math.sqrt(15.0 / (4.0 * math.pi))  # 1.092548
_K3 = math.sqrt(5.0 / (16.0 * math.pi))  # 0.315392
_K4 = math.sqrt(15.0 / (16.0 * math.pi))  # 0.546274
SH_CONSTANTS: tuple[float, float, float, float, float] = (_K0, _K1, _K2, _K3, _K4)

# Lambertian (clamped-cosine) convolution factors per coefficient index (bands 0, 1, 2).
_A_BAND = (math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0)
A_HAT: np.ndarray = np.array([_A_BAND[0]] + [_A_BAND[1]] * 3 + [_A_BAND[2]] * 5, dtype=np.float64)
A_HAT.setflags(write=False)

_BANDS = (slice(0, 1), slice(1, 4), slice(4, 9))


# --------------------------------------------------------------------------------------------------- dispatch
def _is_torch(a: Any) -> bool:
    # No torch import at module load: numpy-only users (the generator) should not pay for it.
    return type(a).__module__.split(".")[0] == "torch"


def _out_dtype(*arrays: Any) -> type:
    return np.float32 if all(getattr(a, "dtype", None) == np.float32 for a in arrays) else np.float64


# --------------------------------------------------------------------------------------------------- basis
def basis(dirs: Any) -> Any:
    """The 9 basis functions at unit directions ``dirs`` (..., 3) → (..., 9), in ARCHITECTURE.md's order.

    Directions are not renormalised (the caller owns that; a zero vector gives only the constant term).
    numpy in → numpy out (float32 if the input was float32, else float64; computed in float64);
    torch in → torch out (same dtype and device, differentiable).
    """
    if _is_torch(dirs):
        import torch

        x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
        return torch.stack(_basis_terms(x, y, z, torch.ones_like(x)), dim=-1)
    arr = np.asarray(dirs)
    if arr.shape[-1:] != (3,):
        raise ValueError(f"basis: expected (..., 3) directions, got shape {arr.shape}")
    d = arr.astype(np.float64, copy=False)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack(_basis_terms(x, y, z, np.ones_like(x)), axis=-1).astype(_out_dtype(arr), copy=False)


def _basis_terms(x: Any, y: Any, z: Any, one: Any) -> list:
    # Only elementwise arithmetic, so the same code serves numpy and torch.
    return [
        _K0 * one,
        _K1 * y,
        _K1 * z,
        _K1 * x,
        _K2 * x * y,
        _K2 * y * z,
        _K3 * (3.0 * z * z - 1.0),
        _K2 * x * z,
        _K4 * (x * x - y * y),
    ]


# --------------------------------------------------------------------------------------------------- equirect
def _row_edges(H: int) -> np.ndarray:
    return np.arange(H + 1, dtype=np.float64) * (math.pi / H)


def _col_edges_phi(W: int) -> np.ndarray:
    # Column i spans u in [i, i+1), i.e. φ from π − 2πi/W (left edge) down to π − 2π(i+1)/W.
    return math.pi - np.arange(W + 1, dtype=np.float64) * (2.0 * math.pi / W)


def equirect_directions(H: int, W: int) -> np.ndarray:
    """Unit world directions (H, W, 3) float64 of the pixel centres of an H x W equirectangular map.

    Pixel (row j, column i) centre: ``θ = (j + 0.5)π/H``, ``φ = π − 2π(i + 0.5)/W``;
    ``d = (sinθ cosφ, sinθ sinφ, cosθ)``. Row 0 is next to +Z; column W/2 (its left edge) faces +X.
    """
    _check_hw(H, W)
    theta = (np.arange(H, dtype=np.float64) + 0.5) * (math.pi / H)
    phi = math.pi - (np.arange(W, dtype=np.float64) + 0.5) * (2.0 * math.pi / W)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return np.stack(
        [st * np.cos(phi)[None, :], st * np.sin(phi)[None, :], np.broadcast_to(ct, (H, W))], axis=-1
    )


def pixel_solid_angles(H: int, W: int) -> np.ndarray:
    """Exact solid angle (H, W) float64 of each pixel: ``(2π/W)(cos θ0 − cos θ1)`` for its row; sums to 4π."""
    _check_hw(H, W)
    c = np.cos(_row_edges(H))
    per_row = (2.0 * math.pi / W) * (c[:-1] - c[1:])
    return np.broadcast_to(per_row[:, None], (H, W)).copy()


def _check_hw(H: int, W: int) -> None:
    if not (int(H) == H and int(W) == W and H >= 1 and W >= 1):
        raise ValueError(f"equirect size must be positive integers, got H={H!r}, W={W!r}")


def _cell_integrals(H: int, W: int) -> tuple[np.ndarray, np.ndarray]:
    """Separable closed-form integrals of each basis function over each pixel cell.

    Returns ``T`` (H, 9) and ``P`` (W, 9) with ``∫_cell Y_k dω = T[j, k] · P[i, k]``. Every Y_k is
    (constant) x f(θ) x g(φ); f·sinθ and g have elementary antiderivatives, so the projection of the
    piecewise-constant map is exact. (A pixel-centre quadrature is off by O(1/H²): 1.2e-5 in L_6 of a constant
    512-row map, which would break the exact constant-map identities the tests rely on.)
    """
    th = _row_edges(H)
    t = np.cos(th)
    t0, t1 = t[:-1], t[1:]
    th0, th1 = th[:-1], th[1:]
    s0, s1 = np.sin(th0), np.sin(th1)
    # ∫_{θ0}^{θ1} f(θ) sinθ dθ for the θ-factors that occur.
    f_one = t0 - t1  # f = 1
    f_s = (th1 - th0) / 2.0 - (np.sin(2 * th1) - np.sin(2 * th0)) / 4.0  # f = sinθ
    f_c = (t0 * t0 - t1 * t1) / 2.0  # f = cosθ
    f_ss = (t0 - t1) - (t0**3 - t1**3) / 3.0  # f = sin²θ
    f_sc = (s1**3 - s0**3) / 3.0  # f = sinθ cosθ
    f_z2 = (t0**3 - t1**3) - (t0 - t1)  # f = 3cos²θ − 1
    ph = _col_edges_phi(W)
    pa, pb = ph[:-1], ph[1:]  # pa > pb
    g_one = pa - pb
    g_sin = np.cos(pb) - np.cos(pa)
    g_cos = np.sin(pa) - np.sin(pb)
    g_sincos = (np.cos(2 * pb) - np.cos(2 * pa)) / 4.0  # sinφ cosφ = sin2φ / 2
    g_cos2 = (np.sin(2 * pa) - np.sin(2 * pb)) / 2.0  # cos²φ − sin²φ = cos2φ
    T = np.stack([_K0 * f_one, _K1 * f_s, _K1 * f_c, _K1 * f_s, _K2 * f_ss, _K2 * f_sc, _K3 * f_z2,
                  _K2 * f_sc, _K4 * f_ss], axis=-1)
    P = np.stack([g_one, g_sin, g_one, g_cos, g_sincos, g_sin, g_one, g_cos, g_cos2], axis=-1)
    return T, P


def project_equirect(radiance: np.ndarray) -> np.ndarray:
    """SH coefficients (9, C) float64 of an equirectangular radiance map (H, W, C) or (H, W).

    Each pixel is a cell of constant radiance under ARCHITECTURE.md's mapping; ``∫_cell Y_i dω`` is computed in
    closed form, so the result is the exact projection of that piecewise-constant sphere function (for Y_0 the
    cell weight is the pixel solid angle ``(2π/W)(cos θ0 − cos θ1)``). Non-finite input raises.
    """
    arr = np.asarray(radiance)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3:
        raise ValueError(f"project_equirect: expected (H, W[, C]), got shape {np.shape(radiance)}")
    L = arr.astype(np.float64, copy=False)
    if not np.all(np.isfinite(L)):
        raise ValueError("project_equirect: radiance contains NaN or Inf")
    H, W, _ = L.shape
    T, P = _cell_integrals(H, W)
    per_row = np.einsum("wk,hwc->hkc", P, L, optimize=True)  # azimuthal integrals first: (H, 9, C)
    return np.einsum("hk,hkc->kc", T, per_row, optimize=True)


# --------------------------------------------------------------------------------------------------- irradiance
def irradiance(coeffs: Any, normals: Any) -> Any:
    """Irradiance ``E(n) = Σ Â_l L_i Y_i(n)`` (..., C) from radiance coefficients (9, C) at normals (..., 3).

    Raw order-2 value (may be negative under strongly directional light). torch if either input is torch.
    """
    if _is_torch(coeffs) or _is_torch(normals):
        import torch

        ref = coeffs if _is_torch(coeffs) else normals
        c = torch.as_tensor(coeffs, dtype=ref.dtype, device=ref.device)
        n = torch.as_tensor(normals, dtype=ref.dtype, device=ref.device)
        a = torch.tensor(A_HAT.tolist(), dtype=ref.dtype, device=ref.device)
        _check_coeffs(tuple(c.shape))
        return basis(n) @ (a[:, None] * c)
    c = np.asarray(coeffs)
    _check_coeffs(c.shape)
    n = np.asarray(normals)
    out = basis(n.astype(np.float64, copy=False)) @ (A_HAT[:, None] * c.astype(np.float64, copy=False))
    return out.astype(_out_dtype(c, n), copy=False)


def shading(coeffs: Any, normals: Any) -> Any:
    """Shading ``S = E / π`` (..., C): a Lambertian surface of albedo a has outgoing radiance a · S. Raw value."""
    return irradiance(coeffs, normals) * (1.0 / math.pi)


def _check_coeffs(shape: tuple) -> None:
    if len(shape) != 2 or shape[0] != N_COEFFS:
        raise ValueError(f"expected SH coefficients of shape (9, C), got {shape}")


# --------------------------------------------------------------------------------------------------- rotation
def fibonacci_sphere(n: int) -> np.ndarray:
    """n well-spread unit directions (n, 3) float64 (spherical Fibonacci lattice), deterministic."""
    i = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


# 64 directions: far more than the 5 needed per band, so each band's least-squares system is well conditioned.
_FIT_DIRS = fibonacci_sphere(64)
_FIT_BASIS = basis(_FIT_DIRS)


def rotation_matrix(R: Any) -> np.ndarray:
    """9x9 float64 matrix M with ``Y(R ω) = M Y(ω)``: rotating the environment by R maps coefficients c to M @ c.

    Block-diagonal (bands never mix). Each band's block is solved exactly by least squares from the rotated basis
    at 64 fixed directions (the rotated band-l functions lie in the span of band l, so the fit is exact up to
    round-off, ~1e-15). R must be a proper rotation (orthonormal, det +1).
    """
    Rm = np.asarray(R, dtype=np.float64)
    if Rm.shape != (3, 3) or not np.all(np.isfinite(Rm)):
        raise ValueError(f"rotation_matrix: expected a finite 3x3 rotation, got shape {Rm.shape}")
    if not np.allclose(Rm @ Rm.T, np.eye(3), atol=1e-6) or np.linalg.det(Rm) < 0:
        raise ValueError("rotation_matrix: R is not a proper rotation (orthonormal with det +1)")
    rotated = basis(_FIT_DIRS @ Rm.T)  # row n = Y(R ω_n)
    M = np.zeros((N_COEFFS, N_COEFFS))
    for band in _BANDS:
        # _FIT_BASIS[:, band] @ M_b.T = rotated[:, band]
        Mt, *_ = np.linalg.lstsq(_FIT_BASIS[:, band], rotated[:, band], rcond=None)
        M[band, band] = Mt.T
    return M


def rotate(coeffs: Any, R: Any) -> Any:
    """Coefficients (9, C) of the environment rotated by R (``L'(ω) = L(Rᵀω)``): ``rotation_matrix(R) @ coeffs``.

    numpy → float64 (float32 if coeffs were float32); torch → torch (same dtype/device, differentiable in coeffs).
    """
    M = rotation_matrix(R)
    if _is_torch(coeffs):
        import torch

        _check_coeffs(tuple(coeffs.shape))
        return torch.as_tensor(M, dtype=coeffs.dtype, device=coeffs.device) @ coeffs
    c = np.asarray(coeffs)
    _check_coeffs(c.shape)
    return (M @ c.astype(np.float64, copy=False)).astype(_out_dtype(c), copy=False)
