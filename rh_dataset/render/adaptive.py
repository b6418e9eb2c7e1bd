"""Samples where the noise is, pixel by pixel: the person's pixels get sample counts in proportion to their noise.

In: a loaded Mitsuba scene (the focused beauty pass's, `rh_dataset.render.focus`), the frame's coverage from the AOV
pass, its display exposure, the mean samples per person pixel (`spp`), the counts a pixel may get (`tiers`), the
environment's count (`env_spp`), seeds. Out: (H, W, 3) float32 linear radiance and the number of pixels per tier.

1. Pilot: the whole frame at env_spp through `render_pixels` (the same samples `mi.render` draws there), keeping each
   pixel's second moment. Where no person is, this is the image (as in `render_focused`); on the person it is only
   the pilot: its samples never enter a person pixel's value.
2. Noise in display space, where the benchmark's floor is measured (rh-eval composites sRGB(clip(exposure x)) over
   white with the coverage): per pixel var_i = sum_c (a_i e g'(e m_ic))^2 s_ic^2, a the coverage, g the sRGB curve,
   m and s^2 the pilot's mean and per-sample variance of channel c (the delta method); averaged over a
   SMOOTH_PX x SMOOTH_PX neighbourhood, since env_spp samples estimate a variance poorly.
3. Allocation (Neyman): n_i = lambda sigma_i minimises sum_i var_i / n_i for sum_i n_i fixed; each pixel takes the
   tier nearest lambda sigma_i (in log), clipped to the first and last tier, lambda the largest whose mean count over
   the person is at most `spp` (bisection; a pixel with no measured noise gets the first tier).
4. Each tier's pixels are traced at that tier's count with a seed of their own (one `render_pixels` call per tier,
   so drjit compiles one kernel per tier and count, reused from its disk cache by every later frame).

Unbiased: given the allocation, each person pixel is the mean of its own fresh samples, an unbiased estimate of the
pixel whatever its count; the allocation depends only on the pilot, which is independent of those samples; so the
image is an unbiased estimate of the same image as a full-frame render (tests/test_adaptive.py against a deep full-
frame reference). Deterministic: the pilot's bits repeat (render_pixels), and so do the allocation and the tiers.
Whether it pays is measured, not assumed (bench/bench_sampler.py --floor ...:a<tiers>; docs/TRADEOFFS.md,
"Samples by noise").
"""
from __future__ import annotations

import numpy as np

from .focus import person_pixels, render_pixels

__all__ = ["SMOOTH_PX", "display_noise", "allocate", "render_adaptive", "check_tiers"]

SMOOTH_PX = 3
"""Side of the box the pilot's noise is averaged over: 3 x 3 pixels x env_spp samples per estimate."""


def check_tiers(tiers, spp: int, env_spp: int | None) -> tuple[int, ...]:
    """`tiers` as a tuple, or ValueError naming the rule it breaks."""
    t = tuple(int(x) for x in tiers)
    if len(t) < 2 or any(b <= a for a, b in zip(t, t[1:])) or t[0] < 1 or any(x != y for x, y in zip(t, tiers)):
        raise ValueError(f"render setting adaptive_tiers must be two or more increasing positive integers, "
                         f"got {tiers!r}")
    if not t[0] <= spp <= t[-1]:
        raise ValueError(f"render setting spp={spp} is the mean count over the person with adaptive_tiers {list(t)}: "
                         f"it must lie within [{t[0]}, {t[-1]}]")
    if env_spp is None or env_spp < 2:
        raise ValueError("render setting adaptive_tiers needs env_spp >= 2: the environment pass is the pilot that "
                         f"measures each pixel's noise (a variance needs two samples); got env_spp={env_spp!r}")
    return t


def _srgb_slope(x: np.ndarray) -> np.ndarray:
    """d sRGB(clip(x, 0, 1)) / dx: 12.92 on the linear toe, 1.055/2.4 x^(1/2.4 - 1) above it, 0 where clipped."""
    x = np.asarray(x, dtype=np.float64)
    toe = x <= 0.0031308
    slope = np.where(toe, 12.92, 1.055 / 2.4 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4 - 1.0))
    return np.where(x >= 1.0, 0.0, slope)


