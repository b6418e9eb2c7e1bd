"""Tests of rh_dataset.characters: recipes (validation, JSON, determinism, pool disjointness), built parts (indices,
UVs, textures, triangle budget), posing (rest pose = anny's rest vertices, unit normals, garments follow the pose
and stay outside the body, root transform), layering."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from rh_dataset.characters import (
    CharacterRecipe,
    Garment,
    HairSpec,
    Material,
    SkinTone,
    body_bounds,
    build_character,
    derive_seed,
    pose_character,
    recipe_from_seed,
    sample_recipe,
)
from rh_dataset.characters import character as character_module
from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.mesh import vertex_normals
from rh_dataset.characters.body_features import GROUPS, body_features

RES = 128  # texture resolution for tests: geometry is resolution-independent, textures are checked small


def _recipe(garments: tuple[str, ...], style: str = "long", seed: int = 12) -> CharacterRecipe:
    base = recipe_from_seed(seed, "benchmark", 0)
    gs = tuple(Garment(kind=k, colour=(0.2, 0.3, 0.6), colour2=(0.9, 0.9, 0.8), pattern=p, period_m=0.03)
               for k, p in zip(garments, ("solid", "stripes", "checks", "noise", "solid")))
    return dataclasses.replace(base, garments=gs, hair=HairSpec(style, (0.3, 0.2, 0.1)))


@pytest.fixture(scope="module")
def dressed():
    """A character with every layer kind that shells use: shoes, trousers, long sleeves, jacket, long hair."""
    return build_character(_recipe(("shoes", "trousers", "longsleeve", "jacket")), RES)


@pytest.fixture(scope="module")
def skirted():
    return build_character(_recipe(("shoes", "skirt", "tshirt"), style="ponytail", seed=14), RES)


# --------------------------------------------------------------------------------------------------------------
# Recipes
# --------------------------------------------------------------------------------------------------------------
def test_recipe_json_round_trip_is_exact():
    rng = np.random.default_rng(5)
    for i in range(6):
        r = sample_recipe(rng, ("benchmark", "pretrain")[i % 2], i)
        obj = r.to_json()
        assert CharacterRecipe.from_json(obj) == r
        text = r.to_json_text()
        assert json.loads(text) == obj and obj["format"] == "rh-character/1"
        assert CharacterRecipe.from_json(text) == r
        assert CharacterRecipe.from_json(json.loads(text)).to_json_text() == text


def test_sample_recipe_is_deterministic():
    a = sample_recipe(np.random.default_rng(3), "benchmark", 7)
    b = sample_recipe(np.random.default_rng(3), "benchmark", 7)
    assert a == b
    assert recipe_from_seed(a.seed, a.pool, a.index) == a


def test_benchmark_and_pretrain_pools_are_disjoint():
    rng = np.random.default_rng(0)
    bench = [sample_recipe(rng, "benchmark", i) for i in range(150)]
    pre = [sample_recipe(rng, "pretrain", i) for i in range(150)]
    assert all(r.seed % 2 == 0 for r in bench) and all(r.seed % 2 == 1 for r in pre)
    assert not {r.seed for r in bench} & {r.seed for r in pre}
    bodies = lambda rs: {tuple(sorted(r.phenotype.items())) for r in rs}  # noqa: E731
    assert not bodies(bench) & bodies(pre)
    # Parity holds for any base seed, so no dataset seed can make the pools meet.
    for base in range(200):
        assert derive_seed("benchmark", base % 7, base) % 2 == 0
        assert derive_seed("pretrain", base % 7, base) % 2 == 1
    with pytest.raises(ValueError, match="pool"):
        dataclasses.replace(bench[0], pool="pretrain")  # an even seed cannot be relabelled as pretraining


@pytest.mark.parametrize(
    "change, field",
    [
        ({"pool": "train"}, "pool"),
        ({"phenotype": {"gender": 2.0, "age": 0.5, "muscle": 0.5, "weight": 0.5, "height": 0.5,
                        "proportions": 0.5}}, "phenotype.gender"),
        ({"phenotype": {"gender": 0.5}}, "phenotype"),
        ({"garments": (Garment("shoes", (0.1, 0.1, 0.1)),)}, "garments"),
        ({"seed": -1}, "seed"),
    ],
)
def test_recipe_validation_names_the_field(change, field):
    r = recipe_from_seed(2, "benchmark", 0)
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(r, **change)


def test_component_validation():
    with pytest.raises(ValueError, match="garment.kind"):
        Garment("scarf", (0.1, 0.1, 0.1))
    with pytest.raises(ValueError, match="garment.colour"):
        Garment("tshirt", (0.1, 1.5, 0.1))
    with pytest.raises(ValueError, match="garment.pattern"):
        Garment("tshirt", (0.1, 0.1, 0.1), pattern="paisley")
    with pytest.raises(ValueError, match="hair.style"):
        HairSpec("mohawk", (0.1, 0.1, 0.1))
    with pytest.raises(ValueError, match="skin.melanin"):
        SkinTone(melanin=1.2)
    with pytest.raises(ValueError, match="albedo"):
        Material(np.full((4, 4, 3), 1.5, np.float32), 0.5, 0.5)
    with pytest.raises(ValueError, match="format"):
        CharacterRecipe.from_json('{"seed": 0}')


# --------------------------------------------------------------------------------------------------------------
# Built characters
# --------------------------------------------------------------------------------------------------------------
def test_build_is_bit_identical():
    recipe = _recipe(("shoes", "shorts", "tshirt"), style="bun", seed=20)
    a = build_character(recipe, 64)
    character_module._build_cached.cache_clear()
    b = build_character(CharacterRecipe.from_json(recipe.to_json_text()), 64)
    assert a is not b
    assert [p.name for p in a.parts] == [p.name for p in b.parts]
    for pa, pb in zip(a.parts, b.parts):
        for f in ("faces", "uvs", "body_vertex", "offset", "blend_vertices", "blend_weights"):
            x, y = getattr(pa, f), getattr(pb, f)
            assert (x is None and y is None) or (x.dtype == y.dtype and np.array_equal(x, y)), (pa.name, f)
        assert np.array_equal(pa.material.albedo, pb.material.albedo)
    for sa, sb in zip(a.strands, b.strands, strict=True):
        assert sa.fibre == sb.fibre and np.array_equal(sa.offset, sb.offset), pa.name
    pose = {"lowerarm01.R": _rot([1, 0, 0], 30)}
    for ma, mb in zip(pose_character(a, pose), pose_character(b, pose)):
        assert np.array_equal(ma.vertices, mb.vertices)
        assert hasattr(ma, "fibre") or np.array_equal(ma.normals, mb.normals)


@pytest.mark.parametrize("which", ["dressed", "skirted"])
def test_parts_are_valid_meshes(which, request):
    ch = request.getfixturevalue(which)
    nv = body_topology().n_vertices
    names = [p.name for p in ch.parts]
    assert names[0] == "body" and not any(n.startswith("hair") for n in names)  # hair is strands
    assert ch.strands and ch.strands[0].name == "hair"
    assert ch.triangle_count < 60_000
    for p in ch.parts:
        assert p.faces.dtype == np.int32 and p.faces.ndim == 2 and p.faces.shape[1] == 3
        assert p.faces.min() >= 0 and p.faces.max() < len(p.uvs)
        assert len(np.unique(p.faces)) == len(p.uvs), f"{p.name}: unreferenced vertices"
        assert p.uvs.dtype == np.float32 and p.uvs.min() >= 0.0 and p.uvs.max() <= 1.0
        assert p.body_vertex.dtype == np.int64 and p.body_vertex.min() >= 0 and p.body_vertex.max() < nv
        assert p.offset.dtype == np.float32 and p.offset.min() >= 0.0
        assert p.offset.max() < 0.1, p.name
        a = p.material.albedo
        assert a.dtype == np.float32 and a.ndim == 3 and a.shape[2] == 3
        assert np.all(np.isfinite(a)) and a.min() >= 0.0 and a.max() <= 1.0
        if p.blend_vertices is not None:
            assert np.allclose(p.blend_weights.sum(1), 1.0, atol=1e-5)
            assert p.blend_vertices.min() >= 0 and p.blend_vertices.max() < nv


def test_albedos_are_physically_plausible(dressed):
    skin = dressed.part("body").material.albedo
    assert 0.01 <= skin.mean() <= 0.6
    for name in ("trousers", "longsleeve", "jacket"):
        a = dressed.part(name).material.albedo
        assert a.min() >= 0.02 and a.max() <= 0.8, name
    # Skin tones span light to dark: the darkest swatch is much darker than the lightest.
    from rh_dataset.characters.recipe import skin_albedo_linear

    light, dark = skin_albedo_linear(SkinTone(0.0)), skin_albedo_linear(SkinTone(1.0))
    assert light[0] > 0.5 and dark[0] < 0.12 and np.all(light > dark)


def test_shell_layers_nest(dressed):
    """Where two shell garments cover the same body vertex, the outer one is further out (jacket over top, etc.)."""
    order = ["shoes", "trousers", "longsleeve", "jacket"]
    offs = {}
    for name in order:
        p = dressed.part(name)
        per_vertex = np.full(body_topology().n_vertices, np.nan)
        if p.body_faces is not None:  # a shell: its vertices off the cut sit on one body vertex each
            pure = p.blend_weights[:, 0] == 1.0
            per_vertex[p.blend_vertices[pure, 0]] = p.offset[pure]
            offs[name] = per_vertex
    names = [n for n in order if n in offs]
    for inner, outer in zip(names, names[1:]):
        both = ~np.isnan(offs[inner]) & ~np.isnan(offs[outer])
        if both.any():
            assert np.all(offs[outer][both] >= offs[inner][both] + 0.0029), (inner, outer)


# --------------------------------------------------------------------------------------------------------------
# Posing
# --------------------------------------------------------------------------------------------------------------
def _rot(axis, deg) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    a = np.radians(deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    return m


def test_zero_pose_is_annys_reference_pose_exactly(dressed):
    """No pose (or identity deltas) gives exactly anny's own output for the body part (offset 0), i.e. anny's
    reference A-pose with the pelvis at the origin: anny's `rest_vertices` shifted by minus the rest root head, up to
    the bones' reference re-orientation (a couple of centimetres)."""
    out = run_anny(dressed.phenotype)
    part = dressed.part("body")
    for deltas in (None, {"upperarm01.L": np.eye(4), "root": np.eye(4)}):
        body = pose_character(dressed, deltas)[0]
        assert body.name == "body"
        assert np.array_equal(body.vertices, out["vertices"][part.body_vertex].astype(np.float32))
    np.testing.assert_allclose(out["bone_poses"][0, :3, 3], 0.0, atol=1e-12)  # root at the origin
    shifted = out["rest_vertices"] - out["rest_bone_heads"][0]
    assert np.median(np.linalg.norm(out["vertices"] - shifted, axis=1)) < 0.02
    # Every body vertex appears in the body part.
    assert set(np.unique(part.body_vertex)) == set(range(body_topology().n_vertices))


