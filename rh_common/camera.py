"""Pinhole camera: intrinsics, OpenCV extrinsics, projection, the frame JSON's `camera` block, and framing a body.

In: resolution, vertical field of view, origin/target/up (or a body's bounding box for `frame_body`, and a list of
(azimuth, elevation) views for `orbit_cameras`, protocol c's rig). Out: `K`,
`world_to_camera` and friends as numpy arrays. Conventions are in docs/ARCHITECTURE.md ("Camera model").
Why in rh_common: a dataset's camera is part of its format, written by the path-traced generator and by RANA's
synthetic datasets alike. The Mitsuba sensor that renders exactly this camera is the generator's
(`rh_dataset.render.camera.mitsuba_sensor`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Camera", "frame_body", "orbit_cameras"]


@dataclass(frozen=True)
class Camera:
    width: int
    height: int
    fov_y_deg: float
    origin: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int) and isinstance(self.height, int)) or self.width < 1 or self.height < 1:
            raise ValueError(f"camera resolution must be positive integers, got {self.width}x{self.height}")
        if not 0.0 < self.fov_y_deg < 179.0:
            raise ValueError(f"camera fov_y_deg must be in (0, 179), got {self.fov_y_deg}")
        fwd = np.subtract(self.target, self.origin)
        if np.linalg.norm(fwd) < 1e-9:
            raise ValueError("camera origin and target coincide")
        if np.linalg.norm(np.cross(fwd, self.up)) < 1e-9 * np.linalg.norm(fwd):
            raise ValueError("camera up vector is parallel to the viewing direction")

    @property
    def K(self) -> np.ndarray:
        f = 0.5 * self.height / math.tan(math.radians(self.fov_y_deg) / 2.0)
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    @property
    def world_to_camera(self) -> np.ndarray:
        """4x4, OpenCV axes: x right, y down, z forward."""
        o = np.asarray(self.origin, dtype=np.float64)
        z = np.subtract(self.target, o)
        z /= np.linalg.norm(z)
        x = np.cross(z, self.up)  # right-handed: forward x up = right
        x /= np.linalg.norm(x)
        y = np.cross(z, x)  # down
        R = np.stack([x, y, z])
        M = np.eye(4)
        M[:3, :3] = R
        M[:3, 3] = -R @ o
        return M

    @property
    def camera_to_world(self) -> np.ndarray:
        return np.linalg.inv(self.world_to_camera)

    @property
    def opencv_to_opengl(self) -> np.ndarray:
        """3x3 change of camera axes from OpenCV (y down, z forward) to OpenGL (y up, z backward)."""
        return np.diag([1.0, -1.0, -1.0])

    def world_to_opengl_rotation(self) -> np.ndarray:
        """3x3 rotation taking world directions to OpenGL camera directions (the frame normals are stored in)."""
        return self.opencv_to_opengl @ self.world_to_camera[:3, :3]

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """(N, 3) world points to (N, 2) pixel coordinates (continuous; pixel centres at +0.5)."""
        p = np.asarray(points_world, dtype=np.float64)
        pc = p @ self.world_to_camera[:3, :3].T + self.world_to_camera[:3, 3]
        uv = pc @ self.K.T
        return uv[:, :2] / uv[:, 2:3]

    def to_json(self) -> dict:
        return {
            "K": self.K,
            "world_to_camera": self.world_to_camera,
            "camera_to_world": self.camera_to_world,
            "fov_y_deg": self.fov_y_deg,
            "origin": list(self.origin),
            "target": list(self.target),
            "up": list(self.up),
        }


def frame_body(bounds_min: np.ndarray, bounds_max: np.ndarray, width: int, height: int, fov_y_deg: float,
               fill: float = 0.85) -> Camera:
    """A camera in front of the body (on the −Y side, looking +Y, horizontal) whose frame holds the given box.

    `fill` is the fraction of the limiting image dimension the box's projected extent may take.
    """
    lo = np.asarray(bounds_min, dtype=np.float64)
    hi = np.asarray(bounds_max, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    half_h = 0.5 * (hi[2] - lo[2])
    half_w = 0.5 * max(hi[0] - lo[0], hi[1] - lo[1])  # the body may turn: its depth can become its width
    tan_y = math.tan(math.radians(fov_y_deg) / 2.0)
    tan_x = tan_y * width / height
    depth_half = 0.5 * max(hi[0] - lo[0], hi[1] - lo[1])
    dist = max(half_h / (fill * tan_y), half_w / (fill * tan_x)) + depth_half
    origin = (float(centre[0]), float(centre[1] - dist), float(centre[2]))
    return Camera(width=width, height=height, fov_y_deg=float(fov_y_deg), origin=origin,
                  target=(float(centre[0]), float(centre[1]), float(centre[2])))


def _fits(cam: Camera, points: np.ndarray, fill: float) -> bool:
    """Every point in front of the camera and inside the central `fill` fraction of the frame (both axes)."""
    pc = points @ cam.world_to_camera[:3, :3].T + cam.world_to_camera[:3, 3]
    if np.any(pc[:, 2] <= 1e-6):
        return False
    uv = cam.project(points)
    half = np.array([cam.width, cam.height]) / 2.0
    return bool(np.all(np.abs(uv - half) <= fill * half))


def _orbit(centre: np.ndarray, azimuth_deg: float, elevation_deg: float, dist: float, width: int, height: int,
           fov_y_deg: float) -> Camera:
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    # azimuth 0 is frame_body's camera (on -Y); counter-clockwise seen from above (+Z)
    d = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
    origin = centre + dist * d
    return Camera(width=width, height=height, fov_y_deg=float(fov_y_deg),
                  origin=tuple(float(x) for x in origin), target=tuple(float(x) for x in centre))


def orbit_cameras(bounds_min: np.ndarray, bounds_max: np.ndarray, width: int, height: int, fov_y_deg: float,
                  views, fill: float = 0.85) -> list[Camera]:
    """One camera per (azimuth_deg, elevation_deg) of `views`, all looking at the box's centre from one distance:
    the smallest (to 0.1%) at which the box, turned to any heading about the vertical (its enclosing vertical
    cylinder), projects inside the central `fill` of the frame in every view. Azimuth 0, elevation 0 points the
    way `frame_body`'s camera does; azimuth turns counter-clockwise seen from above; elevation > 0 looks down."""
    lo = np.asarray(bounds_min, dtype=np.float64)
    hi = np.asarray(bounds_max, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    r = 0.5 * math.hypot(hi[0] - lo[0], hi[1] - lo[1])
    t = np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False)
    rp = r / math.cos(math.pi / len(t))  # a polygon around the circle, not inside it: the fit errs on the safe side
    ring = np.stack([centre[0] + rp * np.cos(t), centre[1] + rp * np.sin(t)], axis=1)
    points = np.concatenate([np.column_stack([ring, np.full(len(t), z)]) for z in (lo[2], hi[2])])
    dist = 0.0
    for az, el in views:
        near = r * 1.001  # inside the cylinder nothing fits; far enough, everything does
        far = near * 2.0
        while not _fits(_orbit(centre, az, el, far, width, height, fov_y_deg), points, fill):
            far *= 2.0
        while far - near > 1e-3 * far:
            mid = 0.5 * (near + far)
            near, far = (near, mid) if _fits(_orbit(centre, az, el, mid, width, height, fov_y_deg), points,
                                             fill) else (mid, far)
        dist = max(dist, far)
    return [_orbit(centre, float(az), float(el), dist, width, height, fov_y_deg) for az, el in views]
