"""Mesh utilities shared by garments, hair and textures: seam splitting, surface distances, anchoring points to the
body, clearance, UV rasterisation, tubes.

In: anny's topology (by name), vertex/normal arrays and index selections. Out: split meshes (`split_faces`, cut along a
level set when asked), per-vertex distances (`boundary_distance`, `surface_clearance`), a mesh's open edges as loops and
their roughness (`boundary_loops`, `edge_roughness`), distinct rows and each row's index among them (`unique_rows`: the
welds of seam copies), ray distances to a mesh (`first_hit`, trimesh), a trimesh for closest-point and ray queries whose
rays' search tree is bulk-loaded on first use (`query_mesh`), exact closest points on a mesh (`closest_point`, libigl)
and the faces a box touches, to search only those (`faces_in_box`),
blend weights that make a point follow the posed body (`hull_anchors`, `smoothing_weights`, `bind_points` -> `Binding`),
compacted meshes (`drop_unreferenced`), the texel -> (face, barycentrics) map of anny's UV layout (`uv_raster`), capped
tubes (`closed_tube`) and the smoothstep every cut and fade blends with (`smoothstep`). Body features (bone groups,
masks) are `body_features`'s.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
from PIL import Image, ImageDraw
from scipy import ndimage, sparse
from scipy.sparse import csgraph
from scipy.spatial import ConvexHull, cKDTree

from rh_common.body_model import ANNY_TOPOLOGY

from .body import body_topology
from .body_features import BodyFeatures

__all__ = [
    "smoothstep",
    "closest_point",
    "faces_in_box",
    "edge_counts",
    "unique_rows",
    "SplitMesh",
    "split_faces",
    "boundary_distance",
    "boundary_loops",
    "edge_roughness",
    "hull_anchors",
    "smoothing_weights",
    "Binding",
    "bind_points",
    "surface_clearance",
    "drop_unreferenced",
    "uv_raster",
    "closed_tube",
    "first_hit",
    "query_mesh",
]


@dataclasses.dataclass(frozen=True)
class SplitMesh:
    """A subset of the body's faces with vertices split at UV seams (what a renderer with per-vertex UVs needs),
    optionally cut along a level set (`split_faces(level=...)`): a cut vertex lies on the body edge from
    `body_vertex` (inside) to `cut_vertex` (outside), at fraction `cut_t` of the way; other vertices have
    cut_vertex == body_vertex and cut_t == 0."""

    faces: np.ndarray  # (F, 3) int32 into the split vertices
    uvs: np.ndarray  # (V, 2) float32, v up
    body_vertex: np.ndarray  # (V,) int64 body vertex each split vertex follows (a cut vertex: its inside end)
    body_faces: np.ndarray  # (F,) int64 index of the body face each face lies in
    cut_vertex: np.ndarray  # (V,) int64 the other end of a cut vertex's body edge (= body_vertex when not cut)
    cut_t: np.ndarray  # (V,) float64 in [0, 1): how far along that edge

    def points(self, vertices: np.ndarray) -> np.ndarray:
        """Positions (V, 3) float64 of the split vertices on a body surface given by its vertices (any pose)."""
        t = self.cut_t[:, None]
        return (1.0 - t) * vertices[self.body_vertex] + t * vertices[self.cut_vertex]

    def welded(self) -> np.ndarray:
        """(V,) int64 index of each split vertex among the distinct surface points (UV-seam copies share one)."""
        return unique_rows(np.stack([self.body_vertex, self.cut_vertex], 1))[1]


CUT_T_MIN = 1e-3  # a cut point never sits closer than this fraction of its edge to a vertex (no zero-area faces)


def smoothstep(x):
    """3x^2 - 2x^3 of x clipped to [0, 1] (an array, or a float64 scalar for a scalar): 0 below 0, 1 above 1, with
    zero slope at both ends, so a blend or fade over it has no corner."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def split_faces(face_ids: np.ndarray, topology: str = ANNY_TOPOLOGY, level: np.ndarray | None = None) -> SplitMesh:
    """One split vertex per unique (body vertex, UV index) pair among the corners of the selected faces.

    `level` (V,) per body vertex, if given, cuts the selection along its zero level set and keeps the side where
    it is negative: a face with all corners inside is kept whole, one with none dropped, and one that straddles
    the level is replaced by its inside part (a triangle or a quad, as one or two triangles) whose new corners lie
    on the crossed edges where the linearly interpolated level is zero. A cut vertex is shared by both faces of its
    edge (per UV index pair, like any split vertex), so the result is as watertight as the selection and its open
    edges follow the level set instead of the triangles' zigzag."""
    topo = body_topology(topology)
    face_ids = np.asarray(face_ids, dtype=np.int64)
    fv = topo.faces[face_ids].astype(np.int64)
    ft = topo.face_texcoords[face_ids].astype(np.int64)
    if level is None:
        inside = np.ones(fv.shape, dtype=bool)
    else:
        level = np.asarray(level, dtype=np.float64)
        if level.shape != (topo.n_vertices,) or not np.all(np.isfinite(level)):
            raise ValueError(f"split_faces: level must be ({topo.n_vertices},) finite values, one per body vertex")
        inside = level[fv] < 0.0
    n_in = inside.sum(1)
    # Corner records (inside vertex a, outside vertex b, their UV indices); an uncut corner is (a, a, ta, ta).
    rec, src = [], []

    def corner(rows, k):
        c = np.arange(len(rows))
        return np.stack([fv[rows, k[c]], fv[rows, k[c]], ft[rows, k[c]], ft[rows, k[c]]], 1)

    def crossing(rows, k_in, k_out):
        c = np.arange(len(rows))
        return np.stack([fv[rows, k_in[c]], fv[rows, k_out[c]], ft[rows, k_in[c]], ft[rows, k_out[c]]], 1)

    whole = np.flatnonzero(n_in == 3)
    if len(whole):
        rec.append(np.stack([corner(whole, np.full(len(whole), k)) for k in range(3)], 1))
        src.append(whole)
    one = np.flatnonzero(n_in == 1)  # the inside corner first, then the two crossings (winding kept)
    if len(one):
        k0 = np.argmax(inside[one], axis=1)
        k1, k2 = (k0 + 1) % 3, (k0 + 2) % 3
        rec.append(np.stack([corner(one, k0), crossing(one, k0, k1), crossing(one, k0, k2)], 1))
        src.append(one)
    two = np.flatnonzero(n_in == 2)  # corners k0, k1 inside, k2 outside: quad k0, k1, x12, x02 as two triangles
    if len(two):
        k2 = np.argmin(inside[two], axis=1)
        k0, k1 = (k2 + 1) % 3, (k2 + 2) % 3
        c0, c1 = corner(two, k0), corner(two, k1)
        x12, x02 = crossing(two, k1, k2), crossing(two, k0, k2)
        rec.append(np.stack([c0, c1, x12], 1))
        rec.append(np.stack([c0, x12, x02], 1))
        src += [two, two]
    if not rec:
        raise ValueError("split_faces: nothing selected (no face has a corner inside the level set)")
    rec = np.concatenate(rec)  # (F', 3, 4)
    body_faces = face_ids[np.concatenate(src)]
    order = np.argsort(body_faces, kind="stable")  # faces in body order (a cut quad's two halves together)
    rec, body_faces = rec[order], body_faces[order]
    uniq, inverse = unique_rows(rec.reshape(-1, 4))
    a, b, ta, tb = uniq.T
    t = np.zeros(len(uniq))
    cut = a != b
    if cut.any():
        la, lb = level[a[cut]], level[b[cut]]
        t[cut] = np.clip(la / (la - lb), CUT_T_MIN, 1.0 - CUT_T_MIN)
    tex = topo.texcoords.astype(np.float64)
    uvs = (1.0 - t)[:, None] * tex[ta] + t[:, None] * tex[tb]
    return SplitMesh(
        faces=inverse.reshape(-1, 3).astype(np.int32),
        uvs=uvs.astype(np.float32),
        body_vertex=a.astype(np.int64),
        body_faces=body_faces,
        cut_vertex=b.astype(np.int64),
        cut_t=t,
    )


