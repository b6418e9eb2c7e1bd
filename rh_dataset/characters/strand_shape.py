"""Hair strands as a Mitsuba 3 shape: one `bsplinecurve` per set of strands of one fibre.

In: posed strands (`points` (S, K, 3) control points, `radius` (S, K), `fibre` with melanin, roughnesses and
`albedo`). Out: a loaded Mitsuba shape with the `hair` BSDF (Chiang et al. 2016, melanin-parameterised) whose
diffuse reflectance, what the `aov` integrator reads as albedo, is the fibre's albedo (Mitsuba's `hair` alone gives
~0 there; ARCHITECTURE.md "Hair"), or with a plain `diffuse` stand-in of that albedo (`stand_in=True`, the preview).
One scene then serves both passes of a frame. Used by the dataset renderer (`render.scene`) and the preview.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..variant import jit_array, load_mitsuba, require_variant

__all__ = ["mitsuba_curves", "HAIR_WITH_ALBEDO"]

HAIR_WITH_ALBEDO = "rh_hair_with_albedo"
"""The Mitsuba plugin name of the `hair` BSDF whose diffuse reflectance is a given albedo (registered on first use)."""
_registered: set[str] = set()


def _register_hair_with_albedo(mi) -> None:
    """Register HAIR_WITH_ALBEDO for the current variant: every scattering query goes to the nested `hair` BSDF
    (the beauty pass traces exactly Mitsuba's hair), only `eval_diffuse_reflectance` answers the albedo."""
    if mi.variant() in _registered:
        return

    class HairWithAlbedo(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.hair = props["hair"]
            self.albedo = mi.Color3f(props["albedo"])
            self.m_flags = self.hair.flags()
            self.m_components = [self.hair.flags(i) for i in range(self.hair.component_count())]

        def sample(self, ctx, si, sample1, sample2, active=True):
            return self.hair.sample(ctx, si, sample1, sample2, active)

        def eval(self, ctx, si, wo, active=True):
            return self.hair.eval(ctx, si, wo, active)

        def pdf(self, ctx, si, wo, active=True):
            return self.hair.pdf(ctx, si, wo, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.hair.eval_pdf(ctx, si, wo, active)

        def eval_diffuse_reflectance(self, si, active=True):
            return mi.Color3f(self.albedo)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"HairWithAlbedo[albedo={self.albedo}, hair={self.hair}]"

    mi.register_bsdf(HAIR_WITH_ALBEDO, lambda props: HairWithAlbedo(props))
    _registered.add(mi.variant())

# Mitsuba 3.9's curve shapes load only from a file: each shape is loaded from a 4-point strand written to a temporary
# directory (removed at once), then filled from arrays through mi.traverse (control_points, segment_indices).
_TEMPLATE = "0 0 0 0.001\n0 0 1 0.001\n0 0 2 0.001\n0 0 3 0.001\n"


def mitsuba_curves(strands, stand_in: bool = False) -> Any:
    """A `bsplinecurve` shape: each strand's control points with its first and last repeated twice more, so the
    uniform cubic B-spline starts at the root and ends at the tip. `stand_in`: a diffuse BSDF of the fibre's albedo
    instead of the hair BSDF."""
    mi = load_mitsuba()
    require_variant()
    P = np.asarray(strands.points, dtype=np.float32)
    R = np.asarray(strands.radius, dtype=np.float32)
    if P.ndim != 3 or P.shape[2] != 3 or R.shape != P.shape[:2] or P.shape[1] < 2:
        raise ValueError(f"strands {strands.name}: points must be (S, K, 3), radius (S, K); got {P.shape} {R.shape}")
    if not (np.all(np.isfinite(P)) and np.all(R > 0)):
        raise ValueError(f"strands {strands.name}: non-finite control points or non-positive radii")
    f = strands.fibre
    if stand_in:
        bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(x) for x in f.albedo]}}
    else:
        _register_hair_with_albedo(mi)
        hair = {"type": "hair", "eumelanin": float(f.eumelanin), "pheomelanin": float(f.pheomelanin),
                "longitudinal_roughness": float(f.longitudinal_roughness),
                "azimuthal_roughness": float(f.azimuthal_roughness)}
        bsdf = {"type": HAIR_WITH_ALBEDO, "hair": hair, "albedo": [float(x) for x in f.albedo]}
    S, K = R.shape
    P = np.concatenate([P[:, :1], P[:, :1], P, P[:, -1:], P[:, -1:]], 1)
    R = np.concatenate([R[:, :1], R[:, :1], R, R[:, -1:], R[:, -1:]], 1)
    k = K + 4
    cp = np.concatenate([P, R[..., None]], -1).reshape(-1)
    seg = (np.arange(S, dtype=np.uint32)[:, None] * k + np.arange(k - 3, dtype=np.uint32)[None, :]).ravel()
    with tempfile.TemporaryDirectory(prefix="rh_curves_") as tmp:
        (Path(tmp) / "strand.txt").write_text(_TEMPLATE)
        shape = mi.load_dict({"type": "bsplinecurve", "filename": str(Path(tmp) / "strand.txt"), "bsdf": bsdf})
    params = mi.traverse(shape)
    params["control_points"] = jit_array(mi.Float, cp)  # aligned: the same kernel every frame
    params["segment_indices"] = jit_array(mi.UInt32, seg)
    params["control_point_count"] = int(S * k)
    params.update()
    return shape