def test_root_delta_moves_every_part_rigidly(dressed):
    """A rotation delta on the root bone (whose head is at the origin) rotates every part rigidly: skinning with
    weights summing to one, normals recomputed on the posed body, offsets along them, all commute with it."""
    rot = _rot([0, 0, 1], 35)
    rot[:3, 3] = (0.1, -0.2, 0.05)
    a = pose_character(dressed)
    b = pose_character(dressed, {"root": rot})
    for ma, mb in zip(a, b):
        expect = ma.vertices.astype(np.float64) @ rot[:3, :3].T + rot[:3, 3]
        np.testing.assert_allclose(mb.vertices, expect, atol=2e-5, err_msg=ma.name)
        if not hasattr(ma, "fibre"):
            np.testing.assert_allclose(mb.normals, ma.normals @ rot[:3, :3].T.astype(np.float32), atol=1e-4)


def test_posed_meshes_are_finite_with_unit_normals(dressed, skirted):
    for ch in (dressed, skirted):
        for m in pose_character(ch, {"upperleg01.L": _rot([1, 0, 0], -40), "head": _rot([0, 0, 1], 30)}):
            assert m.vertices.dtype == np.float32 and np.all(np.isfinite(m.vertices)), m.name
            if hasattr(m, "fibre"):  # strands: control points, no normals
                continue
            n = np.linalg.norm(m.normals.astype(np.float64), axis=1)
            np.testing.assert_allclose(n, 1.0, atol=1e-5, err_msg=m.name)
        lo, hi = body_bounds(pose_character(ch))
        assert 1.3 < hi[2] - lo[2] < 2.2  # an adult's height, hair included


