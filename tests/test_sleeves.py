"""The loose tops' draped sleeves (drape.py kinds `draped_sleeves` and `draped_long_sleeves`, cut by sleeves.py): the
short sleeves' pattern is two closed tubes round the upper arms, faces outward, pinned at a ring clear of the trunk,
every particle off the body (the long sleeves' pattern: tests/test_long_sleeves.py); for both, the shell's ("tee",
"longtop") sleeves end SHELL_OVERLAP under those rings, newton's coarse drape settles off the body and hangs lower
than it was cut, and a character in the loose top wears them (not under an open jacket or coat), skinned to the arms
in every cloth mode; posed they stay off the body with the shell's sleeves inside them. Bounds measured on this
machine (5 December; bench/bench_sleeves.py [--kind] for the benchmark's wearers) and stated here."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.characters.drape import (DRAPE_LEVELS, SHELL_OVERLAP, binding_faces, collider_faces, drape_garment,
                                         drape_settings, garment_pattern, penetration, push_clearance,
                                         shell_hem)
from rh_dataset.characters.geometry import edge_counts
from rh_dataset.characters.sleeves import SIDES, SLEEVE_CUTS, SLEEVES, sleeve_axis, sleeve_pattern, sleeve_tops
from test_drape_coat import HEAVY, PHENO, _heads

KIND = "draped_sleeves"


@pytest.mark.parametrize("level", DRAPE_LEVELS)
@pytest.mark.parametrize("pheno", [PHENO, HEAVY], ids=["slim", "heavy"])
def test_sleeve_pattern_is_two_outward_tubes_round_the_upper_arms(pheno, level):
    """Each tube: every edge in two faces but its top ring's and hem's, faces outward (away from its axis), its top
    ring pinned and perpendicular to the upper arm at `sleeve_tops`, clear of the rest of the body by the ring gap,
    every particle off the arm by half the ring gap, wider at the hem than at the ring (the flare), the hem at
    SLEEVES.hem of the shoulder-to-wrist distance; the pattern function and the drape's agree."""
    st = drape_settings(KIND, level)
    na, nr = st.n_around, st.n_rings
    verts, faces, uvs, pinned, mpu, pieces = sleeve_pattern(pheno, na, nr)
    assert verts.shape == (2 * na * nr, 3) and len(pieces) == 2
    np.testing.assert_array_equal(garment_pattern(KIND, pheno, st)[0], verts)
    _, counts = edge_counts(faces)
    assert set(counts.tolist()) == {1, 2} and (counts == 1).sum() == 4 * na
    assert np.array_equal(np.flatnonzero(pinned), np.sort(np.concatenate([g[0] for g in pieces])))
    heads = _heads(pheno)
    tops = sleeve_tops(pheno, na)
    body = run_anny(pheno)["vertices"]
    depth = penetration(body, body_topology().faces, verts)
    assert depth.max() < -0.5 * SLEEVES.ring_gap
    for side, grid in zip(SIDES, pieces):
        o, a, p, q = sleeve_axis(heads, side)
        t = (verts[grid] - o) @ a  # (rings, around): metres along the arm
        assert np.ptp(t, axis=1).max() < 1e-9 and t[0, 0] == pytest.approx(tops[side], abs=1e-12)
        reach = SLEEVES.hem * np.linalg.norm(heads[f"wrist.{side}"] - o)
        assert t[-1, 0] == pytest.approx(reach, abs=1e-9)
        centre = o + t[:, :1, None] * a  # each ring's point on the axis
        r = np.linalg.norm(verts[grid] - centre, axis=-1)
        assert (r[-1] - r[0] >= (t[-1, 0] - t[0, 0]) * np.tan(SLEEVES.flare) - 1e-9).all()
        own = np.isin(faces, grid.ravel()).all(1)
        tri = verts[faces[own]]
        radial = tri.mean(1) - o - ((tri.mean(1) - o) @ a)[:, None] * a
        assert ((np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * radial).sum(1) > 0).all()
    assert uvs.min() >= 0.0 and uvs.max() <= 1.0 and mpu > 0.2
    assert push_clearance(KIND) == SLEEVES.ring_gap > st.clearance


def test_sleeves_collide_with_the_arms_and_are_bound_to_them():
    """The drape's collider keeps the arms (the sleeves hang round them) but the hands; the skinning comes from the
    upper arms and forearms alone, so no sleeve vertex takes the chest's weights by the armpit."""
    from rh_dataset.characters.body_features import body_features

    feats = body_features(PHENO)
    f = body_topology().faces
    hand, arm = feats.in_groups("hand"), feats.in_groups("upperarm", "lowerarm")
    cf = collider_faces(PHENO, KIND)
    assert not hand[cf].any() and arm[cf].any() and len(cf) == (~hand[f].any(1)).sum()
    bf = binding_faces(PHENO, KIND)
    assert arm[bf].all() and len(bf) == arm[f].all(1).sum()
    np.testing.assert_array_equal(binding_faces(PHENO, "draped_tshirt"), collider_faces(PHENO))


