"""Captured motion (BVH; also the animation of FBX/glTF files) read through Blender into a validated `Motion`.

Reading runs Blender's own importers in Blender's Python (`rh_common.blender`, bpy pins numpy 1.26) via
`bpy_read_motion.py`; only plain numpy arrays come back. What a `Motion` holds is rig-neutral: the file's rest
skeleton (a `Skeleton`, metres, Z up) and, per frame, every bone's world rotation relative to its rest orientation
(G, the quantity `skeleton.py` composes as G_c = G_p D_c) plus the posed root head. Retargeting (`retarget.py`)
copies G between rigs.

Units: BVH files carry no unit. `read_motion(scale=None)` takes the rest skeleton's height h (z extent of its
heads and tails): 0.8-2.5 is read as metres, 80-250 as centimetres, anything else (CMU's BVH files, about 32
units tall, millimetres, a toy) is scaled to a 1.70 m tall skeleton; `Motion.unit_scale` and `unit_rule` record
what was done. Retargeting scales translations by leg length, so the choice only matters for the numbers a
`Motion` reports in metres.
"""
from __future__ import annotations

import dataclasses
import functools
import tempfile
from pathlib import Path

import numpy as np

from rh_common.imageio import sha256_file

from .skeleton import Skeleton, SkeletonPose, posed_heads

__all__ = ["Motion", "MotionError", "read_motion", "read_motion_cached", "motion_from_arrays", "MOTION_SUFFIXES"]

MOTION_SUFFIXES = (".bvh", ".fbx", ".glb", ".gltf")
_SCRIPT = Path(__file__).with_name("bpy_read_motion.py")
_ORTHO_TOL = 1e-5  # Blender computes in float32: rotations come back orthonormal to ~1e-7
# Our forward kinematics from (G, root head) must land on Blender's posed heads: a BVH with translation channels
# on joints other than the root (rare; SkeletonPose only moves the root) would fail here instead of posing wrongly.
_FK_TOL = 1e-3  # as a fraction of the skeleton's height


class MotionError(ValueError):
    """A motion file that cannot be used; the message names the file and what to do."""