def test_sleeve_follows_the_arm_and_stays_outside(dressed):
    feats = body_features(dressed.phenotype)
    sleeve = dressed.part("longsleeve")
    forearm = np.isin(feats.group[sleeve.body_vertex], [GROUPS.index("lowerarm")])
    left = feats.rest_vertices[sleeve.body_vertex, 0] > 0
    pure = sleeve.blend_weights[:, 0] == 1.0  # off the cuff's cut: on one body vertex
    sel = forearm & left & pure
    assert sel.sum() > 50
    idx = [p.name for p in dressed.parts].index("longsleeve")
    rest = pose_character(dressed)[idx].vertices[sel]
    pose = {"upperarm01.L": _rot([0, 1, 0], -50), "lowerarm01.L": _rot([0, 0, 1], 40)}
    posed = pose_character(dressed, pose)
    moved = posed[idx].vertices[sel]
    assert np.median(np.linalg.norm(moved - rest, axis=1)) > 0.1  # the forearm swings by tens of centimetres
    # Outside the posed body: along the posed body normal the sleeve vertex is `offset` (> 0) above the skin.
    out = run_anny(dressed.phenotype, pose)
    topo = body_topology()
    n = vertex_normals(out["vertices"], topo.faces)
    bv = sleeve.body_vertex[sel]
    height = ((moved - out["vertices"][bv]) * n[bv]).sum(1)
    assert np.all(height > 0.0)
    np.testing.assert_allclose(height, sleeve.offset[sel], atol=1e-5)
    # ...and the jacket sleeve is further out than the shirt sleeve at the same body vertices.
    jacket = dressed.part("jacket")
    jp = jacket.blend_weights[:, 0] == 1.0
    common, ia, ib = np.intersect1d(sleeve.body_vertex[pure], jacket.body_vertex[jp], return_indices=True)
    ia, ib = np.flatnonzero(pure)[ia], np.flatnonzero(jp)[ib]
    assert len(common) > 100
    assert np.all(jacket.offset[ib] > sleeve.offset[ia])


