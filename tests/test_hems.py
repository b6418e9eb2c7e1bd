"""Garment shells cut along a level set (garments.garment_level, geometry.split_faces(level=...)): the cut is exact
and watertight, the open edges are closed manifold loops, smoother than keeping whole faces, closed onto the skin,
and the same bits every time."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from rh_common.body_model import ANNY_TOPOLOGY
from rh_dataset.characters import recipe_from_seed
from rh_dataset.characters.body import PHENOTYPE_LABELS, body_topology
from rh_dataset.characters.body_features import body_features
from rh_dataset.characters.garments import (
    BASE_OFFSET,
    SHELL_KINDS,
    TAPER_MIN,
    _clean_level,
    build_garments,
    garment_level,
)
from rh_dataset.characters.geometry import boundary_loops, edge_roughness, split_faces
from rh_dataset.characters.recipe import Garment

# 1/m, every open edge of every shell kind (geometry.edge_roughness; bench/bench_hems.py measured worst 40.1 on
# benchmark seeds 2, 4, 6, where whole faces read up to 95; 40.5 on the all-ones phenotype)
ROUGHNESS_MAX = 45.0


@pytest.fixture(scope="module", params=[2, 6, "ones"])
def phenotype(request):
    if request.param == "ones":  # the heaviest, tallest, most muscular corner of anny's phenotype space
        return {k: 1.0 for k in PHENOTYPE_LABELS}
    return recipe_from_seed(request.param, "benchmark", 0).phenotype


@pytest.fixture(scope="module")
def feats(phenotype):
    return body_features(phenotype)


def _shell(kind, feats):
    return build_garments((Garment(kind, (0.5, 0.5, 0.5)),), feats)[0]


def _rest(part, feats) -> np.ndarray:
    w = part.blend_weights.astype(np.float64)[..., None]
    v, n = feats.rest_vertices, feats.rest_normals
    nb = (n[part.blend_vertices] * w).sum(1)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    return (v[part.blend_vertices] * w).sum(1) + part.offset[:, None] * nb


def test_split_without_a_cut_is_the_plain_split():
    """A level negative everywhere keeps every face whole: the same split as no level, to the bit."""
    topo = body_topology()
    faces = np.arange(0, len(topo.faces), 3)
    a = split_faces(faces)
    b = split_faces(faces, level=np.full(topo.n_vertices, -1.0))
    for f in ("faces", "uvs", "body_vertex", "body_faces", "cut_vertex", "cut_t"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert np.all(a.cut_t == 0) and np.array_equal(a.cut_vertex, a.body_vertex)


def test_cut_vertices_lie_on_the_level_and_the_cut_is_watertight(feats):
    topo = body_topology()
    level = _clean_level(garment_level("longsleeve", feats), ANNY_TOPOLOGY)
    sel = np.flatnonzero((level[topo.faces] < 0).any(axis=1))
    split = split_faces(sel, level=level)
    cut = split.cut_t > 0
    assert cut.sum() > 100
    # The level interpolated along each cut vertex's edge is zero there (to the clamp of CUT_T_MIN).
    la, lb = level[split.body_vertex[cut]], level[split.cut_vertex[cut]]
    t = split.cut_t[cut]
    tol = 2e-3 * np.abs(la - lb)
    assert np.all(np.abs((1 - t) * la + t * lb) <= tol)
    assert np.all(la < 0) and np.all(lb > 0)
    # Every cut face lies inside its body face; the welded mesh is consistently wound, every edge used at most twice.
    weld = split.welded()
    mesh = trimesh.Trimesh(np.zeros((weld.max() + 1, 3)), weld[split.faces], process=False)
    counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)[1]
    assert counts.max() <= 2
    pos = np.zeros((weld.max() + 1, 3))
    pos[weld] = split.points(feats.rest_vertices)
    mesh = trimesh.Trimesh(pos, weld[split.faces], process=False)
    assert mesh.is_winding_consistent
    assert mesh.area_faces.min() > 0
    # The cut keeps the area the level set covers: between whole faces only and every face touched.
    whole = (level[topo.faces[sel]] < 0).all(axis=1)
    body = trimesh.Trimesh(feats.rest_vertices, topo.faces, process=False)
    assert body.area_faces[sel[whole]].sum() < mesh.area < body.area_faces[sel].sum()


def _roughness(kind, feats):
    """Roughness of every open edge of a shell, and of the same level set kept as whole faces (the old shells:
    keep a face when all its corners are inside, drop it otherwise)."""
    part = _shell(kind, feats)
    pos = _rest(part, feats)
    loops = boundary_loops(pos, part.faces)  # raises unless every open edge closes into a simple loop
    topo = body_topology()
    level = _clean_level(garment_level(kind, feats), ANNY_TOPOLOGY)
    old = split_faces(np.flatnonzero((level[topo.faces] < 0).all(axis=1)))
    old_pos = feats.rest_vertices[old.body_vertex] + BASE_OFFSET[kind] * feats.rest_normals[old.body_vertex]
    old_loops = boundary_loops(old_pos, old.faces)
    return part, pos, [edge_roughness(lp) for lp in loops], [edge_roughness(lp) for lp in old_loops]


@pytest.mark.parametrize("kind", SHELL_KINDS)
def test_edges_are_closed_smooth_loops_on_the_skin(kind, feats):
    """Open edges: closed manifold loops, as many as the garment has openings, each below ROUGHNESS_MAX and
    smoother than whole faces on the same level; the edge sits the taper's minimum above the skin (closed onto it,
    no gap)."""
    part, pos, rough, old_rough = _roughness(kind, feats)
    assert len(rough) == {"tshirt": 4, "longsleeve": 4, "jacket": 4, "trousers": 3, "shorts": 3}[kind]
    assert max(rough) < ROUGHNESS_MAX, rough
    assert np.median(rough) < np.median(old_rough), (rough, old_rough)
    # On the edge: the smallest offset, measured as the distance to the body surface (trimesh closest points).
    edge = part.blend_weights[:, 1] > 0
    body = trimesh.Trimesh(feats.rest_vertices, body_topology().faces, process=False)
    _, dist, _ = trimesh.proximity.closest_point(body, pos[edge])
    assert np.all(dist <= TAPER_MIN * BASE_OFFSET[kind] + 5e-4), dist.max()
    np.testing.assert_allclose(part.offset[edge], TAPER_MIN * BASE_OFFSET[kind], rtol=1e-5)


def test_cut_edges_are_much_smoother_than_whole_faces(feats):
    """Over every opening of every shell kind, the median roughness is well under that of whole faces."""
    new, old = [], []
    for kind in SHELL_KINDS:
        _, _, r, o = _roughness(kind, feats)
        new += r
        old += o
    assert np.median(new) < 0.6 * np.median(old), (np.median(new), np.median(old))  # measured 0.42-0.47


def test_shells_are_deterministic(feats):
    kinds = (Garment("trousers", (0.5, 0.5, 0.5)), Garment("longsleeve", (0.5, 0.5, 0.5)),
             Garment("jacket", (0.5, 0.5, 0.5)))
    a, b = build_garments(kinds, feats), build_garments(kinds, feats)
    for pa, pb in zip(a, b):
        for f in ("faces", "uvs", "body_vertex", "offset", "blend_vertices", "blend_weights", "body_faces"):
            x, y = getattr(pa, f), getattr(pb, f)
            assert x.dtype == y.dtype and np.array_equal(x, y), (pa.name, f)


def test_posed_edges_stay_closed_onto_the_skin(phenotype, feats):
    """In a pose (elbow and knee bent, shoulder raised), every cut vertex of a sleeve and a trouser leg is outside
    the posed skin and within the taper's minimum (+ 0.5 mm) of it: the blend along the body edge moves with it
    (measured: 1.8-2.1 mm off the skin, the minimum, and at least 0.85 mm outside it along the face normal)."""
    from rh_dataset.characters.body import run_anny
    from rh_dataset.mesh import vertex_normals
    from rh_dataset.characters.body import anchor_points

    def rot(axis, deg):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        m = np.eye(4)
        a = np.radians(deg)
        m[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
        return m

    pose = {"upperarm01.L": rot([0, 1, 0], -40), "lowerarm01.L": rot([0, 0, 1], 60),
            "lowerleg01.L": rot([1, 0, 0], 50)}
    topo = body_topology()
    v = run_anny(phenotype, pose)["vertices"]
    n = vertex_normals(v, topo.faces)
    body = trimesh.Trimesh(v, topo.faces, process=False)
    for kind in ("longsleeve", "tshirt", "trousers", "shorts"):
        part = _shell(kind, feats)
        pos = anchor_points(v, n, part.blend_vertices, part.blend_weights, part.offset)
        edge = part.blend_weights[:, 1] > 0
        closest, dist, tri = trimesh.proximity.closest_point(body, pos[edge])
        outward = ((pos[edge] - closest) * body.face_normals[tri]).sum(1)
        assert np.all(outward > 0), kind
        assert np.all(dist <= TAPER_MIN * BASE_OFFSET[kind] + 0.5e-3), (kind, dist.max())
