"""Model only what a scene requires: AOV-only frames build no light and no path tracer, the path depth comes from
the split's scene class, and geometry no camera can see is left out without changing what is rendered."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_common.camera import Camera
from rh_dataset.render.cull import FRUSTUM_MARGIN_PX, drop_faces, outside_frustum
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant

AOVS = ["mask", "albedo", "normal", "depth"]
ENV = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


def cam(w=40, h=32, dist=4.0, fov=40.0, target=(0.0, 0.0, 0.0)) -> Camera:
    return Camera(width=w, height=h, fov_y_deg=fov, origin=(target[0], -dist, target[2]), target=target)


# ---------------------------------------------------------------------------------------------- AOV-only frames

def test_an_aov_only_frame_loads_no_emitter_and_no_path_integrator(monkeypatch):
    import rh_dataset.render.passes as passes

    built = []
    real = passes.scene_dict
    monkeypatch.setattr(passes, "scene_dict", lambda *a, **k: built.append(real(*a, **k)) or built[-1])
    # An emitter Mitsuba cannot even load: the AOV-only frame must never try.
    broken = {"type": "no_such_emitter_plugin"}
    out = render_frame([uv_sphere()], broken, cam(), RenderSettings(spp=4, aov_spp=2, max_depth=3), AOVS, seed=0)
    assert set(out.layers) == set(AOVS) and "beauty" not in out.seconds
    assert "environment" not in built[-1] and built[-1]["integrator"]["type"] == "aov"
    assert out.info["emitter_loaded"] is False and out.info["path_traced"] is False and out.info["max_depth"] is None
    # None is accepted as the emitter without an image, refused with one.
    render_frame([uv_sphere()], None, cam(), RenderSettings(spp=4, aov_spp=2, max_depth=3), ["mask"], seed=0)
    with pytest.raises(ValueError, match="needs an emitter"):
        render_frame([uv_sphere()], None, cam(), RenderSettings(), ["image"], seed=0)
    with pytest.raises(Exception):
        render_frame([uv_sphere()], broken, cam(), RenderSettings(spp=2, aov_spp=2, max_depth=3), ["image"], seed=0)


def test_aov_only_layers_are_bit_identical_to_those_of_the_full_scene():
    # The AOV pass reads primary hits only: dropping the light and the path integrator must not move a bit.
    meshes = [uv_sphere(albedo=(0.3, 0.5, 0.7)), uv_sphere(center=(0.6, -0.8, 0.2), radius=0.3, name="small")]
    s = RenderSettings(spp=4, aov_spp=8, max_depth=3, cull=False)
    lit = {"type": "constant", "radiance": {"type": "rgb", "value": 3.0}}
    full = render_frame(meshes, lit, cam(), s, ["image", *AOVS], seed=9).layers
    only = render_frame(meshes, lit, cam(), s, AOVS, seed=9).layers
    for k in AOVS:
        assert np.array_equal(full[k], only[k]), k


# ---------------------------------------------------------------------------------------------- path depth

def test_the_split_scene_class_chooses_the_depth_and_the_preset_can_override_it():
    from rh_dataset.spec import load_protocol
    from rh_dataset.presets import load_presets, load_scene_classes

    classes = load_scene_classes()
    a = load_protocol("a")
    for split in a.splits:
        assert split.path_traced and split.max_depth == classes[split.scene_class].max_depth
    pre = load_protocol("rana_pretrain").split("train")
    assert not pre.path_traced and pre.scene_class is None and pre.max_depth is None
    presets = load_presets()
    std = RenderSettings(spp=4, aov_spp=2, max_depth=presets["standard"].max_depth)
    assert std.max_depth is None  # standard defers to the class
    assert std.for_split(a.split("test")).max_depth == classes["posed-envmap"].max_depth
    assert std.for_split(pre).max_depth is None  # nothing path-traced, no depth
    ref = RenderSettings(max_depth=presets["reference"].max_depth)
    assert ref.for_split(a.split("test")).max_depth == presets["reference"].max_depth
    assert presets["standard"].depth_for("apose-envmap") == classes["apose-envmap"].max_depth
    assert std.for_split(a.split("train")).rr_depth == classes["apose-envmap"].rr_depth == \
        presets["standard"].roulette_for("apose-envmap")
    assert ref.for_split(a.split("test")).rr_depth is None and presets["reference"].roulette_for("posed-envmap") is None
    with pytest.raises(ValueError, match="max_depth is None"):
        render_frame([uv_sphere()], ENV, cam(), std, ["image"], seed=0)


def test_each_class_depth_meets_its_recorded_tolerance_and_one_less_would_not():
    # The choice rests on the measurement recorded beside it. A plain cut: the smallest depth whose truncation PSNR
    # clears the tolerance. With a roulette depth: the roulette starts where that cut was (measured on subject 0),
    # and max_depth is deeper than any measured, because on the strand-hair subjects no plain depth measured clears
    # it (light hair not even 16, against 64).
    from rh_dataset.presets import load_scene_classes

    for c in load_scene_classes().values():
        psnr = {int(k): v for k, v in c.measured["psnr_vs_depth16_db"].items()}
        cut = c.max_depth if c.rr_depth is None else c.rr_depth
        assert psnr[cut] >= c.tolerance_db
        assert all(psnr[d] < c.tolerance_db for d in psnr if d < cut)
        if c.rr_depth is not None:
            hair = c.measured["strand_hair_subjects"]
            assert hair and all(v < c.tolerance_db for h in hair.values() for v in h["psnr_vs_depth16_db"].values())
            assert c.max_depth >= 64 and any(h.get("depth16_vs_depth64_db", 99.0) < c.tolerance_db
                                             for x in load_scene_classes().values()
                                             for h in x.measured["strand_hair_subjects"].values())


def test_russian_roulette_reaches_mitsuba_and_keeps_the_expectation():
    # A grey convex sphere under constant light L: every inside pixel is exactly a * L whatever the depth (nothing to
    # interreflect). Roulette from the first bounce ends most paths early and reweights the survivors: the pixels
    # must still average a * L (within 4 standard errors of their own spread), and differ from the default's.
    a = 0.5
    out = {}
    for rr in (None, 1):
        st = RenderSettings(spp=16, aov_spp=4, max_depth=16, rr_depth=rr)
        out[rr] = render_frame([uv_sphere(albedo=(a, a, a))], ENV, cam(), st, ["image", "mask"], seed=5).layers
    inside = out[1]["mask"] > 0.999
    x = out[1]["image"][inside].astype(np.float64)
    assert inside.sum() > 200 and abs(x.mean() - a) < 4 * x.std() / np.sqrt(x.size)
    assert not np.array_equal(out[1]["image"], out[None]["image"])
    with pytest.raises(ValueError, match="rr_depth must be None or an integer >= 1"):
        RenderSettings(rr_depth=0)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["splits"]["test"].pop("scene_class"), "must declare its scene_class"),
    (lambda d: d["splits"]["test"].update(scene_class="underwater"), "unknown scene_class"),
    (lambda d: d["splits"]["train"].update(layers=["mask", "albedo"]), "nothing is path-traced"),
])
def test_scene_class_declarations_are_checked(tmp_path, mutate, message):
    from rh_dataset.spec import SpecError, load_protocol

    data = json.loads(open(load_protocol("a").source).read())
    mutate(data)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=message):
        load_protocol(str(p))


# ---------------------------------------------------------------------------------------------- frustum culling

def test_frustum_cull_drops_exactly_the_triangles_beyond_one_widened_image_edge():
    sphere = uv_sphere(radius=1.0, n_lat=48, n_lon=96)
    c = cam(w=40, h=32, dist=2.2, fov=30.0, target=(0.5, 0.0, 0.4))  # sees only part of the sphere
    culled = outside_frustum(sphere.vertices, sphere.faces, c)
    # Independently: every vertex is in front of the camera here, so "outside one plane" is "all three projected
    # vertices beyond the same widened edge".
    pc = sphere.vertices @ c.world_to_camera[:3, :3].T + c.world_to_camera[:3, 3]
    assert pc[:, 2].min() > 0.01
    uv = c.project(sphere.vertices)[sphere.faces]  # (F, 3, 2)
    m = FRUSTUM_MARGIN_PX
    expected = (np.all(uv[..., 0] < -m, 1) | np.all(uv[..., 0] > c.width + m, 1)
                | np.all(uv[..., 1] < -m, 1) | np.all(uv[..., 1] > c.height + m, 1))
    assert np.array_equal(culled, expected)
    assert 0 < culled.sum() < len(culled)
    kept, n = drop_faces([sphere], [culled])
    assert n == int(culled.sum()) and len(kept[0].faces) == len(sphere.faces) - n


def test_frustum_cull_leaves_aov_only_layers_unchanged_and_path_traced_frames_whole():
    sphere = uv_sphere(radius=1.0, n_lat=48, n_lon=96)
    c = cam(w=40, h=32, dist=2.2, fov=30.0, target=(0.5, 0.0, 0.4))
    on = render_frame([sphere], None, c, RenderSettings(spp=1, aov_spp=16, max_depth=3, cull=True), AOVS, seed=3)
    off = render_frame([sphere], None, c, RenderSettings(spp=1, aov_spp=16, max_depth=3, cull=False), AOVS, seed=3)
    assert on.info["culled_faces"]["outside_frustum"] > 0 and off.info["culled_faces"]["outside_frustum"] == 0
    assert on.info["triangles"] < off.info["triangles"]
    for k in AOVS:
        assert np.array_equal(on.layers[k], off.layers[k]), k
    # Off-screen geometry still shadows and reflects: a path-traced frame keeps it.
    full = render_frame([sphere], ENV, c, RenderSettings(spp=2, aov_spp=2, max_depth=3, cull=True), ["image", "mask"],
                        seed=3)
    assert full.info["culled_faces"]["outside_frustum"] == 0 and full.info["triangles"] == len(sphere.faces)


def test_a_mesh_entirely_outside_the_view_is_not_loaded_at_all():
    behind = uv_sphere(center=(0.0, -6.0, 0.0), radius=0.5, name="behind")  # behind the camera at y = -4
    front = uv_sphere(radius=0.5, name="front")
    on = render_frame([front, behind], None, cam(), RenderSettings(spp=1, aov_spp=4, max_depth=3), AOVS, seed=0)
    assert on.info["culled_faces"]["outside_frustum"] == len(behind.faces)
    assert on.info["triangles"] == len(front.faces)


# ---------------------------------------------------------------------------------------------- hidden geometry

def test_geometry_enclosed_by_a_shell_can_be_left_out_without_changing_any_layer():
    # A "skin" sphere inside a closed "garment" shell 1 cm out: no ray from outside reaches the skin, so leaving it
    # out changes no sample of any layer (same seed, same paths).
    skin = uv_sphere(radius=1.0, albedo=(0.8, 0.5, 0.4), name="body", n_lat=32, n_lon=64)
    cloth = uv_sphere(radius=1.01, albedo=(0.2, 0.3, 0.6), name="tshirt", n_lat=32, n_lon=64)
    hidden = {"body": np.ones(len(skin.faces), bool)}
    s = RenderSettings(spp=8, aov_spp=4, max_depth=4)
    a = render_frame([skin, cloth], ENV, cam(), s, ["image", *AOVS], seed=1, hidden=hidden)
    b = render_frame([skin, cloth], ENV, cam(), dataclasses.replace(s, cull=False), ["image", *AOVS], seed=1,
                     hidden=hidden)
    assert a.info["culled_faces"]["hidden_under_clothes"] == len(skin.faces)
    assert b.info["culled_faces"]["hidden_under_clothes"] == 0 and b.info["cull"] is False
    for k in a.layers:
        assert np.array_equal(a.layers[k], b.layers[k]), k


@pytest.fixture(scope="module")
def character():
    from rh_dataset.characters import build_character, sample_recipe
    from rh_dataset.generate import rng_for

    return build_character(sample_recipe(rng_for(0, "character", 0), pool="benchmark", index=0), drape="coarse")


def test_hidden_skin_is_covered_by_clothes_and_far_from_uncovered_skin(character):
    from scipy import sparse
    from scipy.sparse import csgraph

    from rh_dataset.characters import pose_character
    from rh_dataset.render.cull import HIDDEN_MARGIN_M, hidden_faces

    hid = hidden_faces(character)["body"]
    body = character.part("body")
    assert hid.shape == (len(body.faces),) and 0.1 < hid.mean() < 0.6
    tri = body.body_vertex[body.faces]
    posed = {m.name: m for m in pose_character(character, None, None)}
    n = int(body.body_vertex.max()) + 1
    pos = np.zeros((n, 3))
    pos[body.body_vertex] = posed["body"].vertices
    # Independently: a body vertex is enclosed when a ray from it crosses a closed garment (shoes, a bun or a hair
    # curtain: the blend-anchored parts other than skirts and open hair sheets) an odd number of times.
    enclosed = np.zeros(n, bool)
    for name in ("shoes", "hair_curtain", "hair_bun", "hair_ponytail"):
        if name not in posed:
            continue
        pv = posed[name].vertices.astype(np.float64)
        box = np.flatnonzero(np.all((pos >= pv.min(0)) & (pos <= pv.max(0)), axis=1))
        enclosed[box] |= _inside_by_parity(pos[box], pv, posed[name].faces)
    # A shell covers the body faces it copies whole (its vertices there sit on one body vertex each); a face its
    # edge cuts is partly bare.
    in_shell = np.zeros(len(tri), bool)
    for p in character.parts:
        if p.name != "body" and p.body_faces is not None:
            whole = (p.blend_weights.max(axis=1) == 1.0)[p.faces].all(axis=1)
            assert np.array_equal(np.sort(p.blend_vertices[p.faces[whole], 0], axis=1),
                                  np.sort(tri[p.body_faces[whole]], axis=1))
            in_shell[p.body_faces[whole]] = True
    covered = in_shell | enclosed[tri].all(axis=1)
    # Every hidden face is under a shell or enclosed ...
    assert np.all(covered[hid])
    assert np.any(hid & ~in_shell)  # the feet inside the shoes
    # ... and each of its vertices is at least the margin along the skin from any skin left uncovered.
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    w = np.linalg.norm(pos[e[:, 0]] - pos[e[:, 1]], axis=1)
    g = sparse.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    exposed = np.unique(tri[~covered].ravel())
    d = csgraph.dijkstra(g, directed=False, indices=exposed, min_only=True)
    assert d[tri[hid]].min() >= HIDDEN_MARGIN_M - 1e-9
    # ... and no covered face that far in is kept.
    assert np.all(hid[covered & (d[tri] >= HIDDEN_MARGIN_M + 1e-6).all(axis=1)])


def _inside_by_parity(points: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Inside a closed mesh: an odd number of crossings of a ray in a fixed, generic direction (Moller-Trumbore)."""
    d = np.array([0.2345, 0.3456, 0.9087])
    d /= np.linalg.norm(d)
    v0, v1, v2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    h = np.cross(d, e2)
    a = (e1 * h).sum(1)
    ok = np.abs(a) > 1e-12
    f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
    out = []
    for p in points:
        s = p - v0
        u = f * (s * h).sum(1)
        q = np.cross(s, e1)
        v = f * (q @ d)
        t = f * (e2 * q).sum(1)
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        out.append(int(hit.sum()) % 2 == 1)
    return np.array(out)


