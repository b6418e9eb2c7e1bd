"""`geometry.query_mesh`: a trimesh whose triangles' search tree is bulk-loaded from numpy arrays on first use answers
closest-point and ray queries exactly as trimesh's own (the same tree: the same candidates, in the same order), on
anny's body and on a local piece of it as `drape.push_out` cuts one; `geometry.closest_point` (libigl) against the
brute-force minimum, and the face it names where several hold the closest point."""
from __future__ import annotations

import numpy as np
import trimesh

from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.characters.geometry import query_mesh
from test_drape_coat import PHENO


def test_query_mesh_answers_as_trimesh_does():
    v = run_anny(PHENO)["vertices"]
    f = body_topology().faces
    rng = np.random.default_rng(3)
    for faces in (f, f[(v[f][:, :, 2] > np.median(v[:, 2])).all(axis=1)]):  # the whole body; its upper half
        ours, theirs = query_mesh(v, faces), trimesh.Trimesh(v, faces, process=False)
        assert ours._cache["triangles_tree"] is None  # not built until a query needs it
        assert ours.triangles_tree is ours.triangles_tree  # then built once, and cached
        centres = v[rng.choice(len(v), 200)]
        boxes = np.c_[centres - 0.03, centres + 0.03]
        for box in boxes:  # the same candidates in the same order
            assert list(ours.triangles_tree.intersection(box)) == list(theirs.triangles_tree.intersection(box))
        pts = v[rng.choice(len(v), 400)] + rng.normal(0.0, 0.02, (400, 3))
        for a, b in zip(trimesh.proximity.closest_point(ours, pts), trimesh.proximity.closest_point(theirs, pts)):
            np.testing.assert_array_equal(a, b)
        d = rng.normal(size=(400, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        for a, b in zip(ours.ray.intersects_id(pts, d, multiple_hits=True, return_locations=True),
                        theirs.ray.intersects_id(pts, d, multiple_hits=True, return_locations=True)):
            np.testing.assert_array_equal(a, b)
    assert len(query_mesh(v, f[:0]).faces) == 0  # no faces: no tree to build


def test_closest_point_is_the_brute_force_minimum():
    """`geometry.closest_point` (libigl's AABB tree, kept in the mesh's cache): on anny's body and on a rumpled cloth
    patch with squashed triangles, every point's distance is the minimum over all faces (trimesh's closest point
    on each triangle, brute force), the closest point lies that far from the point, and so does the face it names. And
    where trimesh's own query takes a face up to its tie tolerance (1e-8 in squared distance) farther because its
    normal faces the point: a point 0.30 mm from one face's edge and 0.305 mm straight over another face gets the
    first."""
    from rh_dataset.characters.geometry import closest_point

    def brute(mesh, pts):
        tri = mesh.triangles
        return np.array([np.linalg.norm(trimesh.triangles.closest_point(tri, np.repeat(p[None], len(tri), 0)) - p,
                                         axis=1).min() for p in pts])

    rng = np.random.default_rng(5)
    v = run_anny(PHENO)["vertices"]
    f = body_topology().faces
    x, y = np.meshgrid(np.linspace(0, 0.1, 12), np.linspace(0, 0.1, 12))
    cloth_v = np.c_[x.ravel(), y.ravel(), 0.01 * np.sin(40 * x.ravel()) * np.cos(30 * y.ravel())]
    cloth_v[5] = cloth_v[6]  # two vertices pushed onto one point: squashed triangles
    idx = np.arange(144).reshape(12, 12)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    cloth_f = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    for mesh, pts in ((query_mesh(v, f), v[rng.choice(len(v), 150)] + rng.normal(0.0, 0.01, (150, 3))),
                      (query_mesh(cloth_v, cloth_f), rng.uniform([-0.02, -0.02, -0.03], [0.12, 0.12, 0.03],
                                                                 (150, 3)))):
        closest, dist, tri = closest_point(mesh, pts)
        assert mesh._cache["rh_igl_aabb"] is not None  # the tree is kept for the next query
        assert mesh._cache["triangles_tree"] is None  # closest points never build the rays' rtree
        np.testing.assert_allclose(dist, brute(mesh, pts), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(closest - pts, axis=1), dist, rtol=0, atol=1e-12)
        on_face = trimesh.triangles.closest_point(mesh.triangles[tri], pts)  # the face it names is that close
        np.testing.assert_allclose(np.linalg.norm(on_face - pts, axis=1), dist, rtol=0, atol=1e-12)
    # One face with its edge at x = 0 (x <= 0, z = 0), another 0.305 mm straight under a point 0.300 mm from that
    # edge, its normal pointing at the point.
    tri_v = np.array([[-0.01, -0.01, 0.0], [0.0, -0.01, 0.0], [0.0, 0.01, 0.0],
                      [5e-5, -0.01, -2.2e-5], [2e-4, -0.01, -2.2e-5], [5e-5, 0.01, -2.2e-5]])
    mesh = query_mesh(tri_v, np.array([[0, 1, 2], [3, 4, 5]]))
    p = np.array([[1e-4, 0.0, 2.83e-4]])
    closest, dist, tri = closest_point(mesh, p)
    assert tri[0] == 0 and abs(dist[0] - np.linalg.norm(p)) < 1e-15, (tri, dist)
    assert len(closest_point(mesh, np.zeros((0, 3)))[0]) == 0


def test_faces_round_a_corner_are_trimeshs_vertex_faces():
    """`geometry._faces_round` (the faces `closest_point` weighs where a closest point lies on a corner or an edge)
    gives, for the vertices asked, trimesh's `vertex_faces` rows (highest face first, -1 padded), on the body and on
    a shuffled subset of its faces, and on a mesh with a degenerate face (a vertex used twice)."""
    from rh_dataset.characters.geometry import _faces_round

    v = run_anny(PHENO)["vertices"]
    f = body_topology().faces
    rng = np.random.default_rng(11)
    for faces in (f, f[rng.permutation(len(f))[:4000]]):
        corners = rng.choice(np.unique(faces), 500)  # repeats included
        ours, theirs = _faces_round(faces, corners), trimesh.Trimesh(v, faces, process=False).vertex_faces[corners]
        assert ours.shape[1] <= theirs.shape[1] and (theirs[:, ours.shape[1]:] == -1).all()
        np.testing.assert_array_equal(ours, theirs[:, :ours.shape[1]])
    tiny = np.array([[0, 1, 2], [0, 0, 3], [2, 1, 3]])  # face 1 uses vertex 0 twice
    np.testing.assert_array_equal(_faces_round(tiny, np.array([3, 0, 1])), [[2, 1, -1], [1, 1, 0], [2, 0, -1]])


def test_edge_counts_are_the_row_wise_unique():
    """`geometry.edge_counts` (one int64 key per edge) returns exactly what `np.unique(sorted edges, axis=0,
    return_counts=True)` does, in the same order: on the body, a shuffled subset of its faces and no faces."""
    from rh_dataset.characters.geometry import edge_counts

    f = body_topology().faces
    rng = np.random.default_rng(2)
    for faces in (f, f[rng.permutation(len(f))[:3000]], f[:0]):
        e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64), axis=1)
        want, want_counts = np.unique(e.reshape(-1, 2), axis=0, return_counts=True)
        got, got_counts = edge_counts(faces)
        assert got.dtype == np.int64 and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(got_counts, want_counts)


