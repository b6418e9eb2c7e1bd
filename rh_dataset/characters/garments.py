"""Garment shells cut from the body's own surface, so they are skinned by anny's weights and follow every pose.

A garment is either
- a subset of the body's faces (chosen by bone-group labels and cut-offs along the limbs and the trunk) whose
  vertices sit `offset` metres out along the posed body normal, or
- (skirts) a generated cone whose vertices are convex blends of body vertices on the hips and thighs: the blend of
  posed vertices plus an offset along the blended normal follows both legs the way a skirt does.

Layers are resolved on the body vertices: every garment's offset is at least the offset of the layers under it plus
a gap, so an outer garment never dips under an inner one. Offsets taper towards a garment's open edges so a hem
closes onto the skin (no visible gap between cloth and body at cuffs and collars).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from .body import ANNY_TOPOLOGY, body_topology
from .geometry import BodyFeatures, boundary_distance, hull_anchors, split_faces
from .recipe import Garment

__all__ = ["PartGeometry", "build_garments", "garment_vertex_mask", "BASE_OFFSET", "LAYER_GAP"]

# Cloth thickness above the skin, metres (outer garments thicker: a jacket stands off the body more than a tee).
BASE_OFFSET = {
    "shoes": 0.008,
    "trousers": 0.007,
    "shorts": 0.007,
    "skirt": 0.007,
    "tshirt": 0.006,
    "longsleeve": 0.006,
    "jacket": 0.017,
}
LAYER_GAP = 0.003  # minimum distance between two layers (well above ray-tracing epsilon at body scale)
TAPER_WIDTH = 0.025  # metres over which the offset falls towards an open edge
TAPER_MIN = 0.3  # fraction of the offset left at the very edge


@dataclasses.dataclass(frozen=True)
class PartGeometry:
    """Geometry of one character part, independent of pose.

    Posed position of split vertex i: anchor_i + offset_i * n_i, where anchor_i / n_i are the posed body vertex
    `body_vertex[i]` and its normal, or, when `blend_vertices` is set, the `blend_weights`-weighted sums of posed
    body vertices / normals (normal renormalised).
    """

    name: str
    faces: np.ndarray  # (F, 3) int32
    uvs: np.ndarray  # (V, 2) float32 in [0, 1], v up
    body_vertex: np.ndarray  # (V,) int64
    offset: np.ndarray  # (V,) float32 metres
    uv_layout: str  # "body" (anny's UV layout) or "own" (a layout generated with the part)
    metres_per_uv: float  # approximate surface metres per UV unit (pattern scale)
    blend_vertices: np.ndarray | None = None  # (V, K) int64
    blend_weights: np.ndarray | None = None  # (V, K) float32, rows sum to 1


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _z(feats: BodyFeatures, bone: str) -> float:
    return float(feats.bone_heads[bone][2])


def garment_vertex_mask(kind: str, feats: BodyFeatures) -> np.ndarray:
    """Body vertices a shell garment covers (rest pose of this phenotype)."""
    v = feats.rest_vertices
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    z_neck = _z(feats, "neck01")
    y_neck = float(feats.bone_heads["neck01"][1])
    z_hip = 0.5 * (_z(feats, "upperleg01.L") + _z(feats, "upperleg01.R"))
    z_waist = 0.5 * (_z(feats, "root") + _z(feats, "spine04")) + 0.02
    trunk = feats.in_groups("torso", "shoulder", "neck")
    arm = feats.in_groups("shoulder", "upperarm", "lowerarm")
    leg = feats.in_groups("upperleg", "lowerleg")
    if kind in ("tshirt", "longsleeve", "jacket"):
        # A scoop at the front centre: the neckline drops in front of the neck, not behind it.
        front = np.clip(-(y - y_neck) / 0.07, 0.0, 1.0) * np.clip(1.0 - np.abs(x) / 0.1, 0.0, 1.0)
        drop = {"tshirt": 0.04, "longsleeve": 0.03, "jacket": 0.06}[kind]
        z_collar = z_neck - 0.012 - drop * front
        z_hem = z_hip + {"tshirt": 0.0, "longsleeve": -0.005, "jacket": -0.02}[kind]
        sleeve = {"tshirt": 0.3, "longsleeve": 0.95, "jacket": 0.97}[kind]
        # Hem: a horizontal cut through trunk and hips alike (upper-leg labelled hip vertices included), kept above
        # the crotch so a top never turns into a bodysuit between the legs.
        hips = feats.in_groups("upperleg") & (z > z_hem)
        body = (trunk | hips) & (z < z_collar) & (z > z_hem)
        sleeves = arm & (np.nan_to_num(feats.arm_t, nan=9.0) <= sleeve) & (z < z_collar)
        return body | sleeves
    if kind in ("trousers", "shorts"):
        length = {"trousers": 0.965, "shorts": 0.42}[kind]
        legs = leg & (np.nan_to_num(feats.leg_t, nan=9.0) <= length)
        return (trunk | legs) & (z < z_waist) & ~feats.in_groups("shoulder", "neck")
    if kind == "shoes":
        foot = feats.in_groups("foot") | feats.masks["foot.L"] | feats.masks["foot.R"]
        ankle = feats.in_groups("lowerleg") & (np.nan_to_num(feats.leg_t, nan=-9.0) >= 0.95)
        return foot | ankle
    raise ValueError(f"garment_vertex_mask: {kind!r} is not a shell garment")


def _select_faces(mask: np.ndarray, topology: str) -> np.ndarray:
    """Faces with all three vertices in the mask, with small holes filled and specks removed (labels from argmax
    weights can leave a few stray faces)."""
    topo = body_topology(topology)
    sel = mask[topo.faces].all(axis=1)
    # Face adjacency through shared edges.
    f = topo.faces
    nf = len(f)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(nf), 3)
    key = e[:, 0] * topo.n_vertices + e[:, 1]
    order = np.argsort(key, kind="stable")
    k_sorted = key[order]
    same = k_sorted[1:] == k_sorted[:-1]
    a, b = fid[order][:-1][same], fid[order][1:][same]

    def components(active: np.ndarray) -> tuple[int, np.ndarray]:
        keep = active[a] & active[b]
        g = sparse.coo_matrix((np.ones(keep.sum()), (a[keep], b[keep])), shape=(nf, nf))
        return csgraph.connected_components(g, directed=False)

    n, lab = components(~sel)  # holes: small islands of unselected faces
    sizes = np.bincount(lab[~sel], minlength=n)
    small = sizes < 60
    sel = sel | (~sel & small[lab])
    n, lab = components(sel)  # specks: small islands of selected faces
    sizes = np.bincount(lab[sel], minlength=n)
    big = sizes >= 40
    sel = sel & big[lab]
    return np.flatnonzero(sel)


def _metres_per_uv(face_ids: np.ndarray, feats: BodyFeatures, topology: str) -> float:
    topo = body_topology(topology)
    tri = feats.rest_vertices[topo.faces[face_ids]]
    uv = topo.texcoords[topo.face_texcoords[face_ids]]
    a3 = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    a2 = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]).sum()
    return float(np.sqrt(a3 / max(a2, 1e-12)))


def _shell(kind: str, feats: BodyFeatures, under: np.ndarray, topology: str) -> PartGeometry:
    face_ids = _select_faces(garment_vertex_mask(kind, feats), topology)
    split = split_faces(face_ids, topology)
    dist = boundary_distance(face_ids, feats.rest_vertices, topology)
    taper = TAPER_MIN + (1.0 - TAPER_MIN) * _smoothstep(dist / TAPER_WIDTH)
    off = BASE_OFFSET[kind] * taper
    if kind == "shoes":
        # Soles: thicker where the foot faces down.
        off = off + 0.012 * np.clip(-feats.rest_normals[:, 2] - 0.3, 0.0, 1.0)
    verts = np.unique(split.body_vertex)
    need = np.where(under > 0, under + LAYER_GAP, 0.0)
    off = np.maximum(off, need)
    under[verts] = np.maximum(under[verts], off[verts])
    return PartGeometry(
        name=kind,
        faces=split.faces,
        uvs=split.uvs,
        body_vertex=split.body_vertex,
        offset=off[split.body_vertex].astype(np.float32),
        uv_layout="body",
        metres_per_uv=_metres_per_uv(face_ids, feats, topology),
    )


def _smoothing_weights(
    feats: BodyFeatures, rows: np.ndarray, radius: float = 0.03, k: int = 24, voxel: float = 0.012
) -> tuple[np.ndarray, np.ndarray]:
    """Convex weights that replace each of `rows` by a Gaussian-weighted mean (sigma = `radius`) of a coarse
    subset of the same region (one vertex per `voxel`-sized cell): a smoothing whose reach is in metres, not in
    edges, so dense detail such as toes is averaged away. Returns (indices (R, k), weights (R, k))."""
    from scipy.spatial import cKDTree

    v = feats.rest_vertices[rows]
    cell = np.floor(v / voxel).astype(np.int64)
    _, first = np.unique(cell, axis=0, return_index=True)
    coarse = rows[np.sort(first)]
    k = min(k, len(coarse))
    dist, nn = cKDTree(feats.rest_vertices[coarse]).query(v, k=k)
    dist, nn = dist.reshape(len(rows), k), nn.reshape(len(rows), k)
    wts = np.exp(-0.5 * (dist / radius) ** 2) + 1e-12
    wts /= wts.sum(axis=1, keepdims=True)
    return coarse[nn].astype(np.int64), wts


def _smooth_shell(kind: str, feats: BodyFeatures, under: np.ndarray, topology: str) -> PartGeometry:
    """A shell whose anchors are smoothed body positions (blends of a neighbourhood), so fine body detail such as
    toes disappears under the garment; the offset is raised wherever smoothing pulled the anchor inside the skin."""
    geo = _shell(kind, feats, np.zeros_like(under), topology)
    verts = np.unique(geo.body_vertex)
    idx, wts = _smoothing_weights(feats, verts)
    v, nrm = feats.rest_vertices, feats.rest_normals
    anchor = (v[idx] * wts[..., None]).sum(1)
    nb = (nrm[idx] * wts[..., None]).sum(1)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    base = np.zeros(len(v))
    base[geo.body_vertex] = geo.offset
    inside = ((v[verts] - anchor) * nb).sum(1)  # > 0: the skin sticks out beyond the smoothed anchor
    # Lift by an envelope of that protrusion (max over a 2 cm ball, then averaged over it, never below the vertex's
    # own): lifting each vertex by exactly its own protrusion would print the toes back onto the shoe.
    from scipy.spatial import cKDTree

    balls = cKDTree(v[verts]).query_ball_point(v[verts], r=0.02)
    pos = np.maximum(inside, 0.0)
    env = np.array([pos[b].max() for b in balls])
    env = np.maximum(np.array([env[b].mean() for b in balls]), pos)
    off = base[verts] + env
    # Distance of the shell above this body vertex, for the layers laid on top.
    clearance = off - inside
    need = np.where(under[verts] > 0, under[verts] + LAYER_GAP - clearance, 0.0)
    off = off + np.maximum(need, 0.0)
    under[verts] = np.maximum(under[verts], off - inside)
    row = np.searchsorted(verts, geo.body_vertex)
    return dataclasses.replace(
        geo,
        offset=off[row].astype(np.float32),
        blend_vertices=idx[row],
        blend_weights=wts[row].astype(np.float32),
    )


def _skirt(feats: BodyFeatures, under: np.ndarray, n_rings: int = 14, n_around: int = 64) -> PartGeometry:
    """A cone from the waist to above the knee: each ring is the convex hull of the hip/thigh cross-section at its
    height (so it bridges the gap between the legs), flaring out towards the hem."""
    v = feats.rest_vertices
    z_waist = 0.5 * (_z(feats, "root") + _z(feats, "spine04")) + 0.01
    z_hip = 0.5 * (_z(feats, "upperleg01.L") + _z(feats, "upperleg01.R"))
    z_knee = 0.5 * (_z(feats, "lowerleg01.L") + _z(feats, "lowerleg01.R"))
    z_hem = z_hip + 0.75 * (z_knee - z_hip)
    centre = feats.bone_heads["root"]
    cand_all = np.flatnonzero(feats.in_groups("torso", "upperleg", "lowerleg"))
    angles = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    ring_idx, ring_w, ring_pos = [], [], []
    ts = np.linspace(0.0, 1.0, n_rings)
    for t in ts:
        zc = z_waist + t * (z_hem - z_waist)
        band = cand_all[np.abs(v[cand_all, 2] - zc) < 0.012]
        idx, w = hull_anchors(v, band, centre, angles)
        ring_idx.append(idx)
        ring_w.append(w)
        ring_pos.append((v[idx] * w[..., None]).sum(1))
    flare = 0.035 + 0.03 * float(np.clip((v[:, 0].max() - v[:, 0].min()) / 1.0 - 0.9, 0.0, 1.0))
    offsets = BASE_OFFSET["skirt"] + flare * ts**1.6
    # Register the skirt's top rings as an inner layer for the tops that hang over it.
    for r in range(n_rings):
        for j in range(2):
            i = ring_idx[r][:, j]
            under[i] = np.maximum(under[i], offsets[r] + 0.004)
    # Grid with a duplicated seam column so u runs 0..1 around (seam at the back, angle 0 = front).
    cols = np.concatenate([np.arange(n_around), [0]])
    circ = float(np.linalg.norm(np.diff(np.vstack([ring_pos[-1], ring_pos[-1][:1]]), axis=0)[:, :2], axis=1).sum())
    length = float(np.linalg.norm(np.diff(np.array([p.mean(0) for p in ring_pos]), axis=0), axis=1).sum()) + 0.05
    bv, bw, uvs, off = [], [], [], []
    for r in range(n_rings):
        for c_i, c in enumerate(cols):
            bv.append(np.pad(ring_idx[r][c], (0, 2)))
            bw.append(np.pad(ring_w[r][c], (0, 2)))
            u = c_i / n_around
            uvs.append((u, (1.0 - ts[r]) * length / circ))
            off.append(offsets[r])
    ncol = n_around + 1
    faces = []
    for r in range(n_rings - 1):
        for c in range(n_around):
            a, b = r * ncol + c, r * ncol + c + 1
            d, e = a + ncol, b + ncol
            # Angles grow from -Y towards +X (clockwise seen from above), rings go down: (a, d, b) faces outwards.
            faces += [(a, b, d), (b, e, d)]
    bv = np.array(bv, dtype=np.int64)
    bw = np.array(bw, dtype=np.float32)
    return PartGeometry(
        name="skirt",
        faces=np.array(faces, dtype=np.int32),
        uvs=np.clip(np.array(uvs, dtype=np.float32), 0.0, 1.0),
        body_vertex=bv[np.arange(len(bv)), np.argmax(bw, axis=1)],
        offset=np.array(off, dtype=np.float32),
        uv_layout="own",
        metres_per_uv=circ,
        blend_vertices=bv,
        blend_weights=bw,
    )


def build_garments(
    garments: tuple[Garment, ...],
    feats: BodyFeatures,
    topology: str = ANNY_TOPOLOGY,
    under: np.ndarray | None = None,
) -> list[PartGeometry]:
    """Geometry of every garment, innermost first, with layer offsets resolved.

    `under` (V,) float64, if given, holds per body vertex the outermost offset already used (zeros = bare skin);
    it is updated in place so that hair laid afterwards can stay outside the clothes.
    """
    if under is None:
        under = np.zeros(len(feats.rest_vertices))
    out = []
    for g in garments:
        if g.kind == "skirt":
            out.append(_skirt(feats, under))
        elif g.kind == "shoes":
            out.append(_smooth_shell(g.kind, feats, under, topology))
        else:
            out.append(_shell(g.kind, feats, under, topology))
    return out
