"""Drawing a frame's light: a seeded generator (and the map library) in, a `LightSpec` out.

Two modes: the original uniform choice among the library's maps (and optionally 'sunsky'), which protocols a and
b use, and a weighted mixture of real maps, sunsky and procedural kinds (a protocol's `lights.mixture`,
docs/ARCHITECTURE.md "Light mixtures"). Building the light from the spec is `light.build_light`.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .library import load_hdri, normalised_scale
from .light import SUNSKY_ELEVATION_RANGE_DEG, SUNSKY_TURBIDITY_RANGE, LightSpec, _is_real
from .procedural import PROCEDURAL_KINDS, procedural_map, sample_params
from .sunsky import bake_sunsky

__all__ = ["MIXTURE_KEYS", "check_mixture", "sample_light"]

MIXTURE_KEYS = ("real", "sunsky", *PROCEDURAL_KINDS)


def check_mixture(mixture: Mapping[str, float]) -> dict[str, float]:
    """The mixture's weights normalised to sum 1, keys in MIXTURE_KEYS order; ValueError naming the bad entry."""
    if not isinstance(mixture, Mapping) or not mixture:
        raise ValueError(f"light mixture must be a non-empty object of kind -> weight, got {mixture!r}")
    for k, w in mixture.items():
        if k not in MIXTURE_KEYS:
            raise ValueError(f"light mixture: unknown kind {k!r}; known: {', '.join(MIXTURE_KEYS)}")
        if not (_is_real(w) and w >= 0):
            raise ValueError(f"light mixture: weight of {k!r} must be a finite number >= 0, got {w!r}")
    total = float(sum(mixture.values()))
    if total <= 0:
        raise ValueError(f"light mixture: weights sum to 0, got {dict(mixture)!r}")
    return {k: float(mixture[k]) / total for k in MIXTURE_KEYS if k in mixture}


def _sunsky_spec(rng: np.random.Generator, rotation: float, ev: float) -> LightSpec:
    az = float(rng.uniform(0.0, 360.0))
    el = float(rng.uniform(*SUNSKY_ELEVATION_RANGE_DEG))
    turb = float(rng.uniform(*SUNSKY_TURBIDITY_RANGE))
    base = bake_sunsky(az, el, turb)
    return LightSpec("sunsky", "sunsky", "", rotation, normalised_scale(base) * 2.0**ev, az, el, turb)


def _envmap_spec(library: Mapping[str, object], name: str, rotation: float, ev: float) -> LightSpec:
    source = str(library[name])
    base, _ = load_hdri(source)
    return LightSpec("envmap", name, source, rotation, normalised_scale(base) * 2.0**ev)


def sample_light(
    rng: np.random.Generator,
    library: Mapping[str, object],
    *,
    exposure_ev_range: tuple[float, float] = (-0.5, 0.5),
    allow_sunsky: bool,
    mixture: Mapping[str, float] | None = None,
) -> LightSpec:
    """Draw a light. Rotation is uniform in [0, 360), scale = normalised_scale(map) · 2**ev with ev uniform in
    `exposure_ev_range`.

    Without `mixture`: a map chosen uniformly among the library's maps (plus one 'sunsky' option when allowed);
    draw order choice, rotation, ev, then sun parameters (azimuth uniform in [0, 360), elevation in
    SUNSKY_ELEVATION_RANGE_DEG, turbidity in SUNSKY_TURBIDITY_RANGE).
    With `mixture` (kind -> weight, MIXTURE_KEYS: 'real' = a library map chosen uniformly, 'sunsky', or a
    procedural kind): draw order one uniform number choosing the kind by the normalised weights, rotation, ev,
    then the kind's own draws (the map index, the sun, `procedural.sample_params`). `allow_sunsky` must then be
    False (the mixture says whether sunsky is in). A seed reproduces the spec either way.
    """
    lo, hi = exposure_ev_range
    if not (_is_real(lo) and _is_real(hi) and lo <= hi):
        raise ValueError(f"sample_light: exposure_ev_range must be (low, high) finite, got {exposure_ev_range!r}")
    names = sorted(library)
    if mixture is not None:
        return _sample_mixture(rng, library, names, check_mixture(mixture), (lo, hi), allow_sunsky)
    n_options = len(names) + (1 if allow_sunsky else 0)
    if n_options == 0:
        raise ValueError("sample_light: empty HDRI library and allow_sunsky=False; nothing to sample")
    k = int(rng.integers(n_options))
    rotation = float(rng.uniform(0.0, 360.0))
    ev = float(rng.uniform(lo, hi))
    if k < len(names):
        return _envmap_spec(library, names[k], rotation, ev)
    return _sunsky_spec(rng, rotation, ev)


def _sample_mixture(rng: np.random.Generator, library: Mapping[str, object], names: list[str],
                    weights: dict[str, float], ev_range: tuple[float, float], allow_sunsky: bool) -> LightSpec:
    if allow_sunsky:
        raise ValueError("sample_light: give sunsky a weight in the mixture instead of allow_sunsky=True")
    if weights.get("real", 0.0) > 0 and not names:
        raise ValueError("sample_light: the mixture draws 'real' maps but the HDRI library is empty")
    u = float(rng.random())
    kinds = [k for k in weights if weights[k] > 0.0]
    cum = np.cumsum([weights[k] for k in kinds])
    kind = kinds[min(int(np.searchsorted(cum, u, side="right")), len(kinds) - 1)]  # cum[-1] may round below 1
    rotation = float(rng.uniform(0.0, 360.0))
    ev = float(rng.uniform(*ev_range))
    if kind == "real":
        return _envmap_spec(library, names[int(rng.integers(len(names)))], rotation, ev)
    if kind == "sunsky":
        return _sunsky_spec(rng, rotation, ev)
    params = sample_params(kind, rng)
    base = procedural_map(kind, params)
    return LightSpec(kind, kind, "", rotation, normalised_scale(base) * 2.0**ev, params=params)  # type: ignore[arg-type]
