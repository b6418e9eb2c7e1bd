"""The camera rig of a multi-view protocol (protocol c): the scene file's `cameras` block in, a `CameraRig` out.

`{"views": [[azimuth_deg, elevation_deg], ...]}`, checked on load (one-line `SpecError`s naming the file); where the
cameras of a subject then stand is `rh_common.camera.orbit_cameras`'s (docs/ARCHITECTURE.md, "Multi-view").
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .scene_files import SpecError, _check_keys

__all__ = ["CameraRig", "parse_rig"]

_CAMERAS_KEYS = {"views"}


@dataclass(frozen=True)
class CameraRig:
    """Several calibrated cameras per frame (protocol c; `rh_common.camera.orbit_cameras`): view k sits on an orbit
    about the centre of the subject's framed box at azimuth `views[k][0]` degrees (0 = the single camera of protocols
    a and b, in front of the body on -Y; counter-clockwise seen from above) and elevation `views[k][1]` degrees
    (positive: above, looking down), every view at one distance per subject that frames the box in all of them."""

    views: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        if not self.views:
            raise SpecError("cameras: views must list at least one [azimuth_deg, elevation_deg]")
        for k, v in enumerate(self.views):
            if not (isinstance(v, tuple) and len(v) == 2 and all(isinstance(x, (int, float))
                                                                 and not isinstance(x, bool) for x in v)):
                raise SpecError(f"cameras: view {k} must be [azimuth_deg, elevation_deg], got {v!r}")
            if not -80.0 <= v[1] <= 80.0:
                raise SpecError(f"cameras: view {k} elevation {v[1]} must be within [-80, 80] degrees")
        if len(set(self.views)) != len(self.views):
            raise SpecError("cameras: two views share an azimuth and elevation")


def parse_rig(where: str, block: Any) -> CameraRig:
    """The scene file's `cameras` block (`where` names the file in errors)."""
    _check_keys(f"{where}: cameras", block, _CAMERAS_KEYS, _CAMERAS_KEYS)
    views = block["views"]
    if not isinstance(views, list):
        raise SpecError(f"{where}: cameras: views must be a list of [azimuth_deg, elevation_deg]")
    try:
        return CameraRig(tuple(tuple(v) if isinstance(v, list) else v for v in views))
    except SpecError as exc:
        raise SpecError(f"{where}: {exc}") from None
