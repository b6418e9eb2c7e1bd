"""Mesh utilities shared by garments, hair and textures: seam splitting, surface distances, anchoring points to the
body, clearance, UV rasterisation, tubes.

In: anny's topology (by name), vertex/normal arrays and index selections. Out: split meshes (`split_faces`),
per-vertex distances (`boundary_distance`, `surface_clearance`), ray distances to a mesh (`first_hit`, trimesh),
blend weights that make a point follow the posed body (`hull_anchors`, `smoothing_weights`, `bind_points` ->
`Binding`), compacted meshes (`drop_unreferenced`), the texel -> (face, barycentrics) map of anny's UV layout
(`uv_raster`) and capped tubes (`closed_tube`).
Body features (bone groups, masks) are `body_features`'s.
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
    "SplitMesh",
    "split_faces",
    "boundary_distance",
    "hull_anchors",
    "smoothing_weights",
    "Binding",
    "bind_points",
    "surface_clearance",
    "drop_unreferenced",
    "uv_raster",
    "closed_tube",
    "first_hit",
]


@dataclasses.dataclass(frozen=True)
class SplitMesh:
    """A subset of the body's faces with vertices split at UV seams (what a renderer with per-vertex UVs needs)."""

    faces: np.ndarray  # (F, 3) int32 into the split vertices
    uvs: np.ndarray  # (V, 2) float32, v up
    body_vertex: np.ndarray  # (V,) int64 body vertex each split vertex follows
    body_faces: np.ndarray  # (F,) int64 index of each face in the body's face list


def split_faces(face_ids: np.ndarray, topology: str = ANNY_TOPOLOGY) -> SplitMesh:
    """One split vertex per unique (body vertex, UV index) pair among the corners of the selected faces."""
    topo = body_topology(topology)
    face_ids = np.asarray(face_ids, dtype=np.int64)
    fv = topo.faces[face_ids]
    ft = topo.face_texcoords[face_ids]
    key = fv.astype(np.int64) * (len(topo.texcoords) + 1) + ft
    uniq, inverse = np.unique(key.ravel(), return_inverse=True)
    body_vertex = uniq // (len(topo.texcoords) + 1)
    uv_index = uniq % (len(topo.texcoords) + 1)
    return SplitMesh(
        faces=inverse.reshape(-1, 3).astype(np.int32),
        uvs=topo.texcoords[uv_index].astype(np.float32),
        body_vertex=body_vertex.astype(np.int64),
        body_faces=face_ids,
    )


def boundary_distance(face_ids: np.ndarray, vertices: np.ndarray, topology: str = ANNY_TOPOLOGY) -> np.ndarray:
    """Distance along the surface (shortest path over mesh edges) from each body vertex of the selected faces to
    the open boundary of the selection; inf for vertices outside it. Used to taper garment and hair offsets so a
    hem closes onto the skin instead of leaving a visible gap."""
    topo = body_topology(topology)
    f = topo.faces[np.asarray(face_ids, dtype=np.int64)]
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    boundary = np.unique(uniq[counts == 1].ravel())
    n = topo.n_vertices
    w = np.linalg.norm(vertices[uniq[:, 0]] - vertices[uniq[:, 1]], axis=1) + 1e-9
    graph = sparse.coo_matrix((w, (uniq[:, 0], uniq[:, 1])), shape=(n, n)).tocsr()
    if len(boundary) == 0:
        out = np.full(n, np.inf)
        out[np.unique(f)] = 1.0
        return out
    return csgraph.dijkstra(graph, directed=False, indices=boundary, min_only=True)


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


def first_hit(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each unit direction (broadcast to origins' shape) from each origin to the first triangle of
    the mesh it hits (trimesh ray casting); inf where the ray misses."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces), process=False)
    o = np.asarray(origins, np.float64)
    d = np.ascontiguousarray(np.broadcast_to(np.asarray(directions, np.float64), o.shape))
    loc, ray, _ = mesh.ray.intersects_location(o, d, multiple_hits=True)
    out = np.full(len(o), np.inf)
    np.minimum.at(out, ray, ((loc - o[ray]) * d[ray]).sum(1))
    return out