def display_noise(mean: np.ndarray, second: np.ndarray, n: int, coverage: np.ndarray, exposure: float) -> np.ndarray:
    """(P,) per-sample variance of each pixel's display-space value as rh-eval composites it, from `n` samples'
    `mean` and `second` moment (P, 3) of linear radiance and the pixel's `coverage` (P,): the delta method."""
    if n < 2:
        raise ValueError(f"display_noise: a variance needs at least 2 samples per pixel, got {n}")
    mean = np.asarray(mean, dtype=np.float64)
    var = np.maximum(np.asarray(second, dtype=np.float64) - mean * mean, 0.0) * (n / (n - 1))
    w = np.asarray(coverage, dtype=np.float64)[:, None] * exposure * _srgb_slope(exposure * mean)
    return np.sum(w * w * var, axis=1)


def allocate(noise: np.ndarray, spp: float, tiers) -> np.ndarray:
    """Index into `tiers` per pixel: counts in proportion to sqrt(noise) (Neyman), each the tier nearest in log,
    their mean at most `spp` and as close to it as the tiers allow."""
    t = np.asarray(tiers, dtype=np.float64)
    sigma = np.sqrt(np.maximum(np.asarray(noise, dtype=np.float64), 0.0))
    if len(sigma) == 0:
        return np.zeros(0, np.int64)
    log_t = np.log(t)
    edges = 0.5 * (log_t[1:] + log_t[:-1])  # a log-count between two tiers goes to the nearer
    noisy = sigma > 0
    log_sigma = np.log(np.where(noisy, sigma, 1.0))

    def tier_of(log_lam: float) -> np.ndarray:
        return np.where(noisy, np.searchsorted(edges, log_lam + log_sigma, side="right"), 0)

    if not noisy.any():
        return np.zeros(len(sigma), np.int64)
    # log lambda from "every noisy pixel at the first tier" to "every noisy pixel at the last": the mean count rises
    # monotonically with lambda, so bisection finds the largest lambda within the budget.
    lo = log_t[0] - log_sigma[noisy].max() - 1.0
    hi = log_t[-1] - log_sigma[noisy].min() + 1.0
    if t[tier_of(hi)].mean() <= spp:
        return tier_of(hi)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if t[tier_of(mid)].mean() > spp:
            hi = mid
        else:
            lo = mid
    return tier_of(lo)


def render_adaptive(mi, scene, coverage: np.ndarray, exposure: float, spp: int, tiers, env_spp: int,
                    seeds: list[int], env_seed: int, margin: int) -> tuple[np.ndarray, dict[int, int]]:
    """The frame: the environment pass at env_spp (seed `env_seed`, also the pilot), the person's pixels (coverage
    grown by `margin`) at the tiers `allocate` gives them, tier k with seed `seeds[k]`. Returns the image and
    {tier count: pixels}."""
    from scipy.ndimage import uniform_filter

    sensor = scene.sensors()[0]
    W, H = (int(v) for v in sensor.film().crop_size())
    everything = np.arange(W * H, dtype=np.uint32)
    mean, second = render_pixels(mi, scene, everything, env_spp, env_seed, moments=True)
    img = mean.astype(np.float32)
    pix = person_pixels(coverage, margin)
    counts = {int(n): 0 for n in tiers}
    if len(pix) == 0:
        return np.ascontiguousarray(img.reshape(H, W, 3)), counts
    cov = np.asarray(coverage, dtype=np.float64).reshape(-1)
    noise = display_noise(mean, second, env_spp, cov, exposure).reshape(H, W)
    noise = uniform_filter(noise, size=SMOOTH_PX, mode="constant", cval=0.0).reshape(-1)
    tier = allocate(noise[pix], spp, tiers)
    for k, n in enumerate(tiers):
        sel = pix[tier == k]
        counts[int(n)] = int(len(sel))
        if len(sel):
            img[sel] = render_pixels(mi, scene, sel, int(n), int(seeds[k]))
    return np.ascontiguousarray(img.reshape(H, W, 3)), counts