def test_skirt_and_hair_follow_the_pose(skirted):
    names = [p.name for p in skirted.parts]
    rest = pose_character(skirted)
    posed = pose_character(skirted, {"head": _rot([0, 0, 1], 40), "upperleg01.L": _rot([1, 0, 0], -30)})
    names += [h.name for h in skirted.strands]
    for name in ("skirt", "hair", "shoes"):
        i = names.index(name)
        assert np.max(np.linalg.norm(posed[i].vertices - rest[i].vertices, axis=1)) > 0.03, name


def test_root_transform_rotates_everything(dressed):
    rot = _rot([0, 0, 1], 90)
    a = pose_character(dressed)
    b = pose_character(dressed, None, rot)
    for ma, mb in zip(a, b):
        np.testing.assert_allclose(mb.vertices, ma.vertices @ rot[:3, :3].T.astype(np.float32), atol=2e-6)
        if hasattr(ma, "fibre"):
            continue
        np.testing.assert_allclose(mb.normals, ma.normals @ rot[:3, :3].T.astype(np.float32), atol=2e-5)
    with pytest.raises(ValueError, match="root_transform"):
        pose_character(dressed, None, np.diag([2.0, 2.0, 2.0, 1.0]))


# --------------------------------------------------------------------------------------------------------------
# Hair and shoes
# --------------------------------------------------------------------------------------------------------------
def _welded_edges(vertices: np.ndarray, faces: np.ndarray):
    """Directed edges of a mesh after welding vertices at equal positions (UV seams split them)."""
    key = np.round(vertices.astype(np.float64) / 1e-7).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    f = inv.ravel()[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    return f, np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])


