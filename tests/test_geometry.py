"""`geometry.query_mesh`: a trimesh whose triangles' search tree is bulk-loaded from numpy arrays answers closest-point
and ray queries exactly as trimesh's own (the same tree: the same candidates, in the same order), on anny's body and
on a local piece of it as `drape.push_out` cuts one."""
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
        assert ours.triangles_tree is ours.triangles_tree  # cached: built once, at construction
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
