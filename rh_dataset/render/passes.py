"""Render one frame: a path-traced beauty pass and, separately, a cheap AOV pass; return `{layer: ndarray}`.

Two passes rather than one `aov` integrator wrapping `path`: the AOVs converge at a few samples per pixel while
the beauty image needs many, and RESEARCH.md measured the split arrangement ~2x faster. Only what the requested
layers need is built and run: an AOV-only frame (pretraining data) never path-traces, and its scene has neither the
path integrator nor the environment emitter (the AOV pass reads primary hits only, which no light changes); with
`RenderSettings.cull` it also leaves out triangles outside the view frustum. `FrameRender.info` says what was built.
Hair strands (`scene.is_strands`) are never culled; their BSDF gives the AOV pass the fibre's albedo and the beauty
pass Mitsuba's hair, so one scene serves both passes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from rh_common.camera import Camera

from .cull import drop_faces, outside_frustum
from .adaptive import render_adaptive
from .focus import person_pixels, render_focused
from .sampler import check_spp
from .scene import MeshLike, RenderSettings, is_strands, scene_dict
from ..variant import load_mitsuba, require_variant

__all__ = ["LAYERS", "FrameRender", "render_frame", "denoise_image", "count_fireflies", "FIREFLY_K"]

LAYERS = ("image", "mask", "albedo", "normal", "depth")
_AOV_LAYERS = {"mask", "albedo", "normal", "depth"}


@dataclass(frozen=True)
class FrameRender:
    layers: dict[str, np.ndarray]
    seconds: dict[str, float]
    info: dict
    """What the scene held and ran (recorded in the frame JSON as `render.scene_model`): path_traced,
    emitter_loaded, max_depth (None without path tracing), cull, triangles (as loaded), culled_faces
    {hidden_under_clothes, outside_frustum}."""


# The inner integrator only contributes the alpha channel (coverage: whether the camera ray hit a surface); the AOVs
# come after RGBA in the output. `depth` rather than a `path` of max_depth 1 with hidden emitters: the same coverage
# bits, but it never looks at the emitter, so the AOV pass on the beauty scene (one scene per frame) does not pay for
# the environment map's lookups where rays miss the person (half the pass's time, measured at 512x512).
_AOV_INTEGRATOR = {"type": "aov", "aovs": "alb:albedo,nrm:sh_normal,pos:position", "inner": {"type": "depth"}}


def render_frame(meshes: Sequence[MeshLike], emitter: dict | None, camera: Camera, settings: RenderSettings,
                 layers: Sequence[str], seed: int, *, hidden: Mapping[str, np.ndarray] | None = None,
                 exposure: float | None = None) -> FrameRender:
    """Render the requested layers of one frame.

    Returned arrays (H, W, ...) float32:
      image  (H,W,3) linear radiance, environment visible behind the person;
      mask   (H,W)   coverage in [0,1];
      albedo (H,W,3) diffuse reflectance, divided by coverage (not premultiplied), 0 outside;
      normal (H,W,3) unit shading normal in OpenGL camera axes, 0 outside;
      depth  (H,W)   camera-space z in metres, 0 outside.
    Both passes use a box reconstruction filter over the same pixel footprint, so that
    image = coverage * person + (1 - coverage) * background holds exactly and compositing over another
    background with the mask is consistent. The scene is loaded once and rendered by both integrators.

    `emitter` may be None when no `image` is requested (it is never loaded then anyway). `hidden`: {mesh name: face
    mask} of faces no camera can see (`rh_dataset.render.cull.hidden_faces`), left out when `settings.cull`.
    `exposure`: the frame's display exposure, which `settings.adaptive_tiers` needs (its noise is display-space).
    """
    import time

    mi = load_mitsuba()

    unknown = set(layers) - set(LAYERS)
    if unknown:
        raise ValueError(f"unknown layers {sorted(unknown)}; known: {LAYERS}")
    path_traced = "image" in layers
    if path_traced and emitter is None:
        raise ValueError("render_frame: the image layer is path-traced and needs an emitter; got None")
    if path_traced and settings.max_depth is None:
        raise ValueError("render_frame: max_depth is None; resolve it from the split's scene class first "
                         "(RenderSettings.for_split)")
    require_variant()
    if path_traced:
        for n in sorted(set(_chunks(settings.spp))):
            check_spp(settings.sampler, n, "spp" if n == settings.spp else "spp (one render call's chunk)")
    if _AOV_LAYERS & set(layers) or (settings.denoise and path_traced):
        check_spp(settings.sampler, settings.aov_spp, "aov_spp")
        if path_traced and settings.env_spp is not None:
            check_spp(settings.sampler, settings.env_spp, "env_spp")
    if path_traced and settings.adaptive_tiers is not None:
        for n in settings.adaptive_tiers:
            check_spp(settings.sampler, n, "adaptive_tiers")
        if settings.adaptive_tiers[-1] > MAX_SPP_PER_CALL:
            raise ValueError(f"render setting adaptive_tiers: each tier is one render call, so at most "
                             f"{MAX_SPP_PER_CALL} samples per pixel; got {list(settings.adaptive_tiers)}")
        if exposure is None or not np.isfinite(exposure) or exposure <= 0:
            raise ValueError("render_frame: adaptive_tiers weigh each pixel's noise in display space and need the "
                             f"frame's exposure (exposure=...), got {exposure!r}")
    out: dict[str, np.ndarray] = {}
    seconds: dict[str, float] = {}
    culled = {"hidden_under_clothes": 0, "outside_frustum": 0}
    strands = [m for m in meshes if is_strands(m)]
    meshes = [m for m in meshes if not is_strands(m)]
    if settings.cull and hidden:
        meshes, culled["hidden_under_clothes"] = drop_faces(meshes, hidden)
    if settings.cull and not path_traced:
        # Only primary hits reach the AOVs, so what lies outside the frustum cannot show (see cull.py).
        meshes, culled["outside_frustum"] = drop_faces(
            meshes, [outside_frustum(m.vertices, m.faces, camera) for m in meshes])
    info = {"path_traced": path_traced, "emitter_loaded": path_traced,
            "max_depth": int(settings.max_depth) if path_traced else None, "cull": bool(settings.cull),
            "triangles": int(sum(len(m.faces) for m in meshes)), "culled_faces": culled,
            "strands": int(sum(len(s.points) for s in strands))}
    t = time.perf_counter()
    if path_traced:
        integrator = {"type": "path", "max_depth": int(settings.max_depth), "hide_emitters": False}
        if settings.rr_depth is not None:
            integrator["rr_depth"] = int(settings.rr_depth)
    else:
        integrator = _AOV_INTEGRATOR

    # One scene for both passes, hair included: the strands' BSDF answers the AOV pass's albedo query with the
    # fibre's albedo and path-traces as Mitsuba's hair (strand_shape.HAIR_WITH_ALBEDO).
    scene = mi.load_dict(scene_dict(meshes + strands, emitter if path_traced else None, camera, integrator,
                                    settings.spp, pixel_format="rgba", sampler=settings.sampler))
    seconds["load"] = time.perf_counter() - t
    try:
        # The AOV pass first: the beauty pass may spend its samples where the AOV coverage says the person is.
        denoise = bool(settings.denoise) and path_traced
        aov = None
        if _AOV_LAYERS & set(layers) or denoise:
            t = time.perf_counter()
            aov = np.array(mi.render(scene, integrator=mi.load_dict(_AOV_INTEGRATOR), spp=settings.aov_spp,
                                     seed=seed + 1), dtype=np.float32)
            seconds["aov"] = time.perf_counter() - t
            out.update(_postprocess_aovs(aov, camera, layers))
        if path_traced:
            t = time.perf_counter()
            if settings.adaptive_tiers is not None and aov is not None:
                tiers = settings.adaptive_tiers
                img, counts = render_adaptive(mi, scene, np.clip(aov[..., 3], 0.0, 1.0), float(exposure), settings.spp,
                                              tiers, settings.env_spp, _chunk_seeds(seed, len(tiers) + 1)[1:],
                                              seed + 2, FOCUS_MARGIN)
                info["focus"] = {"env_spp": int(settings.env_spp), "margin_px": FOCUS_MARGIN,
                                 "pixels": int(sum(counts.values())), "pixels_per_tier": counts}
            elif settings.env_spp is not None and aov is not None:
                chunks = _chunks(settings.spp)
                img = render_focused(mi, scene, np.clip(aov[..., 3], 0.0, 1.0), chunks, settings.env_spp,
                                     _chunk_seeds(seed, len(chunks)), seed + 2, FOCUS_MARGIN)
                info["focus"] = {"env_spp": int(settings.env_spp), "margin_px": FOCUS_MARGIN,
                                 "pixels": int(len(person_pixels(aov[..., 3], FOCUS_MARGIN)))}
            else:
                img = _render_chunked(mi, scene, settings.spp, seed)
            out["image"] = np.ascontiguousarray(img[..., :3])
            seconds["beauty"] = time.perf_counter() - t
    finally:
        scene = None  # a live scene makes the next load recompile its kernels
    if denoise:  # opt-in (RenderSettings.denoise), recorded in the frame JSON; guided by this frame's AOVs
        t = time.perf_counter()
        aux = _postprocess_aovs(aov, camera, ("mask", "albedo", "normal"))
        out["image"] = denoise_image(out["image"], aux["albedo"], aux["normal"], aux["mask"])
        seconds["denoise"] = time.perf_counter() - t
    return FrameRender(layers=out, seconds=seconds, info=info)


def denoise_image(image: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None,
                  coverage: np.ndarray | None = None) -> np.ndarray:
    """Intel Open Image Denoise (pyoidn, `hdr=True`, quality 'high') on linear radiance, (H, W, 3) float32.

    Guides: albedo and normal as `render_frame` returns them (albedo un-premultiplied, 0 outside the person);
    with `coverage` they are premultiplied by it so that a pixel's guide is its average over the pixel footprint,
    as OIDN expects for anti-aliased edges. The guides are noisy at low AOV spp (`clean_aux=False`). The result is
    biased; negative outputs (none expected) are clamped to 0 and non-finite outputs raise.
    """
    import pyoidn

    color = np.ascontiguousarray(image, dtype=np.float32)
    a = n = None
    if albedo is not None:
        a = np.asarray(albedo, np.float32)
        a = a * coverage[..., None] if coverage is not None else a
        a = np.ascontiguousarray(np.clip(a, 0.0, 1.0))
    if normal is not None:
        n = np.asarray(normal, np.float32)
        n = n * coverage[..., None] if coverage is not None else n
        n = np.ascontiguousarray(n)
    res = np.asarray(pyoidn.denoise(color, albedo=a, normal=n, hdr=True, quality="high"), dtype=np.float32)
    if not np.all(np.isfinite(res)):
        raise RuntimeError("denoise_image: the denoiser returned NaN/Inf values")
    return np.ascontiguousarray(np.maximum(res.reshape(color.shape), 0.0))


FIREFLY_K = 10.0
"""A pixel is a firefly when its luminance exceeds FIREFLY_K times its robust local level (see `count_fireflies`)."""
FIREFLY_WINDOW = 5


def count_fireflies(image: np.ndarray, k: float = FIREFLY_K, window: int = FIREFLY_WINDOW) -> int:
    """Number of pixels whose Rec.709 luminance L exceeds ``k * max(median_w(L), 1e-4 * mean(L))``.

    `median_w` is the median of the pixel's `window` x `window` neighbourhood (itself included, edges reflected):
    a lone outlier cannot move it, so it is a robust local level. The floor `1e-4 * mean(L)` (global) makes a lone
    bright pixel on a black neighbourhood count while an all-black image gives 0. A diagnostic, never a filter:
    nothing is clamped. Legitimately tiny, very bright features (a sun disc seen directly, a specular glint of
    a pixel or two) count too; read it as "pixels the noise or the light made isolated outliers".
    """
    from scipy.ndimage import minimum_filter

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[-1] < 3:
        raise ValueError(f"count_fireflies: expected (H, W, 3) radiance, got shape {img.shape}")
    if not np.all(np.isfinite(img)):
        raise ValueError("count_fireflies: image contains NaN or Inf")
    lum = img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    floor = 1e-4 * float(lum.mean())
    w = int(window)
    # The window's median is at least its minimum, so only pixels above k * max(minimum, floor) can count; the
    # median (scipy's rank w*w // 2 of the reflected window) is taken for those alone: the same count as a median
    # filter of the whole frame at a fraction of its time (bench/bench_writer.py).
    cand = np.flatnonzero(lum > k * np.maximum(minimum_filter(lum, size=w, mode="reflect"), floor))
    if len(cand) == 0:
        return 0
    r = w // 2
    padded = np.pad(lum, ((r, w - 1 - r), (r, w - 1 - r)), mode="symmetric")  # scipy's "reflect"
    yy, xx = np.divmod(cand, lum.shape[1])
    dy, dx = np.divmod(np.arange(w * w), w)
    neighbours = padded[yy[:, None] + dy[None, :], xx[:, None] + dx[None, :]]
    rank = (w * w) // 2
    local = np.partition(neighbours, rank, axis=1)[:, rank]
    return int(np.count_nonzero(lum.ravel()[cand] > k * np.maximum(local, floor)))


# One Mitsuba call traces width*height*spp paths as one wavefront; at 512x512 x 4096 spp that is 1e9 lanes and
# runs out of memory. Beyond this many samples per pixel the beauty pass is split into chunks with derived seeds
# and averaged, which the box filter makes equivalent to one pass with the total sample count.
MAX_SPP_PER_CALL = 256

# Pixels around the AOV pass's coverage that the focused beauty pass also renders at full spp: the AOV pass, at
# aov_spp samples, can miss a sliver of coverage; a missed pixel is not biased (focus.py), only noisier.
FOCUS_MARGIN = 2


def _chunks(spp: int) -> list[int]:
    if spp <= MAX_SPP_PER_CALL:
        return [spp]
    return [MAX_SPP_PER_CALL] * (spp // MAX_SPP_PER_CALL) + ([spp % MAX_SPP_PER_CALL] if spp % MAX_SPP_PER_CALL else [])


def _chunk_seeds(seed: int, n_chunks: int) -> list[int]:
    return [seed] if n_chunks == 1 else [seed + 1000003 * (k + 1) for k in range(n_chunks)]


def _render_chunked(mi, scene, spp: int, seed: int) -> np.ndarray:
    if spp <= MAX_SPP_PER_CALL:
        return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float32)
    chunks = _chunks(spp)
    acc = None
    for n, s in zip(chunks, _chunk_seeds(seed, len(chunks))):
        part = np.array(mi.render(scene, spp=n, seed=s), dtype=np.float64) * (n / spp)
        acc = part if acc is None else acc + part
    return acc.astype(np.float32)


def _postprocess_aovs(aov: np.ndarray, camera: Camera, layers: Sequence[str]) -> dict[str, np.ndarray]:
    coverage = np.clip(aov[..., 3], 0.0, 1.0)
    inside = coverage > 1e-6
    res: dict[str, np.ndarray] = {}
    if "mask" in layers:
        res["mask"] = coverage.astype(np.float32)
    safe = np.where(inside, coverage, 1.0)[..., None]
    if "albedo" in layers:
        albedo = np.where(inside[..., None], aov[..., 4:7] / safe, 0.0)
        res["albedo"] = np.clip(albedo, 0.0, 1.0).astype(np.float32)
    if "normal" in layers:
        n_world = aov[..., 7:10]
        R = camera.world_to_opengl_rotation()
        n_cam = n_world @ R.T
        length = np.linalg.norm(n_cam, axis=-1, keepdims=True)
        ok = inside & (length[..., 0] > 1e-8)
        n_cam = np.where(ok[..., None], n_cam / np.where(length > 1e-8, length, 1.0), 0.0)
        res["normal"] = n_cam.astype(np.float32)
    if "depth" in layers:
        pos = np.where(inside[..., None], aov[..., 10:13] / safe, 0.0)
        w2c = camera.world_to_camera
        z = pos @ w2c[2, :3] + w2c[2, 3]
        res["depth"] = np.where(inside, z, 0.0).astype(np.float32)
    return res
