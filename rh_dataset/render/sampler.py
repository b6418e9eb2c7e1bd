"""Mitsuba's sample generators by name, and the sample counts each really takes.

In: a sampler name (one of `SAMPLERS`) and a requested samples-per-pixel. Out: the sensor's `sampler` dict, and
`taken_spp`, the count Mitsuba renders for that request. Several samplers silently round what they are given
(`stratified` to a square, `orthogonal` to a prime squared, `ldsampler` to a power of 4, `multijitter` to a
product of two near factors), so a render asked for n samples would average a different number; `check_spp`
refuses such a request with a one-line error naming the counts nearby that the sampler takes. Which sampler a
preset uses, and why, is measured by bench/bench_sampler.py (docs/TRADEOFFS.md, "Which sampler").
"""
from __future__ import annotations

from functools import lru_cache

from ..variant import load_mitsuba, require_variant

__all__ = ["SAMPLERS", "sampler_dict", "taken_spp", "check_spp"]

SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")


def _check_name(name: str) -> None:
    if name not in SAMPLERS:
        raise ValueError(f"unknown sampler {name!r}; choose one of {', '.join(SAMPLERS)}")


def sampler_dict(name: str, spp: int) -> dict:
    """The Mitsuba `sampler` plugin dict of `name` at `spp` samples per pixel (the count is checked at render)."""
    _check_name(name)
    return {"type": name, "sample_count": int(spp)}


@lru_cache(maxsize=None)
def taken_spp(name: str, spp: int) -> int:
    """How many samples per pixel Mitsuba's `name` sampler renders when asked for `spp` (asked of Mitsuba itself)."""
    _check_name(name)
    mi = load_mitsuba()
    require_variant()
    logger = mi.logger()
    level = logger.log_level()
    logger.set_log_level(mi.LogLevel.Error)  # each rounding sampler warns that it rounds: the caller decides
    try:
        s = mi.load_dict({"type": name, "sample_count": 4})
        s.set_sample_count(int(spp))  # what mi.render(spp=...) calls
        return int(s.sample_count())
    finally:
        logger.set_log_level(level)


def check_spp(name: str, spp: int, what: str = "spp") -> None:
    """Raise ValueError unless the `name` sampler renders exactly `spp` samples per pixel."""
    got = taken_spp(name, int(spp))
    if got != spp:
        near = sorted({taken_spp(name, n) for n in range(max(1, spp // 2), 2 * spp + 1)})
        below = [n for n in near if n < spp][-1:]
        above = [n for n in near if n > spp][:1]
        raise ValueError(f"the {name} sampler renders {got} samples per pixel when asked for {what}={spp}; "
                         f"set {what} to one it takes ({', '.join(map(str, below + above))}) or choose another sampler")