def test_anchor_sums_are_numpys_sum_to_the_bit():
    """`body.anchor_points` and `body.blended_normals` sum their K weighted body rows as a sparse product
    (`body._weighted_rows`): the same bits as numpy's `(rows[idx] * w[..., None]).sum(1)` for any K (both add along
    that axis in order; past 8 terms a pairwise sum would differ), int32 or int64 indices, repeated indices in a row,
    and zeros for K = 0."""
    from rh_dataset.characters.body import _weighted_rows, anchor_points

    rng = np.random.default_rng(4)
    v = run_anny(PHENO)["vertices"]
    n = rng.normal(size=v.shape)
    for k in (0, 1, 3, 4, 8, 9, 16, 17):
        bv = rng.integers(0, len(v), (500, k)).astype(np.int32 if k % 2 else np.int64)
        if k > 2:
            bv[:50, 1] = bv[:50, 0]  # a body vertex twice in one row
        bw = rng.random((500, k)).astype(np.float32)
        np.testing.assert_array_equal(_weighted_rows(v, bv, bw), (v[bv] * bw.astype(np.float64)[..., None]).sum(1))
        if k:
            off = rng.normal(0.0, 0.01, 500).astype(np.float32)
            nb = (n[bv] * bw.astype(np.float64)[..., None]).sum(1)
            unit = nb / np.maximum(np.linalg.norm(nb, axis=1, keepdims=True), 1e-12)
            want = (v[bv] * bw.astype(np.float64)[..., None]).sum(1) + off[:, None].astype(np.float64) * unit
            np.testing.assert_array_equal(anchor_points(v, n, bv, bw, off), want)