@pytest.mark.parametrize("kind, fall", [(KIND, 0.005), ("draped_long_sleeves", 0.003),
                                        ("draped_hoodie_sleeves", 0.003), ("draped_coat_sleeves", 0.003)])
def test_coarse_drape_settles_off_the_arm_and_hangs(tmp_path, monkeypatch, kind, fall):
    """newton's coarse drape: no particle in the body (at least half the particle radius off it), the pinned rings
    where they were cut, and the tubes' hems lower than cut by `fall` (the cloth hangs round the arm under its
    weight; the long sleeves' hems, round the forearm, fall less)."""
    monkeypatch.setenv("RH_DRAPE_CACHE", str(tmp_path))
    st = drape_settings(kind, "coarse")
    g = drape_garment(kind, PHENO, st)
    body = run_anny(PHENO)["vertices"]
    assert penetration(body, body_topology().faces, g.vertices).max() < -0.5 * st.clearance
    np.testing.assert_allclose(g.vertices[g.pinned], g.pattern[g.pinned], atol=1e-6)  # (newton: float32)
    for grid in g.pieces:
        assert g.vertices[grid[-1], 2].mean() < g.pattern[grid[-1], 2].mean() - fall


def test_coat_sleeves_share_a_bent_elbow_along_the_sleeve(tmp_path, monkeypatch):
    """The coat's sleeves (16 mm off the arm) are bound with the weights diffused along the sleeve
    (`drape.LOOSE_EVERYWHERE`, 8 cm: `LOOSE_REACHES`): at an elbow bent 120 degrees the closest point's weights fold
    the tube through itself (31-190 crossing edges on the slim and heavy builds, either drape level, 7 December), the
    diffused ones not at all; the pinned rings keep the closest point's weights exactly, and the rest pose is the
    drape."""
    from scipy.spatial.transform import Rotation

    from rh_dataset.characters.cloth_pose import self_crossings
    from rh_dataset.characters.drape import LOOSE_EVERYWHERE, bind_loose, loose_iterations, skin_points

    kind = "draped_coat_sleeves"
    assert kind in LOOSE_EVERYWHERE
    monkeypatch.setenv("RH_DRAPE_CACHE", str(tmp_path))
    g = drape_garment(kind, PHENO, drape_settings(kind, "coarse"))
    closest, diffused = bind_loose(g, PHENO, iterations=0), bind_loose(g, PHENO)
    assert loose_iterations(g) >= 3
    pin = np.asarray(g.pinned, bool)
    np.testing.assert_array_equal(diffused.weights[pin], closest.weights[pin])
    np.testing.assert_array_equal(diffused.bones[pin], closest.bones[pin])
    assert not np.array_equal(diffused.weights[~pin], closest.weights[~pin])
    rest = run_anny(PHENO)
    np.testing.assert_allclose(skin_points(diffused, rest["bone_poses"], rest["rest_bone_poses"]), g.vertices,
                               atol=1e-5)
    bend = np.eye(4)
    bend[:3, :3] = Rotation.from_euler("x", 120, degrees=True).as_matrix()
    run = run_anny(PHENO, {"lowerarm01.R": bend, "lowerarm01.L": bend})
    crossings = [self_crossings(skin_points(b, run["bone_poses"], run["rest_bone_poses"]), g.faces)
                 for b in (closest, diffused)]
    assert crossings[0] > 10 and crossings[1] == 0, crossings


@pytest.mark.parametrize("shell, top, kind", [("tee", "draped_tshirt", KIND),
                                               ("longtop", "draped_longsleeve", "draped_long_sleeves"),
                                               ("hoodie", "draped_hoodie_body", "draped_hoodie_sleeves"),
                                               ("coat", "draped_coat", "draped_coat_sleeves")])
