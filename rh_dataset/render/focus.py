"""Beauty samples where the noise is: the person's pixels at the full sample count, the rest of the frame at few.

In: a loaded Mitsuba scene (its sensor: box filter, its integrator: the beauty pass's path tracer), the frame's
coverage from the AOV pass, the sample counts, a seed. Out: (H, W, 3) float32 linear radiance.

Where no surface covers a pixel, its camera rays leave the scene at once and see only the environment, which varies
little across one pixel's footprint: a few samples converge it. So the whole frame is rendered at `env_spp`, and the
pixels the person covers (coverage > 0 in the AOV pass, grown by `margin` px) are rendered again, at `spp`, and
replace those pixels. Every pixel is then the box-filter average of its own independent, unbiased samples (spp or
env_spp of them), so the image is an unbiased estimate of the same image a full-frame render estimates, whatever
the AOV pass missed: a pixel it wrongly left out only gets the noise of env_spp samples, never a bias
(tests/test_focus.py checks it against a deep full-frame reference).

The person's pixels are traced by `render_pixels`, the same ray generation and sampler seeding as Mitsuba's own
`mi.render` (the same samples; bit-identical on a full pixel list at 4 spp, tested), over a list of pixel indices
instead of a film crop, summing each pixel's samples in a fixed order so that a frame's bits repeat (the film's
scatter-add does not guarantee that once a pixel's samples straddle two of drjit's work blocks):
drjit compiles a kernel per film crop and per wavefront size, so the list is padded (inactive lanes) to one of a few
sizes per octave and the kernels are reused from drjit's disk cache from the second frame on.
"""
from __future__ import annotations

import numpy as np

__all__ = ["person_pixels", "render_pixels", "render_focused", "padded_size"]


def person_pixels(coverage: np.ndarray, margin: int) -> np.ndarray:
    """Flat indices (row-major) of the pixels with coverage > 0, grown by `margin` px (a square neighbourhood)."""
    from scipy.ndimage import maximum_filter

    inside = np.asarray(coverage) > 0.0
    if margin > 0:
        inside = maximum_filter(inside, size=2 * int(margin) + 1, mode="constant", cval=False)
    return np.flatnonzero(inside).astype(np.uint32)


def padded_size(n: int) -> int:
    """The smallest of 2^k * {1, 1.25, 1.5, 1.75} (k >= 10) that is >= n: a few wavefront sizes per octave."""
    size = 1024
    while True:
        for f in (1.0, 1.25, 1.5, 1.75):
            if int(size * f) >= n:
                return int(size * f)
        size *= 2


def render_pixels(mi, scene, pixels: np.ndarray, spp: int, seed: int, moments: bool = False):
    """(len(pixels), 3) float32: the box-filter average of `spp` samples of each listed pixel (flat row-major
    indices into the sensor's film), traced by the scene's integrator with the sensor's sampler. `moments`: also
    the average of the samples' squares, (len(pixels), 3) float64 (each pixel's noise, `rh_dataset.render.adaptive`);
    the first array is the same either way."""
    import drjit as dr

    sensor = scene.sensors()[0]
    W, H = (int(v) for v in sensor.film().crop_size())
    n = int(len(pixels))
    n_pad = padded_size(n)
    pix = np.zeros(n_pad, np.uint32)
    pix[:n] = pixels
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(int(spp))
    sampler.set_samples_per_wavefront(int(spp))
    sampler.seed(int(seed), n_pad * int(spp))
    lane = dr.arange(mi.UInt32, n_pad * int(spp)) // dr.opaque(mi.UInt32, int(spp))
    active = lane < dr.opaque(mi.UInt32, n)
    p = dr.gather(mi.UInt32, mi.UInt32(pix), lane)
    py = p // dr.opaque(mi.UInt32, W)
    px = p - py * dr.opaque(mi.UInt32, W)
    # As Mitsuba's sample_rays: the pixel corner plus a 2D sample, scaled to [0, 1]^2 of the film.
    pos = mi.Vector2f(mi.Float(px), mi.Float(py)) + sampler.next_2d(active)
    scale = mi.Vector2f(dr.rcp(dr.opaque(mi.Float, W)), dr.rcp(dr.opaque(mi.Float, H)))
    ray, weight = sensor.sample_ray_differential(time=sensor.shutter_open(), sample1=0.0, sample2=pos * scale,
                                                 sample3=mi.Vector2f(0.5), active=active)
    L = scene.integrator().sample(scene, sampler, ray, None, active)[0] * weight
    # Each pixel's samples are summed in a fixed order (drjit's block reduction of the evaluated samples), not by
    # a scatter-add, which adds them in whatever order the threads reach them: a pixel whose samples straddle two of
    # drjit's work blocks (16384 lanes) got different last bits from run to run at 99 spp.
    L = dr.select(active, L, 0.0)
    L2 = L * L if moments else None
    dr.eval(L) if L2 is None else dr.eval(L, L2)  # one kernel traces all three channels (and their squares)
    acc = np.stack([np.array(dr.block_sum(L[c], int(spp)), dtype=np.float64) for c in range(3)], -1)
    mean = (acc[:n] / spp).astype(np.float32)
    if not moments:
        return mean
    sq = np.stack([np.array(dr.block_sum(L2[c], int(spp)), dtype=np.float64) for c in range(3)], -1)
    return mean, sq[:n] / spp


def render_focused(mi, scene, coverage: np.ndarray, spp_chunks: list[int], env_spp: int, seeds: list[int],
                   env_seed: int, margin: int) -> np.ndarray:
    """The whole frame at `env_spp` (seed `env_seed`), its person pixels replaced by the average of the chunks
    (`spp_chunks[k]` samples, seed `seeds[k]`, weighted by their counts)."""
    img = np.array(mi.render(scene, spp=int(env_spp), seed=int(env_seed)), dtype=np.float32)[..., :3]
    pix = person_pixels(coverage, margin)
    if len(pix) == 0:
        return np.ascontiguousarray(img)
    total = float(sum(spp_chunks))
    acc = np.zeros((len(pix), 3), np.float64)
    for n, s in zip(spp_chunks, seeds):
        acc += render_pixels(mi, scene, pix, n, s).astype(np.float64) * (n / total)
    flat = img.reshape(-1, 3)
    flat[pix] = acc.astype(np.float32)
    return np.ascontiguousarray(flat.reshape(img.shape))