def test_unique_rows_is_numpys_unique_over_rows():
    """`geometry.unique_rows` (a lexsort) returns what `np.unique(rows, axis=0, return_inverse=True)` does: the same
    distinct rows in the same order and the same inverse, for int rows with negatives and repeats (the welds' grid
    keys), float rows (positions) and no rows."""
    from rh_dataset.characters.geometry import unique_rows

    rng = np.random.default_rng(9)
    keys = np.round(rng.normal(0.0, 0.3, (4000, 3)) / 1e-6).astype(np.int64)
    keys[2000:] = keys[rng.integers(0, 2000, 2000)]  # seam copies
    small = rng.integers(-3, 3, (500, 4))  # many ties in the first columns
    pos = np.round(rng.normal(size=(3000, 3)), 2)
    pos[1500:] = pos[:1500]
    for rows in (keys, small, pos, keys[:0], keys[:1]):
        want_rows, want_inv = np.unique(rows, axis=0, return_inverse=True)
        got_rows, got_inv = unique_rows(rows)
        np.testing.assert_array_equal(got_rows, want_rows)
        np.testing.assert_array_equal(got_inv, want_inv.ravel())
        assert got_inv.dtype == np.int64 and got_rows.dtype == rows.dtype


def test_vertex_normals_sum_as_add_at_did_to_the_bit():
    """mesh.vertex_normals adds each vertex's face normals by one bincount over corner 0, 1, then 2 of every face:
    the same order, so the same bits, as the np.add.at loop it replaced, on the body's topology (random vertices,
    and an isolated vertex, which gets +Z) and with no faces."""
    from rh_dataset.mesh import vertex_normals

    def add_at(vertices, faces):
        v = np.asarray(vertices, dtype=np.float64)
        tri = v[faces]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n = np.zeros_like(v)
        for corner in range(3):
            np.add.at(n, faces[:, corner], fn)
        length = np.linalg.norm(n, axis=1, keepdims=True)
        bad = length[:, 0] < 1e-20
        n[bad], length[bad] = (0.0, 0.0, 1.0), 1.0
        return n / length

    faces = body_topology().faces
    rng = np.random.default_rng(5)
    for _ in range(3):
        v = rng.normal(size=(int(faces.max()) + 2, 3))  # the last vertex is in no face
        got = vertex_normals(v, faces)
        assert np.array_equal(got, add_at(v, faces)) and np.array_equal(got[-1], [0.0, 0.0, 1.0])
    assert np.array_equal(vertex_normals(v[:4], np.zeros((0, 3), np.int64)), np.tile([0.0, 0.0, 1.0], (4, 1)))
