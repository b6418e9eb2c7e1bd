"""Geometry the camera cannot see, found before a scene is built, so it is never loaded.

Two kinds, each sound only where stated:

* **Skin hidden under clothes** (`hidden_faces`): body triangles covered by a garment shell (a garment cut from
  the body's own faces, offset outwards; a triangle the shell's edge cuts is not covered) or enclosed by a closed
  garment (shoes, hair buns), and at least `margin` metres along the skin from any uncovered skin. Such skin is
  never seen (a primary ray meets the cloth first) and is lit only through the thin gap at the openings, which the
  margin keeps it away from; so it neither appears in any layer nor changes the light elsewhere beyond what
  bench/bench_savings.py measures (docs/TRADEOFFS.md). Valid for every pass. Computed once per character, on the A-pose: the coverage is topological (garments follow
  the skinning), and the margin absorbs how far a pose stretches the skin.

* **Triangles outside the view frustum** (`outside_frustum`): only for passes that see nothing but primary hits (the
  AOV pass). A path-traced pass must keep them: off-screen geometry still shadows and reflects onto what is seen.
  A triangle is dropped when its three vertices lie outside one and the same plane of the frustum widened by
  `margin_px` pixels on every side (or all behind the near plane); such a triangle cannot cover any pixel. The
  test is conservative: a triangle outside the frustum but straddling two planes is kept.
"""
from __future__ import annotations

import dataclasses
from typing import Mapping, Sequence

import numpy as np

__all__ = ["HIDDEN_MARGIN_M", "FRUSTUM_MARGIN_PX", "hidden_faces", "outside_frustum", "drop_faces"]

HIDDEN_MARGIN_M = 0.04
"""Distance along the skin from the nearest uncovered skin below which covered skin is kept. Garments stand
0.6-1.7 cm off the skin and close onto it at hems; seeing 4 cm into such a gap needs a view within ~10 degrees of
the skin's tangent plane, and light entering there is absorbed long before."""
FRUSTUM_MARGIN_PX = 2.0
"""Widening of the frustum for the AOV pass: the box pixel filter samples only inside a pixel, so 1 px would do;
2 px also absorbs float32 rounding of the projection."""

_cache: dict[tuple[str, float], dict[str, np.ndarray]] = {}


def _weld(vertices: np.ndarray) -> np.ndarray:
    """Index of each vertex's welded copy (same position to 1e-6 m): seams duplicate vertices for their UVs."""
    key = np.round(np.asarray(vertices, np.float64) / 1e-6).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    return inv.ravel()


