"""The Mitsuba sensor of a pinhole `rh_common.camera.Camera`.

In: a Camera, a sample count and a sampler name. Out: the `perspective` sensor dict for Mitsuba's scene. Mitsuba's `look_at`
frame has +X to the image's left and +Y up; OpenCV's has +X right and +Y down. `Camera.world_to_camera` is built
independently from the same origin/target/up, and tests check that a rendered point lands where
`K @ world_to_camera` projects it.
"""
from __future__ import annotations

from rh_common.camera import Camera

from ..variant import load_mitsuba
from .sampler import sampler_dict

__all__ = ["mitsuba_sensor"]


def mitsuba_sensor(camera: Camera, spp: int, *, pixel_format: str = "rgb", sampler: str = "independent") -> dict:
    """The Mitsuba `perspective` sensor dict that renders exactly `camera` with `spp` samples per pixel drawn by
    Mitsuba's `sampler` (`rh_dataset.render.sampler`)."""
    mi = load_mitsuba()
    to_world = mi.ScalarTransform4f().look_at(
        origin=list(map(float, camera.origin)), target=list(map(float, camera.target)),
        up=list(map(float, camera.up)),
    )
    # A box filter: every layer is an average over exactly the pixel's footprint, so image, mask and AOVs
    # of one pixel describe the same area (Mitsuba's default Gaussian would bleed 2 px past the mask).
    film = {"type": "hdrfilm", "width": camera.width, "height": camera.height, "pixel_format": pixel_format,
            "rfilter": {"type": "box"}}
    return {
        "type": "perspective",
        "fov": float(camera.fov_y_deg),
        "fov_axis": "y",
        "to_world": to_world,
        "near_clip": 0.01,
        "far_clip": 1000.0,
        "film": film,
        "sampler": sampler_dict(sampler, spp),
    }
