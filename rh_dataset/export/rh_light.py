"""A frame's light as a file the published Relighting Humans loaders open: `<export>/hdri/<stem>.hdr` and `.exr`.

In: a frame record (its `light`, `exposure` and camera) and the HDRI folder the dataset was drawn from. Out: the
environment the frame was lit by, with its rotation, scale and the frame's display exposure baked in, resampled
into the equirectangular convention of IntrinsicAvatar's light (`envlight-tensor`, torch_pbr) in IntrinsicAvatar's
test world, which is attached to the camera; `bg_file` names it. docs/INTEROP.md ("Lights") derives the mapping.

Why baked rather than named: the loaders fetch `<bg_file>` from Poly Haven at 4k, unrotated and unscaled, which is
not the light our frames were rendered under (and nothing here may download). Why the exposure is in: the loaders
render the map's linear radiance straight to sRGB and compare with our display-space PNG, which is
`srgb(exposure · radiance)`; the factor is recorded in the frame JSON (`rh_bake`).
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from rh_common.imageio import write_exr, write_hdr

from .common import ExportError, hdri_path

__all__ = ["BAKE_SIZE", "R_IA", "ia_directions", "bake_radiance", "bake_key", "bake_frame_light", "sample_equirect"]

BAKE_SIZE = (512, 1024)
"""(rows, columns) of every baked map: one size for all, because Gaussian Shadow Casting stacks them in one array."""

R_IA = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
"""IntrinsicAvatar's test world → our OpenCV camera axes (its `get_perspective` at yaw 0, theta = −270°):
its world +x is the camera's forward, −z the camera's right, +y the camera's down."""
R_IA.setflags(write=False)


def ia_directions(H: int, W: int) -> np.ndarray:
    """(H, W, 3) unit directions, in IntrinsicAvatar's test world, that its light assigns to texel (row, column).

    torch_pbr looks a direction up at u = atan2(x, z)/2π + 0.5, v = asin(y)/π + 0.5 with `grid_sample(...,
    align_corners=True)`, so column j sits at u = j/(W−1) and row i at v = i/(H−1) (the first and the last column
    both at longitude ±π; row 0 at y = −1).
    """
    lon = (np.arange(W, dtype=np.float64) / (W - 1) - 0.5) * 2.0 * math.pi
    lat = (np.arange(H, dtype=np.float64) / (H - 1) - 0.5) * math.pi
    cl, sl = np.cos(lat)[:, None], np.sin(lat)[:, None]
    return np.stack([cl * np.sin(lon)[None, :], np.broadcast_to(sl, (H, W)), cl * np.cos(lon)[None, :]], axis=-1)


def sample_equirect(radiance: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Bilinear lookup of our equirectangular map (ARCHITECTURE.md "Environment lights": φ = atan2(y, x),
    θ = arccos z, u = 0.5 − φ/2π, pixel centres at +0.5) in world directions (..., 3); wraps in u."""
    h, w = radiance.shape[:2]
    d = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    theta = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
    phi = np.arctan2(d[..., 1], d[..., 0])
    x = ((0.5 - phi / (2.0 * math.pi)) % 1.0) * w - 0.5
    y = np.clip(theta / math.pi * h - 0.5, 0.0, h - 1.0)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    xa, xb = x0 % w, (x0 + 1) % w
    ya, yb = y0, np.minimum(y0 + 1, h - 1)
    top = radiance[ya, xa] * (1 - fx) + radiance[ya, xb] * fx
    bot = radiance[yb, xa] * (1 - fx) + radiance[yb, xb] * fx
    return top * (1 - fy) + bot * fy


def bake_radiance(light_radiance: np.ndarray, rotation_deg: float, camera_to_world: np.ndarray, k: float,
                  size: tuple[int, int] = BAKE_SIZE) -> np.ndarray:
    """The baked map (H, W, 3) float32: texel → IA direction → camera (R_IA) → our world (camera_to_world) → the
    light's own frame (Rz(−rotation)) → `k ·` our map there. `light_radiance` is `Light.radiance` (scale applied)."""
    from rh_dataset.lights.mitsuba_env import rotation_z

    d_ia = ia_directions(*size)
    M = rotation_z(-rotation_deg) @ np.asarray(camera_to_world, dtype=np.float64)[:3, :3] @ R_IA
    d_light = d_ia @ M.T
    return (k * sample_equirect(np.asarray(light_radiance, dtype=np.float64), d_light)).astype(np.float32)


def bake_key(meta: dict) -> tuple[str, dict]:
    """(file stem, description) of a frame's baked light: one file per distinct light, exposure and camera
    orientation. The stem starts with `rh_` so it never names a Poly Haven map."""
    light = {k: v for k, v in meta["light"].items() if k not in ("sh_world", "sh_camera", "negative_pixels_clamped")}
    R = np.round(np.array(meta["camera"]["camera_to_world"], dtype=np.float64)[:3, :3], 9).tolist()
    desc = {"light": light, "k": float(meta["exposure"]), "camera_to_world_rotation": R, "size": list(BAKE_SIZE)}
    digest = hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:12]
    name = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(light.get("name", "light")))
    return f"rh_{name}_{digest}", desc


def bake_frame_light(meta: dict, hdri_folder: str | None, out_root: Path, done: dict[str, dict],
                     where: str = "frame JSON") -> dict:
    """Write `<out_root>/hdri/<stem>.hdr` and `.exr` for this frame's light (once per export: `done` caches),
    return the record that goes into the frame JSON (`rh_bake`). `where` (the frame JSON's path) names the file
    in the error for a light that cannot be rebuilt."""
    from rh_dataset.lights import LightSpec, build_light

    stem, desc = bake_key(meta)
    if stem in done:
        return done[stem]
    L = meta["light"]
    if L["kind"] == "envmap":
        src = hdri_path(L, hdri_folder)
        if src is None:
            raise ExportError(f"light {L['name']!r} ({L.get('source')}) is not on this machine"
                              f"{' in ' + hdri_folder if hdri_folder else ' (bundled Poly Haven maps)'}: the export "
                              f"bakes every frame's light into <out>/hdri/; install Blender's bundled maps or pass "
                              f"the dataset's --hdri-folder maps at the same path")
        source = str(src)
    else:
        source = ""
    spec = LightSpec.from_json(L, where, source=source)
    light = build_light(spec)
    baked = bake_radiance(light.radiance, spec.rotation_deg, np.array(meta["camera"]["camera_to_world"]), desc["k"])
    write_hdr(out_root / "hdri" / f"{stem}.hdr", baked)
    write_exr(out_root / "hdri" / f"{stem}.exr", baked)
    rec = {"file": f"{stem}.hdr", "exr": f"{stem}.exr", "k": desc["k"], "k_is": "the frame's exposure (scale is in)",
           "size": list(BAKE_SIZE), "convention": "IntrinsicAvatar envlight-tensor, test world (docs/INTEROP.md)"}
    done[stem] = rec
    return rec