def test_shell_sleeves_end_under_the_pinned_rings(shell, top, kind):
    """Worn with the draped sleeves, the shell's ("tee", "longtop", "hoodie", "coat") sleeves end SHELL_OVERLAP along
    the arm past the sleeves' pinned rings (the coat's cut's own, farther down the arm; inside the cloth); without
    them, at the t-shirt's length or down the forearm."""
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.garments import garment_level

    feats = body_features(PHENO)
    tops = sleeve_tops(PHENO, drape_settings(kind).n_around, SLEEVE_CUTS[kind])
    ends = {s: t + SHELL_OVERLAP for s, t in tops.items()}
    hem = shell_hem(top, PHENO)  # `top`: the draped piece the shell ends over (the hoodie's: its body)
    level = garment_level(shell, feats, hem, sleeves=ends)
    plain = garment_level(shell, feats, hem)
    v = feats.rest_vertices
    for side in SIDES:
        o, a, _, _ = sleeve_axis(feats.bone_heads, side)
        arm = feats.in_groups("upperarm", "lowerarm") & ((v[:, 0] > 0) == (side == "L"))
        t = (v - o) @ a
        assert (level[arm & (t > ends[side] + 0.002)] > 0).all()
        assert (level[arm & (t > tops[side] + 0.002) & (t < ends[side] - 0.002)] < 0).any()
        if shell == "tee":  # the t-shirt's: longer
            assert (plain[arm & (t > ends[side] + 0.01) & (t < ends[side] + 0.03)] < 0).any()
        else:  # the long sleeve's: down the forearm (0.83 of the arm's vertices past 20 cm here)
            assert (plain[arm & (t > 0.2)] < 0).mean() > 0.75


def test_parts_of_a_loose_tshirt():
    """The loose t-shirt is the shell, its body of cloth and its sleeves; under an open jacket or a coat, no draped
    sleeves (the jacket's shell sleeves lie over the arm)."""
    from rh_dataset.characters.garments import garment_parts

    assert garment_parts("draped_tshirt") == ("tee", "draped_tshirt", KIND)
    for outer in ("draped_jacket", "draped_coat"):
        assert garment_parts("draped_tshirt", ["draped_tshirt", outer]) == ("tee", "draped_tshirt")
    assert garment_parts("draped_tshirt", ["draped_tshirt", "draped_skirt"]) == ("tee", "draped_tshirt", KIND)
    assert garment_parts("draped_longsleeve") == ("longtop", "draped_longsleeve", "draped_long_sleeves")
    assert garment_parts("draped_hoodie") == ("hoodie", "draped_hoodie_body", "draped_hoodie", "draped_hoodie_sleeves")
    coat = ("coat", "draped_coat", "draped_coat_sleeves")  # the coat keeps its own sleeves, a top under it does not
    assert garment_parts("draped_coat") == garment_parts("draped_coat", ["draped_tshirt", "draped_coat"]) == coat
    jacket = ("coat", "draped_jacket", "draped_coat_sleeves")  # the jacket is the coat cut short, in its sleeves
    assert garment_parts("draped_jacket") == garment_parts("draped_jacket", ["draped_longsleeve", "draped_jacket"])
    assert garment_parts("draped_jacket") == jacket


def loose_top_wearer(cache_dir, top: str, colour, under: str | None = None):
    """A character in a loose top of kind `top` (striped) over shell shorts (and a plain top of kind `under` under
    it, if given), coarse drapes, draped into `cache_dir` (the drape cache is pointed there for the build and put
    back after)."""
    import os

    from rh_dataset.characters import Garment, HairSpec, build_character, recipe_from_seed

    old = os.environ.get("RH_DRAPE_CACHE")
    os.environ["RH_DRAPE_CACHE"] = str(cache_dir)
    try:
        garments = (Garment("shoes", (0.2, 0.2, 0.2)), Garment("shorts", (0.1, 0.1, 0.3)),
                     *([Garment(under, (0.2, 0.5, 0.5))] if under else []),
                     Garment(top, colour, (0.9, 0.9, 0.8), "stripes", 0.03))
        recipe = dataclasses.replace(recipe_from_seed(12, "benchmark", 0), garments=garments,
                                     hair=HairSpec("short", (0.3, 0.2, 0.1)))
        return build_character(recipe, 64, drape="coarse")
    finally:
        if old is None:
            os.environ.pop("RH_DRAPE_CACHE", None)
        else:
            os.environ["RH_DRAPE_CACHE"] = old


@pytest.fixture(scope="module")
def wearer(tmp_path_factory):
    """A character in a loose t-shirt over shell shorts, coarse drapes (its own drape cache)."""
    return loose_top_wearer(tmp_path_factory.mktemp("drape"), "draped_tshirt", (0.7, 0.2, 0.2))


@pytest.fixture(scope="module")
def long_wearer(tmp_path_factory):
    """A character in a loose long sleeve over shell shorts, coarse drapes (its own drape cache)."""
    return loose_top_wearer(tmp_path_factory.mktemp("drape"), "draped_longsleeve", (0.2, 0.5, 0.7))


