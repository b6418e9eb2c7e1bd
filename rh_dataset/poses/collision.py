"""A cheap test for gross self-intersection of a posed anny body.

The mesh is split into 14 segments by each vertex's dominant skinning bone (torso, head, upper arm, forearm, hand,
thigh, shin, foot per side). Segments that share a joint (torso-head, torso-upper arm, upper arm-forearm,
forearm-hand, torso-thigh, thigh-shin, shin-foot) are never compared: linear-blend skinning squeezes and
interpenetrates skin at every flexed joint by construction. For every other pair (A, B), sampled surface points
of A (every 3rd vertex) get a signed distance to B's surface: nearest vertex q of B (KD-tree over all of B's
posed vertices) and s = (p - q) · n_q with n_q B's posed vertex normal, negative inside B.

"Gross" means, numerically: at least `MIN_POINTS` (= 4) sampled points of one segment lie more than
`DEPTH_TOL_M` (= 2 cm) inside a non-adjacent segment. 2 cm is about the sample spacing and well below a forearm's
radius (~4 cm), so resting contact (arms crossed on the chest, hands on the thighs, thighs touching when sitting)
passes while a forearm driven into the torso or one leg through the other fails.
Points of A already within `REST_CONTACT_M` (= 2 cm) of B in the reference pose (inner thighs, arms against the
chest on heavy bodies) are not tested against B: they touch in the rest pose and would flag every pose.

The signed distance is only approximate near concave regions and open segment borders (armpit, groin); the
adjacency exclusion keeps those out of the comparison. Cost: ~15-25 ms per pose on one core (skinning 13k
vertices + ~15 KD-tree builds and queries).
"""
from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping

import numpy as np
from scipy.spatial import cKDTree

from rh_dataset.mesh import vertex_normals

from .pose import BodyPose
from .rig import Rig, rig_for

__all__ = ["Intersection", "find_intersections", "intersects", "SEGMENTS", "DEPTH_TOL_M", "MIN_POINTS",
           "REST_CONTACT_M"]

DEPTH_TOL_M = 0.02
MIN_POINTS = 4
REST_CONTACT_M = 0.02
_MAX_QUERY = 400  # query points per segment: ~1.5-2 cm apart on the torso and limbs
_ALONG_NORMAL = 0.7  # cos 45°

# Segment of each bone, by label prefix; bones of the same segment move (nearly) rigidly together.
SEGMENTS: tuple[str, ...] = ("torso", "head", "upperarm.L", "forearm.L", "hand.L", "thigh.L", "shin.L", "foot.L",
                             "upperarm.R", "forearm.R", "hand.R", "thigh.R", "shin.R", "foot.R")
_ADJACENT = {("torso", "head")} | {
    pair for s in ("L", "R") for pair in (
        ("torso", f"upperarm.{s}"), (f"upperarm.{s}", f"forearm.{s}"), (f"forearm.{s}", f"hand.{s}"),
        ("torso", f"thigh.{s}"), (f"thigh.{s}", f"shin.{s}"), (f"shin.{s}", f"foot.{s}"))}


def _segment_of(label: str) -> str:
    side = label[-1] if label.endswith((".L", ".R")) else ""
    base = label.split(".")[0]
    if base in ("neck01", "neck02", "neck03", "head", "eye"):
        return "head"
    if base.startswith("upperarm"):
        return f"upperarm.{side}"
    if base.startswith("lowerarm"):
        return f"forearm.{side}"
    if base in ("wrist",) or base.startswith(("finger", "metacarpal")):
        return f"hand.{side}"
    if base.startswith("upperleg"):
        return f"thigh.{side}"
    if base.startswith("lowerleg"):
        return f"shin.{side}"
    if base == "foot" or base.startswith("toe"):
        return f"foot.{side}"
    return "torso"  # root, pelvis, spine, clavicle, shoulder01


@dataclasses.dataclass(frozen=True)
class Intersection:
    """Points of `segment` found deeper than the tolerance inside `other`."""

    segment: str
    other: str
    n_points: int
    max_depth_m: float