def edge_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unique edges (E, 2) int64 of a triangle mesh, each (low, high), and how many faces share each: 1 on an
    open edge (a hem, a cut), 2 inside a manifold surface. Sorted by (low, high), as `np.unique(..., axis=0)` sorts
    them; found through one int64 key per edge (low * n + high), ~9x faster than that row-wise unique on the body's
    faces (posing asks for every layer's open edges, `cloth_pose._surface`)."""
    f = np.asarray(faces, np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    if not len(e):
        return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    n = int(e[:, 1].max()) + 1
    key, counts = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    return np.stack([key // n, key % n], axis=1), counts


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of `rows` (N, C) in lexicographic order and, for each row, the index of its own among them
    (N,) int64: what `np.unique(rows, axis=0, return_inverse=True)` returns (rows equal but for the sign of a zero
    are one, as there), by a lexsort of the columns: ~3.5x faster for the welds posing does every frame (a scratch
    timing; tests/test_geometry.py compares them)."""
    a = np.asarray(rows)
    if a.ndim != 2:
        raise ValueError(f"unique_rows: rows must be (N, C), got shape {a.shape}")
    if not len(a):
        return a.copy(), np.zeros(0, np.int64)
    order = np.lexsort(a.T[::-1])
    ordered = a[order]
    new = np.ones(len(a), bool)
    new[1:] = (ordered[1:] != ordered[:-1]).any(axis=1)
    inverse = np.empty(len(a), np.int64)
    inverse[order] = np.cumsum(new) - 1
    return ordered[new], inverse


def boundary_distance(split: SplitMesh, vertices: np.ndarray) -> np.ndarray:
    """Distance along the surface (shortest path over the mesh's edges, UV-seam copies welded) from each split
    vertex to the mesh's open boundary, on the body surface given by `vertices`; cut vertices of a level-set cut
    lie on that boundary (0). Used to taper garment offsets so a hem closes onto the skin instead of leaving a
    visible gap."""
    weld = split.welded()
    n = int(weld.max()) + 1
    pos = np.zeros((n, 3))
    pos[weld] = split.points(vertices)
    f = weld[split.faces]
    uniq, counts = edge_counts(f)
    boundary = np.unique(uniq[counts == 1].ravel())
    if len(boundary) == 0:
        return np.ones(len(weld))
    w = np.linalg.norm(pos[uniq[:, 0]] - pos[uniq[:, 1]], axis=1) + 1e-9
    graph = sparse.coo_matrix((w, (uniq[:, 0], uniq[:, 1])), shape=(n, n)).tocsr()
    return csgraph.dijkstra(graph, directed=False, indices=boundary, min_only=True)[weld]


def boundary_loops(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray]:
    """The open edges of a mesh as closed loops of points ((n, 3) each, the first point not repeated), vertices at
    equal positions (UV-seam copies) welded first. Raises if an open edge's vertex has more than two open edges
    (the boundary is not a set of simple loops)."""
    import trimesh

    key = np.round(np.asarray(vertices, np.float64) / 1e-7).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64)[first], inv.ravel()[faces], process=False)
    edges = mesh.edges_sorted[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    if len(edges) == 0:
        return []
    if np.any(np.bincount(edges.ravel()) > 2):
        raise ValueError("boundary_loops: a vertex has more than two open edges (boundary not manifold)")
    loops = []
    for comp in trimesh.graph.connected_components(edges):
        nxt = {}
        sub = edges[np.isin(edges[:, 0], comp)]
        for a, b in sub:
            nxt.setdefault(a, []).append(b)
            nxt.setdefault(b, []).append(a)
        if any(len(v) != 2 for v in nxt.values()):
            raise ValueError("boundary_loops: an open boundary does not close into a loop")
        start = int(comp[0])
        order, prev, cur = [start], -1, start
        while True:
            a, b = nxt[cur]
            step = a if a != prev else b
            if step == start:
                break
            order.append(step)
            prev, cur = cur, step
        if len(order) != len(comp):
            raise ValueError("boundary_loops: an open boundary does not close into a single loop")
        loops.append(mesh.vertices[order])
    return loops


def edge_roughness(loop: np.ndarray, step: float = 0.005) -> float:
    """Roughness of a closed curve (n, 3), 1/m: how much its curvature varies beyond that of a circle of the same
    length, sqrt(mean(k^2) - (2 pi / L)^2) over the curve resampled every `step` metres of arc length (k from second
    differences). 0 for a circle (of any size); for a plane convex curve, the standard deviation of its curvature
    (its mean is 2 pi / L). A zigzag that follows the triangles reads several times a smooth cut's value."""
    p = np.concatenate([loop, loop[:1]])
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(int(round(s[-1] / step)), 8)
    q = np.stack([np.interp(np.arange(n) * s[-1] / n, s, p[:, k]) for k in range(3)], 1)
    h = s[-1] / n
    k = np.linalg.norm(np.roll(q, -1, 0) - 2.0 * q + np.roll(q, 1, 0), axis=1) / h**2
    return float(np.sqrt(max(np.mean(k**2) - (2.0 * np.pi / s[-1]) ** 2, 0.0)))


def hull_anchors(
    vertices: np.ndarray,
    candidates: np.ndarray,
    centre: np.ndarray,
    angles: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """For rays from `centre` (xy) at `angles` (radians, measured from -Y towards +X), where they leave the convex
    hull of the candidate vertices' xy positions: each exit point as a blend of two hull vertices.

    Returns (indices (N, 2) int64 body vertices, weights (N, 2) float64). A blend of posed vertices then follows
    the pose, which is how skirts and hanging hair are skinned without their own weights.
    """
    pts = vertices[candidates, :2]
    hull = ConvexHull(pts)
    ring = hull.vertices  # counter-clockwise
    a = pts[ring] - centre[:2]
    b = np.roll(a, -1, axis=0)
    idx = np.zeros((len(angles), 2), dtype=np.int64)
    wts = np.zeros((len(angles), 2))
    for k, ang in enumerate(angles):
        d = np.array([np.sin(ang), -np.cos(ang)])
        # Solve centre + s d = a + t (b - a) for every edge; keep the one with t in [0, 1] and s > 0.
        e = b - a
        den = d[0] * (-e[:, 1]) - d[1] * (-e[:, 0])
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (a[:, 0] * (-e[:, 1]) - a[:, 1] * (-e[:, 0])) / den
            t = (d[0] * a[:, 1] - d[1] * a[:, 0]) / den
        ok = (t >= -1e-9) & (t <= 1 + 1e-9) & (s > 0) & np.isfinite(s)
        j = int(np.flatnonzero(ok)[np.argmax(s[ok])]) if ok.any() else int(np.argmax(a @ d))
        tt = float(np.clip(t[j], 0.0, 1.0)) if ok.any() else 0.0
        idx[k] = (candidates[ring[j]], candidates[ring[(j + 1) % len(ring)]])
        wts[k] = (1.0 - tt, tt)
    return idx, wts


def smoothing_weights(
    vertices: np.ndarray, rows: np.ndarray, radius: float = 0.03, k: int = 24, voxel: float = 0.012
) -> tuple[np.ndarray, np.ndarray]:
    """Convex weights that replace each of `rows` by a Gaussian-weighted mean (sigma = `radius`) of a coarse
    subset of the same region (one vertex per `voxel`-sized cell): a smoothing whose reach is in metres, not in
    edges, so dense detail such as toes is averaged away. Returns (indices (R, k), weights (R, k))."""
    rows = np.asarray(rows, dtype=np.int64)
    v = vertices[rows]
    cell = np.floor(v / voxel).astype(np.int64)
    _, first = np.unique(cell, axis=0, return_index=True)
    coarse = rows[np.sort(first)]
    k = min(k, len(coarse))
    dist, nn = cKDTree(vertices[coarse]).query(v, k=k)
    dist, nn = dist.reshape(len(rows), k), nn.reshape(len(rows), k)
    wts = np.exp(-0.5 * (dist / radius) ** 2) + 1e-12
    wts /= wts.sum(axis=1, keepdims=True)
    return coarse[nn].astype(np.int64), wts


@dataclasses.dataclass(frozen=True)
class Binding:
    """Points expressed in the anchoring scheme of `PartGeometry`: point_i = sum_k w_ik v[idx_ik] + offset_i * n_i,
    n_i = normalise(sum_k w_ik n[idx_ik]) over posed body vertices v / normals n. `error` (N,) metres is how far
    the rest-pose reconstruction lies from the requested point (0 where the projection converged)."""

    blend_vertices: np.ndarray  # (N, K) int64
    blend_weights: np.ndarray  # (N, K) float32, rows sum to 1
    offset: np.ndarray  # (N,) float32 >= 0
    error: np.ndarray  # (N,) float64

    @property
    def body_vertex(self) -> np.ndarray:
        return self.blend_vertices[np.arange(len(self.blend_vertices)), np.argmax(self.blend_weights, axis=1)]


def _barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
    d20, d21 = (v2 * v0).sum(-1), (v2 * v1).sum(-1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) < 1e-20, 1e-20, den)
    y = (d11 * d20 - d01 * d21) / den
    z = (d00 * d21 - d01 * d20) / den
    return np.stack([1.0 - y - z, y, z], axis=-1)


def bind_points(
    points: np.ndarray,
    region: np.ndarray,
    feats: BodyFeatures,
    topology: str = ANNY_TOPOLOGY,
    smooth_radius: float = 0.02,
    n_candidates: int = 16,
    iterations: int = 12,
) -> Binding:
    """Bind rest-pose points to the body ("wrap"): each point becomes a blend of body vertices plus an offset along
    the blended normal, the anchoring `pose_character` already applies to skirts and hanging hair.

    The anchor surface is the body's faces inside `region` (a vertex mask or index array), with every vertex
    replaced by a Gaussian blend of its neighbourhood (`smooth_radius` metres; 0 = the raw surface), so hair that
    stands off the head follows a smooth frame instead of the skin's facets. Each point is projected along the
    interpolated normal field (not to the closest point): a fixed-point iteration finds, on the best of the nearest
    `n_candidates` faces, barycentrics b with point = B(b) + d n(b), which the pose then reproduces exactly in the
    rest pose and moves with the skin in any other."""
    topo = body_topology(topology)
    v, n = feats.rest_vertices, feats.rest_normals
    pts = np.asarray(points, dtype=np.float64)
    inreg = np.zeros(len(v), dtype=bool)
    inreg[np.asarray(region)] = True
    faces = topo.faces[inreg[topo.faces].all(axis=1)]
    used = np.unique(faces)
    if smooth_radius > 0:
        sidx, sw = smoothing_weights(v, used, radius=smooth_radius)
    else:
        sidx, sw = used[:, None], np.ones((len(used), 1))
    local = np.full(len(v), -1, dtype=np.int64)
    local[used] = np.arange(len(used))
    fl = local[faces]
    S = (v[sidx] * sw[..., None]).sum(1)  # smoothed positions
    N = (n[sidx] * sw[..., None]).sum(1)  # unnormalised smoothed normals (what the pose blends)
    tri = S[fl]  # (F, 3, 3)
    k = min(n_candidates, len(fl))
    _, cand = cKDTree(tri.mean(1)).query(pts, k=k)
    cand = cand.reshape(len(pts), k)
    A, B, C = tri[cand, 0], tri[cand, 1], tri[cand, 2]  # (P, k, 3)
    NA, NB, NC = N[fl[cand, 0]], N[fl[cand, 1]], N[fl[cand, 2]]
    fn = np.cross(B - A, C - A)
    fn /= np.maximum(np.linalg.norm(fn, axis=-1, keepdims=True), 1e-20)
    P = pts[:, None, :]
    bc = _barycentric(P - ((P - A) * fn).sum(-1, keepdims=True) * fn, A, B, C)
    for _ in range(iterations):
        bc = np.clip(bc, 0.0, None)
        bc /= bc.sum(-1, keepdims=True)
        nb = bc[..., :1] * NA + bc[..., 1:2] * NB + bc[..., 2:] * NC
        nb /= np.maximum(np.linalg.norm(nb, axis=-1, keepdims=True), 1e-20)
        den = (nb * fn).sum(-1, keepdims=True)
        den = np.where(np.abs(den) < 1e-3, np.copysign(1e-3, den), den)
        t = ((P - A) * fn).sum(-1, keepdims=True) / den
        bc = _barycentric(P - t * nb, A, B, C)
    bc = np.clip(bc, 0.0, None)
    bc /= bc.sum(-1, keepdims=True)
    base = bc[..., :1] * A + bc[..., 1:2] * B + bc[..., 2:] * C
    nb = bc[..., :1] * NA + bc[..., 1:2] * NB + bc[..., 2:] * NC
    nb /= np.maximum(np.linalg.norm(nb, axis=-1, keepdims=True), 1e-20)
    d = ((P - base) * nb).sum(-1)
    dd = np.maximum(d, 0.0)
    err = np.linalg.norm(P - (base + dd[..., None] * nb), axis=-1)
    best = np.argmin(err + 1e-6 * np.arange(k)[None, :], axis=1)  # ties: the nearest candidate
    rows = np.arange(len(pts))
    face = cand[rows, best]
    b = bc[rows, best]  # (P, 3)
    ks = sidx.shape[1]
    bv = sidx[fl[face]].reshape(len(pts), 3 * ks)
    bw = (b[:, :, None] * sw[fl[face]]).reshape(len(pts), 3 * ks)
    bw /= bw.sum(1, keepdims=True)
    return Binding(bv.astype(np.int64), bw.astype(np.float32), dd[rows, best].astype(np.float32), err[rows, best])


def surface_clearance(
    points: np.ndarray, vertices: np.ndarray, normals: np.ndarray, candidates: np.ndarray, k: int = 6
) -> np.ndarray:
    """Approximate signed distance of points above a surface given as vertices with normals (> 0 outside): the
    height above the tangent plane of the nearest of `k` candidate vertices, taken at the most negative of them
    when the point lies within their spacing (so a point sunk between two vertices is not missed)."""
    cand = np.asarray(candidates, dtype=np.int64)
    dist, nn = cKDTree(vertices[cand]).query(points, k=min(k, len(cand)))
    dist, nn = dist.reshape(len(points), -1), nn.reshape(len(points), -1)
    idx = cand[nn]
    h = ((points[:, None, :] - vertices[idx]) * normals[idx]).sum(-1)
    near = dist <= dist[:, :1] * 1.5 + 1e-9
    return np.where(near, h, np.inf).min(axis=1)


def drop_unreferenced(vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray):
    """Remove vertices no face uses (e.g. the spare copy of a pole at a UV seam); returns (vertices, faces, uvs)."""
    used = np.unique(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces], uvs[used]


@functools.lru_cache(maxsize=4)
def uv_raster(resolution: int, topology: str = ANNY_TOPOLOGY) -> tuple[np.ndarray, np.ndarray]:
    """Which body face and which barycentric weights every texel of a (res x res) texture in anny's UV layout
    belongs to. Texels outside every UV island take their nearest covered texel, so attributes baked through this
    map are defined everywhere (no black bleeding at island borders under bilinear filtering).

    Returns (face (H, W) int64, bary (H, W, 3) float32); row 0 is the top of the image (v = 1).
    """
    topo = body_topology(topology)
    res = int(resolution)
    uv = topo.texcoords[topo.face_texcoords]  # (F, 3, 2)
    px = np.stack([uv[..., 0] * res, (1.0 - uv[..., 1]) * res], axis=-1)
    im = Image.new("I", (res, res), 0)  # 32-bit: face id + 1
    draw = ImageDraw.Draw(im)
    for fid, tri in enumerate(px):
        draw.polygon([tuple(p) for p in (tri - 0.5)], fill=fid + 1)
    face = np.asarray(im, dtype=np.int64) - 1
    covered = face >= 0
    _, (ri, ci) = ndimage.distance_transform_edt(~covered, return_indices=True)
    face = face[ri, ci]
    rows, cols = np.mgrid[0:res, 0:res]
    p = np.stack([cols + 0.5, rows + 0.5], axis=-1).astype(np.float64)
    tri = px[face]  # (H, W, 3, 2)
    v0 = tri[..., 1, :] - tri[..., 0, :]
    v1 = tri[..., 2, :] - tri[..., 0, :]
    v2 = p - tri[..., 0, :]
    den = v0[..., 0] * v1[..., 1] - v1[..., 0] * v0[..., 1]
    den = np.where(np.abs(den) < 1e-12, 1e-12, den)
    b1 = (v2[..., 0] * v1[..., 1] - v1[..., 0] * v2[..., 1]) / den
    b2 = (v0[..., 0] * v2[..., 1] - v2[..., 0] * v0[..., 1]) / den
    bary = np.stack([1 - b1 - b2, b1, b2], axis=-1)
    # Texels snapped from outside an island extrapolate; clamping keeps baked values within the face's range.
    bary = np.clip(bary, 0.0, 1.0)
    bary /= bary.sum(-1, keepdims=True)
    face.setflags(write=False)
    bary = bary.astype(np.float32)
    bary.setflags(write=False)
    return face, bary


def closed_tube(rings: np.ndarray, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closed tube through `rings` (S, K, 3), capped by pole points `start` and `end`.

    Returns vertices ((S + 2) * (K + 1), 3), a grid whose seam column is duplicated so UVs can wrap, and faces
    (int64). Shared by shoes and hair buns/ponytails.
    """
    S, K, _ = rings.shape
    grid = np.concatenate([np.repeat(start[None, None], K + 1, 1), np.concatenate([rings, rings[:, :1]], 1),
                           np.repeat(end[None, None], K + 1, 1)], 0)  # (S + 2, K + 1, 3)
    n_rows, n_cols = S + 2, K + 1
    faces = []
    for j in range(n_rows - 1):
        for c in range(n_cols - 1):
            a, b = j * n_cols + c, j * n_cols + c + 1
            d, e = a + n_cols, b + n_cols
            if j == 0:
                faces.append((a, d, e))
            elif j == n_rows - 2:
                faces.append((a, d, b))
            else:
                faces += [(a, d, b), (b, d, e)]
    return grid.reshape(-1, 3), np.array(faces, dtype=np.int64)


def seamed_grid(grid: np.ndarray, start: int, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A tube's render grid: `grid` (rings, around) its vertex indices into `points` (V, 3), the first column
    repeated at the end so UVs can run 0..1 round it. Returns (full (rings, around + 1): the source vertex of each
    render vertex, faces (F, 3) of the render vertices numbered from `start` row by row, arc (rings, around + 1):
    metres along each ring from its first column through `points`)."""
    rows, cols = grid.shape
    full = np.concatenate([grid, grid[:, :1]], axis=1)
    local = start + np.arange(rows * (cols + 1)).reshape(rows, cols + 1)
    a, c = local[:-1, :-1], local[1:, :-1]
    b, d = local[:-1, 1:], local[1:, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    arc = np.concatenate([np.zeros((rows, 1)), np.cumsum(np.linalg.norm(np.diff(points[full], axis=1), axis=-1), 1)],
                         axis=1)
    return full, faces, arc


def metre_uvs(us: list[np.ndarray], vs: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """UVs (R, 2) in [0, 1] from per-piece metres along (`us`) and up (`vs`) a cut, u shifted to start at 0, both over
    one scale (the larger span), and that scale in metres per UV: the draped pieces' render meshes."""
    u, v = np.concatenate(us), np.concatenate(vs)
    u -= u.min()
    mpu = float(max(u.max(), v.max()))
    return np.clip(np.stack([u, v], 1) / mpu, 0.0, 1.0), mpu


def query_mesh(vertices: np.ndarray, faces: np.ndarray):
    """A `trimesh.Trimesh` of (`vertices`, `faces`) (not processed) for closest-point (`closest_point`) and ray
    queries, whose triangles' search tree for rays (`triangles_tree`, an rtree of the faces' boxes) is bulk-loaded
    from numpy arrays on first use.

    Why bulk: trimesh builds that tree by streaming one Python tuple per face into rtree (`trimesh.util.bounds_tree`),
    ~30 ms for a few thousand faces; rtree's bulk load from arrays is the same libspatialindex bulk load over the same
    boxes in the same order, ~5x faster: the same tree, so the same candidates in the same order and the same ray
    hits to the bit (tests/test_geometry.py compares them). Why on first use: closest points come from libigl's own
    tree, and most of posing's meshes are only asked for those; building every mesh's rtree up front was ~10 % of a
    loose subject's posing (bench/bench_posing.py)."""
    return _query_mesh_type()(np.asarray(vertices, np.float64), np.asarray(faces), process=False)


@functools.cache
def _query_mesh_type():
    """`query_mesh`'s trimesh subclass (made on first use, so importing this module does not import trimesh)."""
    import rtree
    import trimesh

    class QueryMesh(trimesh.Trimesh):
        @property
        def triangles_tree(self):
            tree = self._cache["triangles_tree"]  # None if absent; cleared when the vertices or faces change
            if tree is None:
                tri = self.triangles
                if not len(tri):
                    return super().triangles_tree  # trimesh's own (no faces: it raises, as before)
                tree = rtree.index.Index((np.arange(len(tri), dtype=np.int64), tri.min(axis=1), tri.max(axis=1)),
                                         properties=rtree.index.Property(dimension=3))
                self._cache["triangles_tree"] = tree
            return tree

    return QueryMesh


def closest_point(mesh, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest point on the triangle mesh `mesh` (a trimesh, e.g. `query_mesh`'s) to each of `points` (P, 3):
    (closest points (P, 3), distances (P,), index of the face each lies on (P,)), as trimesh.proximity.closest_point
    returns them, from libigl's AABB tree, built on the first query and kept in the mesh's cache (dropped with it
    when the mesh's arrays change).

    Why not trimesh's: (1) speed: for each point it boxes the faces out to the nearest vertex in an rtree (~35
    candidate faces a point on a posed body) and tests every one in numpy, a Python loop per point picking the best
    two; posing made ~60 such queries a frame, ~70 % of a loose subject's posing in a profile (docs/TRADEOFFS.md). (2)
    Exactness: where its two best faces lie within `tol.merge` (1e-8) in *squared* distance it takes the one whose
    normal faces the point, which in metres, millimetres from a surface, is up to ~15 micrometres farther than the
    closest (measured on posed cloth; libigl's answer is the brute-force minimum: tests/test_geometry.py). Where a
    closest point lies on a corner or an edge, several faces hold it: the face named is the one whose normal faces
    the point best (`_facing_face`), trimesh's rule for its two best."""
    import igl

    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    v = np.ascontiguousarray(mesh.vertices, np.float64)
    f = np.ascontiguousarray(mesh.faces, np.int64)
    if not len(p):
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
    if not len(f):
        raise ValueError("closest_point: the mesh has no faces")
    tree = mesh._cache["rh_igl_aabb"]  # trimesh's cache (None if absent): cleared when the vertices or faces change
    if tree is None:
        tree = igl.AABB()
        tree.init(v, f)
        mesh._cache["rh_igl_aabb"] = tree
    sq, tri, closest = tree.squared_distance(v, f, p)
    return closest, np.sqrt(sq), _facing_face(mesh, p, closest, tri)


def faces_in_box(vertices: np.ndarray, faces: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(F,) bool: the faces whose bounding boxes meet the box [lo, hi] (3,) each. Closest-point queries of points
    in a region search only these (with the box grown by how far the answer can lie), not the whole body."""
    v = np.asarray(vertices)
    f = np.asarray(faces)
    c0, c1, c2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]  # elementwise over the corners: ~3x a reduce over axis 1
    return ((np.maximum(np.maximum(c0, c1), c2) >= lo) & (np.minimum(np.minimum(c0, c1), c2) <= hi)).all(axis=1)


def _facing_face(mesh, points: np.ndarray, closest: np.ndarray, tri: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Of the faces that share a closest point on a corner or an edge (all equally close), the one whose normal
    faces the point best, as trimesh's query chose between its two best: the face a closest point names decides
    which cloth triangle `cloth_pose.lift_over_skin` moves, and libigl names whichever its tree met first (with it,
    a seated knee's skin through the trousers went from 17 to 35 vertices, tests/test_cloth_pose.py, slow). `tol`:
    barycentric coordinates under it put the closest point on the face's boundary. Equal normals (coplanar faces)
    go to the higher-numbered face. Only the faces round those corners are looked at (`_faces_round`), not the
    whole mesh's face normals and vertex -> faces table."""
    import trimesh

    f = np.asarray(mesh.faces)
    v = np.asarray(mesh.vertices)
    with np.errstate(invalid="ignore", divide="ignore"):
        bary = trimesh.triangles.points_to_barycentric(v[f[tri]], closest)
    on = np.isfinite(bary).all(1) & (bary < tol).any(1)
    off = points - closest
    size = np.linalg.norm(off, axis=1)
    idx = np.flatnonzero(on & (size > 0.0))
    if not len(idx):
        return tri
    corners = f[tri[idx]]  # (n, 3)
    keep = bary[idx] >= tol  # the corners spanning the corner or edge the closest point lies on
    first = corners[np.arange(len(idx)), np.argmax(keep, axis=1)]
    cand = _faces_round(f, first)  # (n, D), -1 padded: the faces round that corner
    ok = cand >= 0
    cf = f[np.where(ok, cand, 0)]  # (n, D, 3)
    for k in range(3):  # ... that hold every spanning corner
        need = np.where(keep[:, k], corners[:, k], -1)
        ok &= (need[:, None] < 0) | (cf == need[:, None, None]).any(-1)
    normals, valid = trimesh.triangles.normals(v[cf.reshape(-1, 3)])
    unit = np.zeros((cf.shape[0] * cf.shape[1], 3))
    unit[valid] = normals  # degenerate faces: a zero normal, as trimesh's face_normals gives them
    dots = (unit.reshape(cf.shape) * (off[idx] / size[idx, None])[:, None, :]).sum(-1)
    best = cand[np.arange(len(idx)), np.argmax(np.where(ok, dots, -np.inf), axis=1)]
    out = tri.copy()
    out[idx] = best
    return out


def _faces_round(faces: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """For each vertex index in `corners` (n,), the faces that use it, highest index first, padded with -1: (n, D)
    (the rows of trimesh's `vertex_faces` for those vertices, without building the whole table)."""
    uniq, inv = np.unique(corners, return_inverse=True)
    face, col = np.nonzero(np.isin(faces, uniq))
    vert = faces[face, col]
    order = np.lexsort((-face, vert))  # by vertex, then face descending
    vert, face = vert[order], face[order]
    start = np.searchsorted(vert, uniq)
    count = np.searchsorted(vert, uniq, side="right") - start
    out = np.full((len(uniq), int(count.max())), -1, np.int64)
    out[np.repeat(np.arange(len(uniq)), count), np.arange(len(vert)) - np.repeat(start, count)] = face
    return out[inv]


def first_hit(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each unit direction (broadcast to origins' shape) from each origin to the first triangle of
    the mesh it hits (trimesh ray casting); inf where the ray misses."""
    mesh = query_mesh(vertices, faces)
    o = np.asarray(origins, np.float64)
    d = np.ascontiguousarray(np.broadcast_to(np.asarray(directions, np.float64), o.shape))
    loc, ray, _ = mesh.ray.intersects_location(o, d, multiple_hits=True)
    out = np.full(len(o), np.inf)
    np.minimum.at(out, ray, ((loc - o[ray]) * d[ray]).sum(1))
    return out