def _assert_closed(mesh) -> None:
    f, e = _welded_edges(mesh.vertices, mesh.faces)
    und, counts = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    assert np.all(counts == 2), f"{mesh.name}: {np.sum(counts != 2)} edges not shared by exactly two faces"
    assert len(np.unique(e, axis=0)) == len(e), f"{mesh.name}: inconsistent face orientation"
    v = mesh.vertices.astype(np.float64)
    tri = v[mesh.faces]
    vol = np.einsum("ij,ij->i", np.cross(tri[:, 1], tri[:, 2]), tri[:, 0]).sum() / 6.0
    assert vol > 1e-6, f"{mesh.name}: normals point inwards (signed volume {vol})"


@pytest.fixture(scope="module")
def styled():
    return {"short": build_character(_recipe(("shoes", "trousers", "tshirt"), style="short", seed=32), 32)}


def test_shoes_are_closed(styled):
    posed = {m.name: m for m in pose_character(styled["short"], {"head": _rot([0, 0, 1], 25)})}
    _assert_closed(posed["shoes"])


def test_shoes_hide_the_toes(styled):
    """All foot vertices below the shoe's collar are inside the shoes (toes included), and the shoe is smooth: no
    toe-sized bumps."""
    from rh_dataset.characters.geometry import surface_clearance

    ch = styled["short"]
    posed = {m.name: m for m in pose_character(ch)}
    feats = body_features(ch.phenotype)
    foot = run_anny(ch.phenotype)["vertices"][feats.in_groups("foot")]
    foot = foot[foot[:, 2] < foot[:, 2].min() + 0.06]
    shoes = posed["shoes"]
    h = surface_clearance(foot, shoes.vertices.astype(np.float64),
                          shoes.normals.astype(np.float64), np.arange(len(shoes.vertices)))
    assert np.all(h < 0.0), f"{np.sum(h >= 0)} foot vertices poke through the shoes"
    # Smooth: adjacent face normals of the shoe differ by little (a toe shape would crease it).
    f = shoes.faces
    tri = shoes.vertices.astype(np.float64)[f]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ok = np.linalg.norm(fn, axis=1) > 1e-12
    assert ok.mean() > 0.99
    vn = shoes.normals.astype(np.float64)[f]
    fn = fn[ok] / np.linalg.norm(fn[ok], axis=1, keepdims=True)
    cos = np.einsum("ij,ikj->ik", fn, vn[ok])
    assert np.median(cos) > 0.97


def test_styles_are_deterministic():
    recipe = _recipe(("shoes", "skirt", "tshirt"), style="long", seed=44)
    a = build_character(recipe, 32)
    character_module._build_cached.cache_clear()
    b = build_character(CharacterRecipe.from_json(recipe.to_json_text()), 32)
    for pa, pb in zip(a.parts, b.parts):
        for f in ("faces", "uvs", "offset", "blend_vertices", "blend_weights"):
            x, y = getattr(pa, f), getattr(pb, f)
            assert (x is None and y is None) or np.array_equal(x, y), (pa.name, f)
        assert np.array_equal(pa.material.albedo, pb.material.albedo)
    for sa, sb in zip(a.strands, b.strands, strict=True):
        assert sa.fibre == sb.fibre and np.array_equal(sa.offset, sb.offset)