@pytest.mark.slow
def test_a_clothed_character_renders_the_same_without_its_hidden_skin(character):
    from rh_dataset.characters import body_bounds, pose_character
    from rh_common.camera import frame_body
    from rh_dataset.render.cull import hidden_faces

    meshes = pose_character(character, None, None)
    lo, hi = body_bounds(meshes)
    c = frame_body(lo, hi, 48, 48, 30.0)
    s = RenderSettings(spp=16, aov_spp=4, max_depth=3)
    a = render_frame(meshes, ENV, c, s, ["image", *AOVS], seed=2, hidden=hidden_faces(character))
    b = render_frame(meshes, ENV, c, dataclasses.replace(s, cull=False), ["image", *AOVS], seed=2)
    # Subject 0 wears a draped dress: the culling counts skin under shells, not under draped cloth (its bodice and
    # shoes: 4704 faces on 6 December; over 5000 under its shell clothes of before), as test_generated_frames_... says.
    assert a.info["culled_faces"]["hidden_under_clothes"] > 3000
    for k in AOVS:
        assert np.array_equal(a.layers[k], b.layers[k]), k
    # Measured bit-identical (no path meets the hidden skin); allow noise-level change for other platforms.
    d = a.layers["image"].astype(np.float64) - b.layers["image"]
    assert np.mean(d ** 2) <= 1e-4 * np.mean(b.layers["image"].astype(np.float64) ** 2)