@pytest.fixture(scope="module")
def hoodie_wearer(tmp_path_factory):
    """A character in a hoodie over shell shorts, coarse drapes (its own drape cache)."""
    return loose_top_wearer(tmp_path_factory.mktemp("drape"), "draped_hoodie", (0.5, 0.5, 0.2))


@pytest.fixture(scope="module")
def coat_wearer(tmp_path_factory):
    """A character in an open coat over a shell long sleeve and shell shorts, coarse drapes (its own cache)."""
    return loose_top_wearer(tmp_path_factory.mktemp("drape"), "draped_coat", (0.6, 0.3, 0.4), under="longsleeve")


@pytest.fixture(scope="module")
def jacket_wearer(tmp_path_factory):
    """A character in an open jacket over a shell t-shirt and shell shorts, coarse drapes (its own cache)."""
    return loose_top_wearer(tmp_path_factory.mktemp("drape"), "draped_jacket", (0.3, 0.3, 0.5), under="tshirt")


# (wearer fixture, shell, the cloth before the sleeves (the loose tops' body, the hoodie's hood, the coat's panels),
# sleeves, the most a shell vertex may lie over the cloth: 3 mm for the short sleeves, 5 mm for the long, whose raised
# arm's armpit gave 4.1 mm here; the top under the sleeves, if any)
WEARERS = [("wearer", "tee", "draped_tshirt", KIND, 0.003, None),
           ("long_wearer", "longtop", "draped_longsleeve", "draped_long_sleeves", 0.005, None),
           ("hoodie_wearer", "hoodie", "draped_hoodie", "draped_hoodie_sleeves", 0.005, None),
           ("coat_wearer", "coat", "draped_coat", "draped_coat_sleeves", 0.005, "longsleeve"),
           ("jacket_wearer", "coat", "draped_jacket", "draped_coat_sleeves", 0.005, "tshirt")]
UNDER_OVER_M = 0.005  # the most the top's sleeve under the coat's may lie over them (the skin wins in a crease)


@pytest.mark.parametrize("fixture, shell, body_cloth, kind, over, under", WEARERS,
                         ids=["short", "long", "hoodie", "coat", "jacket"])
def test_posed_sleeves_stay_off_the_body_with_the_shell_inside(request, fixture, shell, body_cloth, kind, over, under):
    """Rest, a raised arm and a bent elbow, skinned and simulated (the sleeves are skinned in both; the same bits;
    the coat's and jacket's only skinned, their panels' simulation is slow): the sleeves keep off the skin (push_out: more than
    1 mm), no vertex of the shell's sleeves lies more than `over` over the cloth, and none of the sleeves of the top
    under them (the coat's, the jacket's) more than UNDER_OVER_M."""
    from rh_common.body_model import ANNY_TOPOLOGY
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import group_mask
    from rh_dataset.characters.cloth_pose import layer_depth
    from scipy.spatial.transform import Rotation

    who = request.getfixturevalue(fixture)
    names = [p.name for p in who.parts]
    assert names.index(shell) < names.index(body_cloth) < names.index(kind)
    raise_arm, bend = np.eye(4), np.eye(4)
    raise_arm[:3, :3] = Rotation.from_euler("y", 50, degrees=True).as_matrix()
    bend[:3, :3] = Rotation.from_euler("x", 60, degrees=True).as_matrix()
    on_arm = group_mask(ANNY_TOPOLOGY, "upperarm", "lowerarm")[who.part(shell).body_vertex]
    for bones in (None, {"upperarm01.L": raise_arm}, {"lowerarm01.R": bend}):
        posed = {m.name: m for m in pose_character(who, bones) if hasattr(m, "faces")}
        if under is None:
            sim = {m.name: m for m in pose_character(who, bones, cloth="simulated") if hasattr(m, "faces")}
            np.testing.assert_array_equal(posed[kind].vertices, sim[kind].vertices)
        sl, top, body = posed[kind], posed[shell], posed["body"]
        v = np.asarray(sl.vertices, np.float64)
        assert penetration(np.asarray(body.vertices, np.float64), body.faces, v).max() < -0.001
        d = layer_depth(np.asarray(top.vertices, np.float64)[on_arm], v, sl.faces)
        assert np.nan_to_num(d, nan=0.0).min() > -over
        if under is not None:
            in_arm = group_mask(ANNY_TOPOLOGY, "upperarm", "lowerarm")[who.part(under).body_vertex]
            d = layer_depth(np.asarray(posed[under].vertices, np.float64)[in_arm], v, sl.faces)
            assert np.nan_to_num(d, nan=0.0).min() > -UNDER_OVER_M, (bones, np.nanmin(d))
