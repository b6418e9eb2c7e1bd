"""Hair fibres: melanin concentrations for a hair colour, and what "albedo" means for a fibre.

In: a hair colour (sRGB in [0, 1], as recipes hold it). Out: `HairFibre`s - eumelanin / pheomelanin
concentrations and roughnesses, the parameters of Mitsuba 3's `hair` BSDF (the Chiang et al. 2016 fibre model) -
each with the fraction of strands it makes (grey hair is pigmented strands mixed with unpigmented ones).

Absorption: sigma_a = eumelanin * (0.419, 0.697, 1.37) + pheomelanin * (0.187, 0.4, 1.05) per unit of fibre
radius (the coefficients the BSDF uses; linear RGB).

Albedo (the ground truth's `albedo` layer on hair, ARCHITECTURE.md "Hair"): the fibre's *multiple-scattering
colour*, c = exp(-sqrt(sigma_a) * P(beta_n)) per channel with P(b) = 5.969 - 0.215 b + 2.532 b^2 - 10.73 b^3 +
5.574 b^4 + 0.245 b^5 and beta_n the azimuthal roughness - the colour a dense volume of such fibres shows under
uniform light, the mapping Chiang et al. fitted to path-traced hair (their eq. for sigma_a from a colour, inverted).
A single fibre's own directional albedo is not it: the `aov` integrator reads ~0.004 from the `hair` BSDF, and a
fibre's first-bounce reflectance (the ~5 % Fresnel R lobe) says nothing of its colour. Zero melanin gives c = 1.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import nnls

from rh_common.colourspace import srgb_decode

__all__ = ["HairFibre", "EUMELANIN_SIGMA_A", "PHEOMELANIN_SIGMA_A", "fibre_albedo", "sigma_a_for_albedo",
           "fibres_for_colour"]

EUMELANIN_SIGMA_A = np.array([0.419, 0.697, 1.37])
PHEOMELANIN_SIGMA_A = np.array([0.187, 0.4, 1.05])
AZIMUTHAL_ROUGHNESS = 0.3
LONGITUDINAL_ROUGHNESS = 0.25
_WHITE_FRACTIONS = np.round(np.arange(0.0, 0.86, 0.05), 2)


def _p(beta_n: float) -> float:
    b = float(beta_n)
    return 5.969 - 0.215 * b + 2.532 * b ** 2 - 10.73 * b ** 3 + 5.574 * b ** 4 + 0.245 * b ** 5


def fibre_albedo(sigma_a: np.ndarray, beta_n: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """Multiple-scattering colour (linear RGB) of fibres with absorption sigma_a (per unit radius)."""
    return np.exp(-np.sqrt(np.maximum(np.asarray(sigma_a, dtype=np.float64), 0.0)) * _p(beta_n))


def sigma_a_for_albedo(albedo: np.ndarray, beta_n: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """The inverse of `fibre_albedo` (albedo in (0, 1])."""
    a = np.clip(np.asarray(albedo, dtype=np.float64), 1e-6, 1.0)
    return (np.log(a) / _p(beta_n)) ** 2


@dataclasses.dataclass(frozen=True)
class HairFibre:
    """Mitsuba `hair` BSDF parameters; `fraction` of the character's strands that are of this fibre."""

    eumelanin: float
    pheomelanin: float
    fraction: float = 1.0
    longitudinal_roughness: float = LONGITUDINAL_ROUGHNESS
    azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS

    def __post_init__(self) -> None:
        for f in ("eumelanin", "pheomelanin"):
            v = getattr(self, f)
            if not (np.isfinite(v) and 0.0 <= v <= 50.0):
                raise ValueError(f"HairFibre.{f} must be in [0, 50], got {v!r}")
        if not 0.0 < self.fraction <= 1.0:
            raise ValueError(f"HairFibre.fraction must be in (0, 1], got {self.fraction!r}")

    @property
    def sigma_a(self) -> np.ndarray:
        return self.eumelanin * EUMELANIN_SIGMA_A + self.pheomelanin * PHEOMELANIN_SIGMA_A

    @property
    def albedo(self) -> np.ndarray:
        """This fibre's albedo (module docstring), linear RGB float32 (3,)."""
        return fibre_albedo(self.sigma_a, self.azimuthal_roughness).astype(np.float32)


def _fit_melanin(target: np.ndarray) -> tuple[float, float]:
    """Non-negative (eumelanin, pheomelanin) whose sigma_a is closest to `target` (least squares in sqrt space,
    which is linear in log-albedo)."""
    a = np.stack([EUMELANIN_SIGMA_A, PHEOMELANIN_SIGMA_A], 1)
    w = 1.0 / np.sqrt(np.maximum(target, 1e-3))  # relative error: weights ~ 1 / sqrt(sigma)
    x, _ = nnls(a * w[:, None], target * w)
    return float(x[0]), float(x[1])


def fibres_for_colour(colour_srgb) -> tuple[HairFibre, ...]:
    """The fibre mix whose strand-weighted albedo best matches a hair colour: one pigmented fibre, plus unpigmented
    (white) fibres where that matches better (grey hair). Deterministic."""
    c = np.clip(srgb_decode(np.asarray(colour_srgb, dtype=np.float64)), 0.002, 0.98)
    best = None
    for f in _WHITE_FRACTIONS:
        pig = (c - f) / (1.0 - f)
        if pig.min() <= 0.002:
            break
        e, p = _fit_melanin(sigma_a_for_albedo(pig))
        fib = HairFibre(e, p)
        mix = f + (1.0 - f) * fib.albedo.astype(np.float64)
        err = float(np.abs(np.log(mix) - np.log(c)).sum()) + 0.05 * f  # prefer one fibre when nearly as good
        if best is None or err < best[0]:
            best = (err, f, fib)
    _, f, fib = best
    if f == 0.0:
        return (fib,)
    return (dataclasses.replace(fib, fraction=float(1.0 - f)), HairFibre(0.0, 0.0, fraction=float(f)))