@dataclasses.dataclass(frozen=True, eq=False)
class Motion:
    """skeleton: the file's rest skeleton (metres, Z up, facing -Y when the file faced its forward axis);
    rotations (F, J, 3, 3): G per frame and bone, world rotation relative to rest; root_positions (F, 3): the posed
    head of the first root bone, metres; fps; source: the file's name; sha256 of the file; first_frame: the file's
    number of frame 0 (Blender's numbering, BVH frames start at 1); unit_scale: metres per file unit applied;
    unit_rule: how unit_scale was chosen ('given', 'metres', 'centimetres', 'height')."""

    skeleton: Skeleton
    rotations: np.ndarray
    root_positions: np.ndarray
    fps: float
    source: str
    sha256: str
    first_frame: int = 0
    unit_scale: float = 1.0
    unit_rule: str = "given"

    def __post_init__(self) -> None:
        J = len(self.skeleton)
        G = np.array(self.rotations, dtype=np.float64)
        r = np.array(self.root_positions, dtype=np.float64)
        where = f"motion {self.source or '(unnamed)'}"
        if G.ndim != 4 or G.shape[1:] != (J, 3, 3) or len(G) < 1:
            raise MotionError(f"{where}: rotations must be (F >= 1, {J}, 3, 3), got {G.shape}")
        if r.shape != (len(G), 3):
            raise MotionError(f"{where}: root_positions must be ({len(G)}, 3), got {r.shape}")
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(r))):
            bad = sorted({int(f) for f in np.flatnonzero(~np.isfinite(G).reshape(len(G), -1).all(1))}
                         | {int(f) for f in np.flatnonzero(~np.isfinite(r).all(1))})
            raise MotionError(f"{where}: non-finite values in frames {bad[:10]}")
        err = np.abs(np.einsum("fjab,fjcb->fjac", G, G) - np.eye(3)).max()
        det = np.abs(np.linalg.det(G) - 1.0).max()
        if err > _ORTHO_TOL or det > _ORTHO_TOL:
            raise MotionError(f"{where}: rotations are not proper rotations (orthonormality error {err:.1e}, "
                              f"determinant error {det:.1e}); a scaled or mirrored bone cannot be retargeted")
        if not (isinstance(self.fps, (int, float)) and np.isfinite(self.fps) and self.fps > 0):
            raise MotionError(f"{where}: fps must be a positive number, got {self.fps!r}")
        if not (np.isfinite(self.unit_scale) and self.unit_scale > 0):
            raise MotionError(f"{where}: unit_scale must be positive, got {self.unit_scale!r}")
        if not np.any(self.skeleton.parents < 0):
            raise MotionError(f"{where}: the skeleton has no root bone")
        G.setflags(write=False)
        r.setflags(write=False)
        object.__setattr__(self, "rotations", G)
        object.__setattr__(self, "root_positions", r)
        object.__setattr__(self, "fps", float(self.fps))

    def __len__(self) -> int:
        return len(self.rotations)

    @functools.cached_property
    def root(self) -> int:
        return int(np.flatnonzero(self.skeleton.parents < 0)[0])

    def pose(self, f: int) -> SkeletonPose:
        """Frame f as a SkeletonPose of `skeleton` (deltas D_c = G_p^T G_c; the root carries the translation)."""
        G = self.rotations[f]
        par = self.skeleton.parents
        D = np.where((par < 0)[:, None, None], G, np.einsum("jba,jbc->jac", G[np.maximum(par, 0)], G))
        return SkeletonPose(D, self.root_positions[f] - self.skeleton.heads[self.root])

    def posed_heads(self, f: int) -> np.ndarray:
        """(J, 3) posed bone heads of frame f, metres."""
        return posed_heads(self.skeleton, self.pose(f), self.rotations[f])

    def record(self, frame: int) -> dict:
        """What a frame JSON says about where its pose came from."""
        return {"file": self.source, "sha256": self.sha256, "frame": int(frame),
                "file_frame": int(self.first_frame + frame), "fps": self.fps}


def _unit_scale(heads: np.ndarray, tails: np.ndarray, scale: float | None) -> tuple[float, str]:
    if scale is not None:
        if not (isinstance(scale, (int, float)) and np.isfinite(scale) and scale > 0):
            raise MotionError(f"scale must be a positive number of metres per file unit, got {scale!r}")
        return float(scale), "given"
    z = np.concatenate([heads[:, 2], tails[:, 2]])
    h = float(z.max() - z.min())
    if h <= 0:
        raise MotionError("the rest skeleton is flat (no vertical extent): pass scale= explicitly")
    if 0.8 <= h <= 2.5:
        return 1.0, "metres"
    if 80.0 <= h <= 250.0:
        return 0.01, "centimetres"
    return 1.70 / h, "height"