def _is_closed(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge of the welded mesh shared by exactly two faces: the mesh bounds a volume."""
    w = _weld(vertices)[faces]
    e = np.sort(np.concatenate([w[:, [0, 1]], w[:, [1, 2]], w[:, [2, 0]]]), axis=1)
    e = e[e[:, 0] != e[:, 1]]  # collapsed edges at tube poles
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(len(counts)) and bool(np.all(counts == 2))


def _winding_number(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, chunk: int = 64) -> np.ndarray:
    """Generalised winding number of a closed triangle mesh at each point (1 inside, 0 outside, sign by orientation),
    by the solid angle each triangle subtends (Van Oosterom & Strackee 1983)."""
    tri = np.asarray(vertices, np.float32)[faces]  # (F, 3, 3); float32 is ample for a 0.5 threshold
    out = np.zeros(len(points))
    for s in range(0, len(points), chunk):
        p = np.asarray(points[s:s + chunk], np.float32)
        a, b, c = (tri[None, :, k, :] - p[:, None, :] for k in range(3))
        la, lb, lc = (np.sqrt(np.einsum("pfi,pfi->pf", x, x)) for x in (a, b, c))
        bxc = np.empty_like(b)
        bxc[..., 0] = b[..., 1] * c[..., 2] - b[..., 2] * c[..., 1]
        bxc[..., 1] = b[..., 2] * c[..., 0] - b[..., 0] * c[..., 2]
        bxc[..., 2] = b[..., 0] * c[..., 1] - b[..., 1] * c[..., 0]
        det = np.einsum("pfi,pfi->pf", a, bxc)
        den = la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la \
            + np.einsum("pfi,pfi->pf", c, a) * lb
        out[s:s + chunk] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def hidden_faces(character, margin: float = HIDDEN_MARGIN_M) -> dict[str, np.ndarray]:
    """{part name: boolean mask over that part's faces of the faces never seen}; only the body part has any.

    Pure function of the character (its recipe) and `margin`; cached per (recipe, margin)."""
    key = (character.recipe.to_json_text(), float(margin))
    if key not in _cache:
        if len(_cache) > 8:
            _cache.clear()
        _cache[key] = _hidden_faces(character, float(margin))
    return _cache[key]


def _hidden_faces(character, margin: float) -> dict[str, np.ndarray]:
    from scipy import sparse
    from scipy.sparse import csgraph

    from rh_dataset.characters import pose_character

    body = character.part("body")
    tri = body.body_vertex[body.faces]  # body faces as triples of anny vertices
    n = int(body.body_vertex.max()) + 1
    posed = {m.name: m for m in pose_character(character, None, None)}
    pos = np.zeros((n, 3))
    pos[body.body_vertex] = posed["body"].vertices

    covered = np.zeros(len(tri), bool)
    inside = np.zeros(n, bool)
    for part in character.parts:
        if part.name == "body":
            continue
        if part.body_faces is not None:
            # A shell cut from the body's faces, offset outwards: the faces it copies whole are under it (a face
            # it cuts is partly bare skin).
            whole = (part.blend_weights.max(axis=1) == 1.0)[part.faces].all(axis=1)
            shell = whole & (part.offset[part.faces].min(axis=1) > 0.0)
            covered[part.body_faces[shell]] = True
        elif _is_closed(posed[part.name].vertices, part.faces):
            # A closed garment (shoes, a bun): the skin inside its volume.
            pv = posed[part.name].vertices
            lo, hi = pv.min(0) - 1e-3, pv.max(0) + 1e-3
            # Only skin not already under a shell and within the garment's box can newly turn out hidden.
            free = np.ones(n, bool)
            free[np.unique(tri[covered])] = False
            cand = np.flatnonzero(free & np.all((pos >= lo) & (pos <= hi), axis=1))
            if len(cand):
                inside[cand] |= np.abs(_winding_number(pos[cand], pv, part.faces)) > 0.5
    candidate = covered | inside[tri].all(axis=1)
    # Distance along the skin (over mesh edges) from the skin that stays exposed.
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    w = np.linalg.norm(pos[e[:, 0]] - pos[e[:, 1]], axis=1) + 1e-12
    graph = sparse.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    exposed = np.unique(tri[~candidate].ravel())
    if len(exposed) == 0:
        return {"body": candidate}
    dist = csgraph.dijkstra(graph, directed=False, indices=exposed, min_only=True)
    hidden = candidate & (dist[tri] >= margin).all(axis=1)
    return {"body": hidden}


def outside_frustum(vertices: np.ndarray, faces: np.ndarray, camera, margin_px: float = FRUSTUM_MARGIN_PX,
                    near: float = 0.01) -> np.ndarray:
    """Boolean mask of the faces whose three vertices are outside one common plane of the widened frustum."""
    V = np.asarray(vertices, np.float64)
    w2c = camera.world_to_camera
    pc = V @ w2c[:3, :3].T + w2c[:3, 3]  # OpenCV camera axes: x right, y down, z forward
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    K = camera.K
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    m = float(margin_px)
    # Planes through the camera centre, written without dividing by z so points behind the camera classify right:
    # u >= -m  <=>  fx x + (cx + m) z >= 0 for z > 0, and the same sign test bounds the half-space for any z.
    planes = np.stack([
        fx * x + (cx + m) * z,
        (camera.width + m - cx) * z - fx * x,
        fy * y + (cy + m) * z,
        (camera.height + m - cy) * z - fy * y,
        z - near,
    ], axis=1)
    out = planes < 0.0  # (V, 5): outside each plane
    F = np.asarray(faces, np.int64)
    return (out[F[:, 0]] & out[F[:, 1]] & out[F[:, 2]]).any(axis=1)


def drop_faces(meshes: Sequence, masks: Mapping[str, np.ndarray] | Sequence[np.ndarray]) -> tuple[list, int]:
    """The meshes without the masked faces (a mesh left with none is dropped); and how many faces went.

    `masks`: {mesh name: face mask} (meshes not named keep every face) or one mask per mesh, in order."""
    if isinstance(masks, Mapping):
        masks = [masks.get(m.name) for m in meshes]
    if len(masks) != len(meshes):
        raise ValueError(f"drop_faces: {len(masks)} masks for {len(meshes)} meshes")
    out, dropped = [], 0
    for m, mask in zip(meshes, masks):
        if mask is None or not np.any(mask):
            out.append(m)
            continue
        if len(mask) != len(m.faces):
            raise ValueError(f"cull mask for {m.name} has {len(mask)} entries for {len(m.faces)} faces")
        dropped += int(np.count_nonzero(mask))
        if not np.all(mask):
            out.append(dataclasses.replace(m, faces=np.ascontiguousarray(np.asarray(m.faces)[~np.asarray(mask)])))
    return out, dropped
