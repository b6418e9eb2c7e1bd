"""Draped garments (rh_dataset/characters/drape.py): the skirt pattern, the skinning transfer, and (slow) newton's
drape: bit-identical reruns and cloth that stays outside the body in the rest pose and in sampled poses."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.mesh import vertex_normals
from rh_dataset.characters.drape import (DRAPED_KINDS, PROFILES, PUSH_CLEARANCE, bind_loose, bind_to_skeleton,
                                         collider_faces, drape_garment, drape_settings, garment_pattern, penetration,
                                         push_out, skin_points)
from rh_dataset.characters.geometry import edge_counts
from rh_dataset.characters.recipe import LOOSE_TOPS

PHENO = {"gender": 1.0, "age": 0.6, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5}
# Worst cloth-vertex depth under the skin (metres) allowed. newton keeps the particles `clearance` (4 mm) off the
# body in the rest pose, to within its contact stiffness; in a pose, linear-blend skinning alone lets a thigh swing
# into a hanging skirt (bench/bench_cloth.py: up to ~10 cm when sitting), and `push_out` moves those vertices back
# out to PUSH_CLEARANCE above the skin at their closest skin point, walking those a crease pinches (the thighs in
# the prior's seated poses, where a push out of one thigh lands in the other) out along the crease's bisector:
# nothing is left under the skin in any pose (before the walk, 3 December: skirt 1.17 / 2.25 mm deep in the two
# seated poses, dress 1.29 / 2.00 mm).
REST_BOUND_M = 0.002
POSED_BOUND_M = 0.0
# One closed tube; trousers: test_drape_trousers.py, the open coat: test_drape_coat.py, the hood: test_drape_hoodie.py.
# The skirt and the dress; the loose tops (recipe.LOOSE_TOPS, cut to the hips) have their own checks:
# tests/test_drape_tshirt.py, and the hoodie's body, their cut: tests/test_drape_hoodie.py.
TUBE_KINDS = tuple(k for k in DRAPED_KINDS if k in PROFILES and not PROFILES[k].legs and not PROFILES[k].opening
                   and k not in LOOSE_TOPS + ("draped_hoodie_body",))


def _a_pose_heads() -> dict[str, np.ndarray]:
    """Bone heads of the test phenotype's A-pose (the frame the cloth is draped in; anny's bind space is ~9 cm
    higher)."""
    run = run_anny(PHENO)
    return {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}


@pytest.mark.parametrize("kind", TUBE_KINDS)
def test_pattern_is_an_outward_tube_outside_the_body(kind):
    verts, faces, uvs, pinned, circ = garment_pattern(kind, PHENO)
    st = drape_settings(kind)
    assert verts.shape == (st.n_around * st.n_rings, 3) and pinned.sum() == st.n_around
    # Every interior edge is shared by two faces, the two boundary rings' edges by one: an open tube.
    _, counts = edge_counts(faces)
    assert set(counts.tolist()) == {1, 2} and (counts == 1).sum() == 2 * st.n_around
    # Faces point away from the body's vertical axis.
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    radial = tri.mean(1) - verts[:st.n_around].mean(0)
    radial[:, 2] = 0.0
    assert ((n * radial).sum(1) > 0).all()
    run = run_anny(PHENO)
    assert penetration(run["vertices"], body_topology().faces, verts).max() < 0.0
    assert uvs.min() >= 0.0 and uvs.max() <= 1.0 and circ > 0.5
    # Held where the profile says: the skirt's waistband between the pelvis and spine03, the dress's top under the
    # arms (between spine03 and spine01); both hems cut to end above the knee (the dress's settles at the knee:
    # test_drape_is_bit_identical_and_stays_outside_the_body).
    heads = _a_pose_heads()
    top, hem = verts[0, 2], verts[-1, 2]
    if kind == "draped_skirt":
        assert heads["root"][2] < top < heads["spine03"][2]
    else:
        assert heads["spine03"][2] <= top < heads["spine01"][2]
        assert penetration(run["vertices"], body_topology().faces, verts[pinned]).max() < -0.003  # arms too
    assert 0.05 < hem - heads["lowerleg01.L"][2] < 0.2


def test_dress_top_keeps_off_the_arms_of_heavy_bodies():
    """The dress's top ring is lowered (`_under_the_arms`) where the A-pose arm presses the trunk: for benchmark
    dress wearers of every build, the pinned ring keeps off the whole body, arms included."""
    from rh_dataset.characters.recipe_draws import recipe_from_seed

    rs = [recipe_from_seed(2 * k, "benchmark", k) for k in range(40)]
    phs = [r.phenotype for r in rs if r.garment("draped_dress") is not None]
    assert len(phs) >= 4 and max(p["weight"] for p in phs) > 0.85
    st = drape_settings("draped_dress")
    for ph in phs:
        verts, _, _, pinned, _ = garment_pattern("draped_dress", ph, st)
        assert penetration(run_anny(ph)["vertices"], body_topology().faces, verts[pinned]).max() < 0.0


def test_skinning_transfer_round_trips_and_matches_the_body():
    rng = np.random.default_rng(0)
    run = run_anny(PHENO)
    topo = body_topology()
    # Points just off the skin: the binding reproduces them in the rest pose (to float64 rounding).
    # Vertices of the collider (the body without arms and hands, whose weights the cloth takes).
    idx = rng.choice(np.unique(collider_faces(PHENO)), 400, replace=False)
    pts = run["vertices"][idx] + 0.01 * rng.normal(size=(400, 3))
    b = bind_to_skeleton(pts, PHENO)
    np.testing.assert_allclose(skin_points(b, run["bone_poses"], run["rest_bone_poses"]), pts, atol=1e-9)
    # Body vertices themselves, posed: their transferred weights are the body's own, so they land on anny's output.
    R = np.eye(4)
    c, s = np.cos(0.7), np.sin(0.7)
    R[1:3, 1:3] = [[c, -s], [s, c]]
    posed = run_anny(PHENO, {"upperleg01.L": R, "spine03": R})
    b = bind_to_skeleton(run["vertices"][idx], PHENO)
    got = skin_points(b, posed["bone_poses"], posed["rest_bone_poses"])
    np.testing.assert_allclose(got, posed["vertices"][idx], atol=1e-6)
    assert b.weights.shape[1] == 8 and np.allclose(b.weights.sum(1), 1.0, atol=1e-6) and topo.n_vertices > 0


def test_push_out_clears_points_sunk_into_the_skin(monkeypatch):
    rng = np.random.default_rng(1)
    run = run_anny(PHENO)
    faces = body_topology().faces
    v = run["vertices"]
    n = vertex_normals(v, faces)
    from rh_dataset.characters.body_features import body_features

    # Where skirts and dresses are (fingers and toes are thinner than the 1 cm the points sink by).
    idx = rng.choice(np.flatnonzero(body_features(PHENO).in_groups("torso", "upperleg", "lowerleg")), 300,
                     replace=False)
    sunk = v[idx] - 0.01 * n[idx]  # 1 cm under the skin
    depth = penetration(v, faces, sunk)
    assert (depth > 0).mean() > 0.9
    import trimesh  # the fast signed distance: the sign of trimesh's ray-cast one, the brute-force distance

    ref = trimesh.proximity.signed_distance(trimesh.Trimesh(v, faces, process=False), sunk[:40])
    np.testing.assert_array_equal(np.sign(depth[:40]), np.sign(ref))
    tri = v[faces]
    brute = [np.linalg.norm(trimesh.triangles.closest_point(tri, np.repeat(p[None], len(tri), 0)) - p, axis=1).min()
             for p in sunk[:40]]
    np.testing.assert_allclose(np.abs(depth[:40]), brute, rtol=0, atol=1e-12)
    # trimesh's own distance can be farther: its closest point takes, of two faces within 1e-8 in squared distance,
    # the one whose normal faces the point (geometry.closest_point)
    assert (np.abs(ref) >= np.abs(depth[:40]) - 1e-12).all()
    out = push_out(sunk, v, n, faces)
    assert penetration(v, faces, out).max() < 0.0
    # push_out searches only the skin near the points (one search tree, PUSH_REACH): the closest points on the whole
    # body, but for a point equally close to two faces, which the smaller search may order otherwise (1e-18 m seen).
    from rh_dataset.characters.drape import closest_on_surface

    d, closest, cn = closest_on_surface(v, faces, sunk, n)
    bad = d > -PUSH_CLEARANCE + 1e-6
    whole = sunk.copy()
    whole[bad] = closest[bad] + PUSH_CLEARANCE * cn[bad]
    from rh_dataset.characters import drape

    with monkeypatch.context() as m:  # one round, without the walk out of creases (test_push_out_..._in_a_crease)
        m.setattr(drape, "_walk_out", lambda p, *args: p)
        np.testing.assert_allclose(push_out(sunk, v, n, faces, rounds=1), whole, rtol=0, atol=1e-12)
    far = v[idx] + 0.05 * n[idx]
    far = far[penetration(v, faces, far) < -0.02]  # already clear (not between the thighs): untouched
    assert len(far) > 200
    assert np.array_equal(push_out(far, v, n, faces), far)
    assert PUSH_CLEARANCE > 0


def _notched_block(half_angle_deg: float):
    """A closed block (metres) whose top has a V notch of `half_angle_deg` down to a crease along Y at z = 2 cm:
    (vertices, faces, vertex normals), subdivided to 5 mm edges so its interpolated normals are a body's."""
    import trimesh

    a, top, apex = 0.1, 0.1, 0.02
    w = (top - apex) * np.tan(np.radians(half_angle_deg))
    outline = np.array([(-a, 0), (0, 0), (a, 0), (a, top), (w, top), (0, apex), (-w, top), (-a, top)])  # x, z
    n = len(outline)
    v = np.array([(x, y, z) for y in (-0.05, 0.05) for x, z in outline])
    caps = [(1, 2, 3), (1, 3, 4), (1, 4, 5), (1, 5, 6), (1, 6, 7), (1, 7, 0)]  # a fan from the bottom's middle
    f = [c for c in caps] + [(n + c[0], n + c[2], n + c[1]) for c in caps]
    f += [(i, (i + 1) % n, n + i) for i in range(n)] + [((i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    mesh = trimesh.Trimesh(v, np.array(f), process=False)
    mesh.fix_normals()
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=0.005)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    return np.asarray(v), np.asarray(f), vertex_normals(np.asarray(v), np.asarray(f))


@pytest.mark.parametrize("half_angle", [10.0, 25.0])
def test_push_out_clears_points_in_a_crease(monkeypatch, half_angle):
    """Points under a narrow crease (two skin surfaces meeting at an angle, as a thigh lifted against the belly):
    the closest-point rounds alone step out of one side into the other and leave them inside (10 degrees) or
    within a fraction of a millimetre of the skin (25 degrees); `push_out` walks those out to the clearance."""
    from rh_dataset.characters import drape

    v, f, n = _notched_block(half_angle)
    y = np.linspace(-0.03, 0.03, 7)
    pts = np.concatenate([np.stack([np.full_like(y, dx), y, np.full_like(y, 0.02 - dz)], 1)
                          for dx in (-0.001, 0.0, 0.0015) for dz in (0.001, 0.003, 0.006)])
    assert penetration(v, f, pts).min() > 0.0  # all under the skin
    out = push_out(pts, v, n, f)
    depth = penetration(v, f, out)
    assert depth.max() < -0.5 * PUSH_CLEARANCE  # off the skin (the rounds leave some short of the clearance)
    assert np.linalg.norm(out - pts, axis=1).max() < 0.06  # out of the crease, not far beyond it
    assert np.array_equal(push_out(pts, v, n, f), out)  # deterministic
    monkeypatch.setattr(drape, "_walk_out", lambda p, *args: p)  # the rounds alone leave some in or on the skin
    assert penetration(v, f, push_out(pts, v, n, f)).max() > (0.0 if half_angle < 20 else -0.5 * PUSH_CLEARANCE)


@pytest.mark.slow
@pytest.mark.parametrize("kind", TUBE_KINDS)
def test_drape_is_bit_identical_and_stays_outside_the_body(tmp_path, monkeypatch, kind):
    from rh_common.body_model import load_anny
    from rh_dataset.poses import sample_poses

    monkeypatch.setenv("RH_DRAPE_CACHE", str(tmp_path))
    st = drape_settings(kind)
    g1 = drape_garment(kind, PHENO, st, use_cache=False)
    g2 = drape_garment(kind, PHENO, st)  # simulated again, then cached
    assert g1.vertices.tobytes() == g2.vertices.tobytes()
    g3 = drape_garment(kind, PHENO)  # read back from the cache (the kind's default settings are st)
    assert g3.vertices.tobytes() == g1.vertices.tobytes()
    assert len(list(tmp_path.glob(f"{kind}-*.npz"))) == 1
    rest = run_anny(PHENO)
    faces = body_topology().faces
    assert penetration(rest["vertices"], faces, g1.vertices).max() < REST_BOUND_M
    # It hangs: the hem dropped below where the pattern put it, and the waistband stayed pinned.
    pattern = garment_pattern(kind, PHENO, st)[0]
    assert g1.vertices[-st.n_around:, 2].mean() < pattern[-st.n_around:, 2].mean() - 0.02
    if kind == "draped_dress":  # cut short so that it settles around the knee
        knee = _a_pose_heads()["lowerleg01.L"][2]
        assert abs(g1.vertices[-st.n_around:, 2].mean() - knee) < 0.05
    np.testing.assert_allclose(g1.vertices[:st.n_around], pattern[:st.n_around], atol=1e-6)  # float32 particles
    b = bind_loose(g1, PHENO)  # the binding the skinned path poses draped garments with
    for pose in sample_poses(np.random.default_rng(7), load_anny(), 6):
        run = run_anny(PHENO, dict(pose.bones))
        pts = skin_points(b, run["bone_poses"], run["rest_bone_poses"])
        pts = push_out(pts, run["vertices"], vertex_normals(run["vertices"], faces), faces)
        depth = penetration(run["vertices"], faces, pts)
        assert depth.max() < POSED_BOUND_M, pose.label


def test_benchmark_recipes_draw_loose_garments():
    """recipe_from_seed draws the draped skirt wherever it drew a skirt (never the shell one), and a share of the
    women wear a draped dress alone (no top, bottom or jacket), from a stream of its own; a dress recipe
    round-trips through JSON, and a dress worn with a top is refused."""
    from rh_dataset.characters.recipe import BOTTOMS, DRESSES, CharacterRecipe, Garment
    from rh_dataset.characters.recipe_draws import DRESS_P, recipe_from_seed

    assert "draped_skirt" in BOTTOMS and DRESSES == ("draped_dress",)
    rs = [recipe_from_seed(2 * i, "benchmark", i) for i in range(300)]
    kinds = [{g.kind for g in r.garments} for r in rs]
    women = [r.phenotype["gender"] > 0.5 for r in rs]
    assert not any("skirt" in k for k in kinds)
    dress = np.array(["draped_dress" in k for k in kinds])
    skirt = np.array(["draped_skirt" in k for k in kinds])
    assert not dress[~np.array(women)].any() and not skirt[~np.array(women)].any()
    share = dress[np.array(women)].mean()
    assert abs(share - DRESS_P) < 0.08, share
    assert 0.15 < (dress | skirt).mean() < 0.4  # a quarter of all subjects in something loose
    for k, d in zip(kinds, dress):
        assert (k == {"shoes", "draped_dress"}) if d else len(k) >= 3
    r = rs[int(np.flatnonzero(dress)[0])]
    assert CharacterRecipe.from_json(r.to_json_text()) == r
    with pytest.raises(ValueError, match="dress"):
        CharacterRecipe(seed=r.seed, pool=r.pool, index=r.index, phenotype=r.phenotype, skin=r.skin, hair=r.hair,
                        garments=(Garment("shoes", (0.1, 0.1, 0.1)), Garment("draped_dress", (0.2, 0.5, 0.3)),
                                  Garment("tshirt", (1, 1, 1))))


@pytest.mark.slow
@pytest.mark.parametrize("kind", TUBE_KINDS)
def test_character_wears_the_draped_skirt_in_every_pose(tmp_path, monkeypatch, kind):
    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.recipe import CharacterRecipe, Garment
    from rh_dataset.characters.recipe_draws import recipe_from_seed
    from rh_dataset.poses import sample_poses

    monkeypatch.setenv("RH_DRAPE_CACHE", str(tmp_path))
    base = recipe_from_seed(0, "benchmark", 0)
    gs = (Garment("shoes", (0.1, 0.1, 0.1)), Garment("draped_skirt", (0.2, 0.5, 0.3)), Garment("tshirt", (1, 1, 1)))
    if kind == "draped_dress":
        gs = (Garment("shoes", (0.1, 0.1, 0.1)), Garment("draped_dress", (0.2, 0.5, 0.3)))
    recipe = CharacterRecipe(seed=base.seed, pool=base.pool, index=base.index, phenotype=PHENO, skin=base.skin,
                             hair=base.hair, garments=gs)
    ch = build_character(recipe, 64)
    part = ch.part(kind)
    assert part.skinning is not None and part.blend_vertices is None and part.drape == drape_settings(kind)
    faces = body_topology().faces
    for pose in sample_poses(np.random.default_rng(3), load_anny(), 3):
        posed = {m.name: m for m in pose_character(ch, dict(pose.bones), pose.root_transform)}
        skirt = posed[kind]
        assert np.isfinite(skirt.vertices).all()
        np.testing.assert_allclose(np.linalg.norm(skirt.normals, axis=1), 1.0, atol=1e-5)
        run = run_anny(PHENO, dict(pose.bones))
        v = run["vertices"] @ pose.root_transform[:3, :3].T + pose.root_transform[:3, 3]
        assert penetration(v, faces, skirt.vertices).max() < POSED_BOUND_M, pose.label


def test_drape_cache_key_covers_the_patterns_triangles_and_pins():
    """A pattern whose points stay but whose triangles or pins change (the hood's faces were once flipped that way)
    must not read back a drape cached for the old one; the same pattern gives the same key, and so does one whose
    points differ in their last bits."""
    from rh_dataset.characters.drape import _cache_key

    st = drape_settings("draped_skirt", "coarse")
    verts, faces, _, pinned, _ = garment_pattern("draped_skirt", PHENO, st)
    key = _cache_key("draped_skirt", PHENO, st, verts, faces, pinned)
    assert key == _cache_key("draped_skirt", PHENO, st, verts.copy(), faces.copy(), pinned.copy())
    assert key != _cache_key("draped_skirt", PHENO, st, verts, faces[:, ::-1], pinned)
    moved = pinned.copy()
    moved[len(verts) // 2] = True
    assert key != _cache_key("draped_skirt", PHENO, st, verts, faces, moved)

    # The points are keyed to 1 nm (KEY_DECIMALS): a pattern a few ulps off, as anny through another torch build or
    # CPU may give, reads back the same drape; a point moved by 1 micrometre does not. Signed zeros hash as one.
    rng = np.random.default_rng(0)
    ulps = np.nextafter(verts, np.where(rng.random(verts.shape) < 0.5, -np.inf, np.inf))
    ulps = np.nextafter(ulps, np.where(rng.random(verts.shape) < 0.5, -np.inf, np.inf))
    assert not np.array_equal(ulps, verts) and np.abs(ulps - verts).max() < 1e-15
    assert key == _cache_key("draped_skirt", PHENO, st, ulps, faces, pinned)
    shifted = verts.copy()
    shifted[7, 2] += 1e-6
    assert key != _cache_key("draped_skirt", PHENO, st, shifted, faces, pinned)
    zeroed = verts.copy()
    zeroed[0, 0] = 0.0
    negzero = zeroed.copy()
    negzero[0, 0] = -1e-17
    assert _cache_key("draped_skirt", PHENO, st, zeroed, faces, pinned) == \
        _cache_key("draped_skirt", PHENO, st, negzero, faces, pinned)


def test_settle_ends_the_drape_at_rest():
    """`DrapeSettings.settle` (steps after the drape's `steps`, each particle keeping `settle_keep` of its velocity
    from one to the next): a square sheet pinned along one edge, let go level, swings under gravity; simulated on,
    it is still swinging 4 s later (10 more steps move it centimetres). After 200 settle steps keeping 0.8 of the
    velocity it hangs straight down from its pinned edge (the static equilibrium) and 10 more move it under 1 mm
    (measured 0.26 mm); 200 steps each from rest (`settle_keep` 0) leave it creeping (10 more move it 3.8 mm): the
    sheet's swing about its pinned edge is a slow mode (restored by gravity alone), which steps from rest relax with
    a time constant of ~100 steps, a damped swing in tens (`pytest -s` prints the three). The settle's count and
    fraction enter the drape cache key only where set (keys of drapes without one read back as before)."""
    from rh_dataset.characters.drape import DrapeSettings, _cache_key, _simulate

    n, size = 9, 0.16
    x, y = np.meshgrid(np.linspace(0.0, size, n), np.linspace(0.0, size, n), indexing="ij")
    verts = np.stack([x.ravel(), y.ravel(), np.ones(n * n)], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
    pinned = verts[:, 0] == 0.0
    far = (np.array([[5.0, 5.0, -5.0], [5.1, 5.0, -5.0], [5.0, 5.1, -5.0]]), np.array([[0, 1, 2]]))  # no body

    def sim(steps, settle, keep=0.0):
        return _simulate(verts, faces, pinned, *far, DrapeSettings(steps=steps, settle=settle, settle_keep=keep,
                                                                   self_contact=False))

    def moved(p, q):
        return np.linalg.norm(p - q, axis=1).max()

    swing = moved(sim(450, 0), sim(440, 0))
    settled = sim(40, 200, 0.8)
    rest = moved(sim(40, 210, 0.8), settled)
    creep = moved(sim(40, 210), sim(40, 200))
    print(f"10 more steps: swinging {1e3 * swing:.1f} mm, settled keeping 0.8 {1e3 * rest:.2f} mm, from rest "
          f"{1e3 * creep:.2f} mm")
    assert swing > 0.03 and rest < 0.001 and creep > 0.002, (swing, rest, creep)
    assert np.abs(settled[~pinned, 0]).max() < 0.02  # under the pinned edge (x = 0)
    assert 1.0 - settled[verts[:, 0] == size, 2].mean() > size  # its free edge a sheet's length down

    st = drape_settings("draped_skirt", "coarse")
    pat, pf, _, pp, _ = garment_pattern("draped_skirt", PHENO, st)
    key = _cache_key("draped_skirt", PHENO, st, pat, pf, pp)
    assert key != _cache_key("draped_skirt", PHENO, dataclasses.replace(st, settle=10), pat, pf, pp)
    assert (_cache_key("draped_skirt", PHENO, dataclasses.replace(st, settle=10), pat, pf, pp)
            != _cache_key("draped_skirt", PHENO, dataclasses.replace(st, settle=10, settle_keep=0.8), pat, pf, pp))