# ---------------------------------------------------------------------------------------------- the generator

def test_generated_frames_record_what_was_modelled(tmp_path, monkeypatch):
    from rh_common.imageio import read_json
    from rh_dataset.cli import main as generate_main
    from rh_dataset.presets import load_scene_classes

    # standard defers the depth and the roulette depth to each split's scene class
    tiny = ["--subjects", "1", "--frames", "1", "--resolution", "24", "--spp", "2", "--aov-spp", "2", "--preset",
            "standard", "--drape", "coarse", "--no-progress"]
    assert generate_main(["--protocol", "a", "--out", str(tmp_path / "a"), *tiny]) == 0
    classes = load_scene_classes()
    for split, cls in (("train", "apose-envmap"), ("test", "posed-envmap")):
        r = read_json(tmp_path / "a" / "subject_000" / "protocol_a" / split / "frame_000000.json")["render"]
        m = r["scene_model"]
        assert r["max_depth"] == m["max_depth"] == classes[cls].max_depth
        assert r["rr_depth"] == classes[cls].rr_depth
        assert m["path_traced"] and m["emitter_loaded"] and m["cull"]
        # standard poses draped cloth "auto": the turntable frame and the test split's first pose (a reach) leave no
        # skin out through the dress, so both stay skinned, and the frame JSON says so.
        assert r["cloth"] == "auto" and r["cloth_posed"] == "skinned"
        # Subject 0 wears a draped dress: only its shoes hide skin (measured 4026 faces; cull.hidden_faces counts
        # shells, not draped cloth), where its shell clothes hid over 5000.
        assert m["culled_faces"]["hidden_under_clothes"] > 3000 and m["culled_faces"]["outside_frustum"] == 0
    # AOV-only pretraining frames never build the emitter at all.
    import rh_dataset.lights as lights

    def refuse(_light):
        raise AssertionError("an AOV-only frame built an emitter")

    monkeypatch.setattr(lights, "mitsuba_emitter_dict", refuse)
    assert generate_main(["--protocol", "rana_pretrain", "--out", str(tmp_path / "p"), *tiny, "--no-cull"]) == 0
    r = read_json(tmp_path / "p" / "subject_000" / "protocol_a" / "train" / "frame_000000.json")["render"]
    assert r["scene_model"]["path_traced"] is False and r["scene_model"]["emitter_loaded"] is False
    assert r["scene_model"]["max_depth"] is None and r["cull"] is False
    assert r["scene_model"]["culled_faces"] == {"hidden_under_clothes": 0, "outside_frustum": 0}