@dataclasses.dataclass(frozen=True, eq=False)
class _Checker:
    rig: Rig
    segment_vertices: tuple[np.ndarray, ...]  # per segment: all its vertex ids (KD-tree targets), sorted
    query_positions: tuple[np.ndarray, ...]  # per segment: positions of its query points in segment_vertices
    rest_normals: np.ndarray
    # per target segment B: ((A, mask over A's query points tested against B), ...)
    targets: tuple[tuple[int, tuple[tuple[int, np.ndarray], ...]], ...]

    def posed(self, W: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        every = np.concatenate(self.segment_vertices)
        pts, nrm = self.rig.skin(W, every, self.rest_normals[every])
        cuts = np.cumsum([len(v) for v in self.segment_vertices])[:-1]
        return np.split(pts, cuts), np.split(nrm, cuts)

    def depths(self, W: np.ndarray):
        """Yield (A, B, depth inside B of each tested query point of A; <= 0 when not inside)."""
        points, normals = self.posed(W)
        for b, sources in self.targets:
            target = points[b]
            lo, hi = target.min(0), target.max(0)
            tree = None
            for a, mask in sources:
                q = points[a][self.query_positions[a]][mask]
                depth = np.zeros(len(q))
                # A point outside B's bounding box cannot be inside B: most pairs end here.
                near = np.flatnonzero(np.all((q > lo) & (q < hi), axis=1))
                if len(near):
                    tree = tree if tree is not None else cKDTree(target)
                    _, nearest = tree.query(q[near])
                    offset = q[near] - target[nearest]
                    s = np.einsum("ij,ij->i", offset, normals[b][nearest])
                    # Inside only if the offset runs along the inward normal: beyond an open segment border
                    # (a far point whose nearest vertex is on the cut rim) the offset is tangential instead.
                    along = -s >= _ALONG_NORMAL * np.linalg.norm(offset, axis=1)
                    depth[near] = np.where(along, -s, 0.0)
                yield a, b, depth


@functools.lru_cache(maxsize=8)
def _checker(rig: Rig) -> _Checker:
    dominant = rig.weight_bones[np.arange(len(rig.weights)), np.argmax(rig.weights, axis=1)]
    seg_of_bone = np.array([SEGMENTS.index(_segment_of(b)) for b in rig.bone_labels])
    vertex_segment = seg_of_bone[dominant]
    segment_vertices = tuple(np.flatnonzero(vertex_segment == s) for s in range(len(SEGMENTS)))
    # At most ~_MAX_QUERY points per segment (the head and hands are finely tessellated).
    query_positions = tuple(np.arange(0, len(v), max(1, -(-len(v) // _MAX_QUERY))) for v in segment_vertices)
    rest_normals = vertex_normals(rig.rest_vertices, rig.faces)
    n = len(SEGMENTS)
    pairs = [(a, b) for a in range(n) for b in range(n) if a != b
             and (SEGMENTS[a], SEGMENTS[b]) not in _ADJACENT and (SEGMENTS[b], SEGMENTS[a]) not in _ADJACENT]

    def grouped(masks):
        return tuple((b, tuple((a, masks[a, b]) for a in range(n) if (a, b) in masks)) for b in range(n)
                     if any((a, b) in masks for a in range(n)))

    everything = {(a, b): np.ones(len(query_positions[a]), bool) for a, b in pairs}
    provisional = _Checker(rig, segment_vertices, query_positions, rest_normals, grouped(everything))
    # Points already touching B in the reference pose are not tested against B (see the module docstring).
    # A point counts as touching when it is inside B or within REST_CONTACT_M of B's nearest vertex.
    W0 = rig.world_poses(np.tile(np.eye(4), (len(rig.bone_labels), 1, 1)))
    points, _ = provisional.posed(W0)
    masks = {}
    for a, b, depth in provisional.depths(W0):
        dist, _ = cKDTree(points[b]).query(points[a][query_positions[a]])
        mask = (depth <= 0.0) & (dist > REST_CONTACT_M)
        if mask.any():
            masks[a, b] = mask
    return _Checker(rig, segment_vertices, query_positions, rest_normals, grouped(masks))


def find_intersections(pose: BodyPose, model=None, *, rig: Rig | None = None,
                       phenotype: Mapping[str, float] | None = None) -> list[Intersection]:
    """All gross intersections of `pose` (see the module docstring for the numbers). Give `model` (with an
    optional phenotype, default anny's default body) or a prepared `rig`."""
    if rig is None:
        if model is None:
            raise ValueError("give model or rig")
        rig = rig_for(model, phenotype)
    found = []
    for a, b, depth in _checker(rig).depths(rig.world_poses(pose.deltas())):
        deep = int(np.count_nonzero(depth > DEPTH_TOL_M))
        if deep >= MIN_POINTS:
            found.append(Intersection(SEGMENTS[a], SEGMENTS[b], deep, float(depth.max())))
    return found


def intersects(pose: BodyPose, model=None, *, rig: Rig | None = None,
               phenotype: Mapping[str, float] | None = None) -> bool:
    """True when the pose has a gross self-intersection."""
    return bool(find_intersections(pose, model, rig=rig, phenotype=phenotype))