def motion_from_arrays(arrays: dict, *, source: str, sha256: str, scale: float | None = None) -> Motion:
    """A Motion from the reader's arrays (see `bpy_read_motion.py`), checked: shapes, finiteness, rotations, and
    that our forward kinematics reproduces the posed heads Blender computed."""
    need = ("names", "parents", "rest_heads", "rest_tails", "rotations", "posed_heads", "fps", "frame_start")
    if missing := [k for k in need if k not in arrays]:
        raise MotionError(f"{source}: the reader's output lacks {missing} (a stale bpy_read_motion.py?)")
    try:
        skeleton = Skeleton(tuple(str(n) for n in arrays["names"]), arrays["parents"], arrays["rest_heads"],
                            arrays["rest_tails"])
    except ValueError as exc:
        raise MotionError(f"{source}: bad skeleton: {exc}") from exc
    k, rule = _unit_scale(skeleton.heads, skeleton.tails, scale)
    skeleton = Skeleton(skeleton.names, skeleton.parents, skeleton.heads * k, skeleton.tails * k)
    posed = np.asarray(arrays["posed_heads"], dtype=np.float64) * k
    root = int(np.flatnonzero(skeleton.parents < 0)[0])
    if posed.ndim != 3 or posed.shape[1:] != (len(skeleton), 3):
        raise MotionError(f"{source}: posed heads must be (F, {len(skeleton)}, 3), got {posed.shape}")
    motion = Motion(skeleton, arrays["rotations"], posed[:, root], float(arrays["fps"]), source, sha256,
                    first_frame=int(arrays["frame_start"]), unit_scale=k, unit_rule=rule)
    height = float(np.ptp(np.concatenate([skeleton.heads, skeleton.tails])[:, 2])) or 1.0
    worst = max(float(np.abs(motion.posed_heads(f) - posed[f]).max()) for f in range(len(motion)))
    if worst > _FK_TOL * height:
        raise MotionError(f"{source}: posed joints differ from Blender's by up to {worst:.3g} m: the file moves "
                          f"joints other than the root by translation, which retargeting cannot carry")
    return motion


def read_motion(path: str | Path, *, scale: float | None = None) -> Motion:
    """Read the animation of a BVH (or FBX/glTF) file through Blender. `scale`: metres per file unit (default:
    guessed from the skeleton's height, see the module docstring). Raises MotionError naming the file and the fix."""
    from rh_common.blender import BlenderError, BlenderUnavailable, run_blender_script

    path = Path(path)
    if not path.is_file():
        raise MotionError(f"motion file {path} does not exist: pass the path of a .bvh (or .fbx/.glb/.gltf) file")
    if path.suffix.lower() not in MOTION_SUFFIXES:
        raise MotionError(f"motion file {path}: unsupported type {path.suffix!r}; use one of {MOTION_SUFFIXES}")
    digest = sha256_file(path)
    with tempfile.TemporaryDirectory(prefix="rh_motion_") as tmp:
        out = Path(tmp) / "motion.npz"
        try:
            run_blender_script(_SCRIPT, [str(path.resolve()), str(out)], timeout=600, threads=1)
        except BlenderUnavailable as exc:
            raise MotionError(f"cannot read motion file {path}: {exc}") from exc
        except BlenderError as exc:
            last = str(exc).strip().splitlines()[-1]
            raise MotionError(f"cannot read motion file {path}: {last}. Check that it is a complete, valid "
                              f"{path.suffix[1:].upper()} file (open it in Blender to see what is wrong) or "
                              f"export it again") from exc
        with np.load(out, allow_pickle=False) as z:
            arrays = {key: z[key] for key in z.files}
    return motion_from_arrays(arrays, source=path.name, sha256=digest, scale=scale)


@functools.lru_cache(maxsize=4)
def _read_cached(resolved: str, sha256: str, scale: float | None) -> Motion:
    motion = read_motion(resolved, scale=scale)
    if motion.sha256 != sha256:
        raise MotionError(f"motion file {resolved} changed while being read (sha256 {motion.sha256[:12]} != "
                          f"{sha256[:12]})")
    return motion


def read_motion_cached(path: str | Path, sha256: str, *, scale: float | None = None) -> Motion:
    """`read_motion`, once per process for a (file, content): generation asks for the same motion every frame.
    Refuses a file whose content is not `sha256` any more (the dataset records the file it was made from)."""
    path = Path(path)
    if not path.is_file():
        raise MotionError(f"motion file {path} does not exist: pass the path of a .bvh (or .fbx/.glb/.gltf) file")
    now = sha256_file(path)
    if now != sha256:
        raise MotionError(f"motion file {path} has changed since the run started (sha256 {now[:12]}, expected "
                          f"{sha256[:12]}): rerun with the file as it was, or start a new --out")
    return _read_cached(str(path.resolve()), sha256, scale)
