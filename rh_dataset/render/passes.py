"""Render one frame: a path-traced beauty pass and, separately, a cheap AOV pass; return `{layer: ndarray}`.

Two passes rather than one `aov` integrator wrapping `path`: the AOVs converge at a few samples per pixel while
the beauty image needs many, and RESEARCH.md measured the split arrangement ~2x faster. Only the passes the
requested layers need are run: an AOV-only frame (pretraining data) never path-traces.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .camera import Camera
from .scene import MeshLike, RenderSettings, scene_dict
from .variant import require_variant

__all__ = ["LAYERS", "FrameRender", "render_frame"]

LAYERS = ("image", "mask", "albedo", "normal", "depth")
_AOV_LAYERS = {"mask", "albedo", "normal", "depth"}


@dataclass(frozen=True)
class FrameRender:
    layers: dict[str, np.ndarray]
    seconds: dict[str, float]


def _render(d: dict, seed: int) -> np.ndarray:
    import mitsuba as mi

    scene = mi.load_dict(d)
    out = np.array(mi.render(scene, seed=seed), dtype=np.float32)
    del scene  # a live scene makes the next load recompile its kernels
    return out


def render_frame(meshes: Sequence[MeshLike], emitter: dict, camera: Camera, settings: RenderSettings,
                 layers: Sequence[str], seed: int) -> FrameRender:
    """Render the requested layers of one frame.

    Returned arrays (H, W, ...) float32:
      image  (H,W,3) linear radiance, environment visible behind the person;
    Both passes use a box reconstruction filter over the same pixel footprint, so that
    image = coverage * person + (1 - coverage) * background holds exactly and compositing over another
    background with the mask is consistent.
      mask   (H,W)   coverage in [0,1] (box filter);
      albedo (H,W,3) diffuse reflectance, divided by coverage (not premultiplied), 0 outside;
      normal (H,W,3) unit shading normal in OpenGL camera axes, 0 outside;
      depth  (H,W)   camera-space z in metres, 0 outside.
    """
    import time

    unknown = set(layers) - set(LAYERS)
    if unknown:
        raise ValueError(f"unknown layers {sorted(unknown)}; known: {LAYERS}")
    require_variant()
    out: dict[str, np.ndarray] = {}
    seconds: dict[str, float] = {}
    if "image" in layers:
        t = time.perf_counter()
        integ = {"type": "path", "max_depth": int(settings.max_depth), "hide_emitters": False}
        img = _render(scene_dict(meshes, emitter, camera, integ, settings.spp, pixel_format="rgb"), seed)
        out["image"] = np.ascontiguousarray(img[..., :3])
        seconds["beauty"] = time.perf_counter() - t
    if _AOV_LAYERS & set(layers):
        t = time.perf_counter()
        # The inner path integrator with max_depth 1 and hidden emitters only contributes the alpha channel
        # (coverage); the AOVs come after RGBA in the output.
        integ = {"type": "aov", "aovs": "alb:albedo,nrm:sh_normal,pos:position",
                 "inner": {"type": "path", "max_depth": 1, "hide_emitters": True}}
        aov = _render(scene_dict(meshes, emitter, camera, integ, settings.aov_spp, pixel_format="rgba"), seed + 1)
        seconds["aov"] = time.perf_counter() - t
        out.update(_postprocess_aovs(aov, camera, layers))
    return FrameRender(layers=out, seconds=seconds)


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
