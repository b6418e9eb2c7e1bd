"""Skin and cloth detail (rh_dataset.characters.surface_detail): determinism, low-contrast bounds, old recipes
unchanged, knit ribs, and the albedo ground truth of the principled BSDF with cloth sheen."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from analytic_scenes import quad
from rh_common.camera import Camera
from rh_dataset.characters import CharacterRecipe, Garment, Material, SkinTone, recipe_from_seed
from rh_dataset.characters.body_features import body_features
from rh_dataset.characters.surface_detail import DETAIL_FACTOR_RANGE, KNIT_PERIOD_M, knit_ribs
from rh_dataset.characters.textures import _mask, garment_texture, skin_texture, texel_positions

RES = 256  # 3.7 mm texels: the 5 mm freckle cells and the 8 mm veins still show


@pytest.fixture(scope="module")
def body():
    r = recipe_from_seed(2, "benchmark", 0)
    feats = body_features(r.phenotype)
    return r, feats, texel_positions(feats, RES)


def _skin(body, tone: SkinTone, detail_seed: int | None = 4) -> np.ndarray:
    r, feats, pos = body
    rng = None if detail_seed is None else np.random.default_rng(detail_seed)
    return skin_texture(tone, r.hair.colour, feats, np.random.default_rng(1), RES, positions=pos, detail_rng=rng)


FULL = SkinTone(0.1, 0.5, freckles=1.0, blush=1.0, veins=1.0)


def test_skin_detail_is_deterministic(body):
    a, b = _skin(body, FULL), _skin(body, FULL)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, _skin(body, FULL, detail_seed=5))


def test_no_detail_keeps_the_texture_bit_for_bit(body):
    # Recipes written before the detail fields load with strengths 0 and must rebuild their old textures exactly.
    plain = _skin(body, SkinTone(0.1, 0.5), detail_seed=None)
    assert np.array_equal(plain, _skin(body, SkinTone(0.1, 0.5, 0.0, 0.0, 0.0), detail_seed=4))
    with pytest.raises(ValueError, match="detail_rng"):
        _skin(body, FULL, detail_seed=None)


def test_detail_is_low_contrast(body):
    plain = _skin(body, SkinTone(0.1, 0.5), detail_seed=None).astype(np.float64)
    full = _skin(body, FULL).astype(np.float64)
    ratio = full / np.maximum(plain, 1e-6)
    lo, hi = DETAIL_FACTOR_RANGE
    assert ratio.min() >= lo - 1e-5 and ratio.max() <= hi + 1e-5
    # The whole body's mean albedo moves by < 2%, the face's by < 6% (freckles and blush sit there).
    mean_change = np.abs(full.reshape(-1, 3).mean(0) / plain.reshape(-1, 3).mean(0) - 1.0)
    assert np.all(mean_change < 0.02), mean_change
    face = _mask("face", RES) > 0.5
    face_change = np.abs(full[face].mean(0) / plain[face].mean(0) - 1.0)
    assert np.all(face_change < 0.06), face_change
    # ... and yet it is there: freckles darken some face texels by > 10%, blush makes the face redder.
    assert (ratio[face][:, 1] < 0.9).mean() > 0.01
    assert full[face][:, 0].mean() / full[face][:, 1].mean() > plain[face][:, 0].mean() / plain[face][:, 1].mean()


def test_each_detail_changes_only_its_own_pattern(body):
    # One generator per pattern: adding blush leaves the freckles where they were.
    fr = _skin(body, SkinTone(0.1, 0.5, freckles=1.0))
    fr_bl = _skin(body, SkinTone(0.1, 0.5, freckles=1.0, blush=1.0))
    plain = _skin(body, SkinTone(0.1, 0.5), detail_seed=None)
    bl = _skin(body, SkinTone(0.1, 0.5, blush=1.0))
    both, product = fr_bl / plain, (fr / plain) * (bl / plain)
    lo, hi = DETAIL_FACTOR_RANGE
    free = np.all((product > lo + 1e-3) & (product < hi - 1e-3), axis=-1)  # not clipped
    assert free.mean() > 0.99
    np.testing.assert_allclose(both[free], product[free], rtol=1e-4, atol=1e-4)


def test_recipe_detail_fields_validate_and_old_json_loads():
    r = recipe_from_seed(6, "benchmark", 2)
    d = r.to_json()
    assert {"freckles", "blush", "veins"} <= set(d["skin"]) and all("fabric" in g for g in d["garments"])
    assert CharacterRecipe.from_json(r.to_json_text()) == r
    for g in d["garments"]:
        del g["fabric"]
    for k in ("freckles", "blush", "veins"):
        del d["skin"][k]
    old = CharacterRecipe.from_json(d)
    assert old.skin.freckles == old.skin.blush == old.skin.veins == 0.0
    assert all(g.fabric == "plain" for g in old.garments)
    with pytest.raises(ValueError, match="skin.freckles"):
        SkinTone(0.5, freckles=1.5)
    with pytest.raises(ValueError, match="garment.fabric"):
        Garment("tshirt", (0.5, 0.5, 0.5), fabric="silk")


def test_surface_detail_draws_are_their_own_stream():
    # The detail is drawn after, and apart from, everything else: stripping it gives the recipe's other fields.
    for seed in (2, 4, 6, 8):
        r = recipe_from_seed(seed, "benchmark", 0)
        assert 0.0 <= r.skin.veins <= 1.0 - r.skin.melanin + 1e-12
        assert all(g.fabric == "plain" for g in r.garments if g.kind == "shoes")


def test_knit_ribs_have_the_stated_period():
    n = 480
    a = np.linspace(0.0, 0.24, n, endpoint=False, dtype=np.float32)  # 24 cm across, 0.5 mm texels
    coords = np.stack(np.meshgrid(a, np.zeros(4, np.float32)), -1)
    f = knit_ribs(coords)[0].astype(np.float64)
    assert f.min() >= 0.85 - 1e-6 and f.max() <= 1.0
    spec = np.abs(np.fft.rfft(f - f.mean()))
    assert np.argmax(spec) == round(0.24 / KNIT_PERIOD_M)  # 20 wales in 24 cm
    g = Garment("longsleeve", (0.4, 0.3, 0.2), fabric="knit")
    res = 64
    coords = np.stack(np.meshgrid(np.linspace(0, 0.3, res), np.linspace(0, 0.3, res)), -1).astype(np.float32)
    knit = garment_texture(g, np.random.default_rng(0), res, coords)
    jersey = garment_texture(dataclasses.replace(g, fabric="jersey"), np.random.default_rng(0), res, coords)
    np.testing.assert_allclose(knit, np.clip(jersey * knit_ribs(coords)[..., None], 0.024, 0.8), atol=1e-6)


def _square(res: int, side_m: float) -> np.ndarray:
    """Texel-centre coordinates (res, res, 2) of a square `side_m` metres across."""
    a = ((np.arange(res) + 0.5) / res * side_m).astype(np.float32)
    return np.stack(np.meshgrid(a, a), -1)


def test_printed_noise_is_laid_out_in_metres():
    """The noise print's lattice is in metres: the same value at the same metric point whichever grid samples it,
    features twice the size at twice the period, and a noise garment's print over the same 60 cm square the same at
    two texture resolutions (as a part's own UV layout at two metres per UV would give it); colour2 covers `duty`."""
    from rh_dataset.characters.textures import metric_noise

    fine, coarse = _square(128, 0.6), _square(64, 0.6)
    points = fine[1::2, 1::2]  # texel centres of a 64-grid shifted by a quarter texel
    a = metric_noise(np.random.default_rng(3), points, 0.05)
    b = metric_noise(np.random.default_rng(3), fine, 0.05)[1::2, 1::2]
    np.testing.assert_array_equal(a, b)
    line = _square(2048, 2.0)[:64]  # 64 rows, 2 m long

    def crossings_per_metre(cell):
        n = metric_noise(np.random.default_rng(5), line, cell)
        return np.mean(np.sum(np.diff(np.sign(n - np.median(n)), axis=1) != 0, axis=1)) / 2.0

    ratio = crossings_per_metre(0.04) / crossings_per_metre(0.08)
    assert 1.6 < ratio < 2.5, ratio
    g = Garment("tshirt", (0.05, 0.05, 0.05), (0.7, 0.7, 0.7), pattern="noise", period_m=0.08, duty=0.4)
    hi = garment_texture(g, np.random.default_rng(1), 128, fine)[..., 0] > 0.2
    lo = garment_texture(g, np.random.default_rng(1), 64, coarse)[..., 0] > 0.2
    assert abs(hi.mean() - 0.4) < 0.05 and abs(lo.mean() - 0.4) < 0.05
    assert (hi[::2, ::2] == lo).mean() > 0.9, (hi[::2, ::2] == lo).mean()


# -----------------------------------------------------------------------------------------------------------------
# Sheen: what the albedo ground truth is
# -----------------------------------------------------------------------------------------------------------------
def _quad_render(sheen: float, tilt_deg: float, layers, spp: int):
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import select_variant

    select_variant("llvm_ad_rgb")
    tex = np.empty((8, 8, 3), np.float32)
    tex[:] = (0.5, 0.3, 0.2)
    tex[:4, :4] = (0.1, 0.6, 0.3)
    t = np.radians(tilt_deg)
    # A 2 x 2 m quad in the x-z plane facing -y, tilted about x by tilt_deg (0: facing the camera).
    c = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]
    c = [(x, z * np.sin(t), z * np.cos(t)) for x, _, z in c]
    q = quad(c, tex)
    q.material = Material(tex, 0.8, 0.15, two_sided=True, sheen=sheen)
    cam = Camera(width=24, height=24, fov_y_deg=8.0, origin=(0.0, -6.0, 0.0), target=(0.0, 0.0, 0.0))
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    return render_frame([q], env, cam, RenderSettings(spp=spp, aov_spp=4, max_depth=2), layers, seed=3).layers, tex


def test_sheen_albedo_is_the_texture():
    # The `aov` integrator's albedo is the BSDF's diffuse reflectance, which for `principled` is base_color: the
    # texture, whatever the sheen. The sheen is a lobe added on top (like the specular), not part of the albedo.
    albedos = []
    c0, c1 = np.array([0.5, 0.3, 0.2]), np.array([0.1, 0.6, 0.3])
    for sheen in (0.0, 1.0):
        out, tex = _quad_render(sheen, 0.0, ["albedo", "mask"], spp=4)
        inside = out["mask"] > 0.999
        alb = out["albedo"][inside].astype(np.float64)
        assert inside.sum() > 300
        # Every pixel is a texel colour or, at the bilinear edge between the two, a blend of them.
        t = np.clip((alb - c0) @ (c1 - c0) / ((c1 - c0) @ (c1 - c0)), 0.0, 1.0)
        assert np.abs(alb - (c0 + t[:, None] * (c1 - c0))).max() < 1e-5
        assert (t < 1e-6).mean() > 0.5 and (t > 1 - 1e-6).any()
        albedos.append(out["albedo"])
    assert np.array_equal(albedos[0], albedos[1])


def test_sheen_adds_light_at_grazing_angles_only():
    # Under uniform white light the sheen lobe brightens a grazing view and leaves a head-on view (almost) alone:
    # measured +11% at 80 degrees, < 0.5% head-on for sheen 1 on this base.
    def mean_image(sheen, tilt):
        out, _ = _quad_render(sheen, tilt, ["image", "mask"], spp=256)
        return out["image"][out["mask"] > 0.999].astype(np.float64).mean(0)

    head_on = mean_image(1.0, 0.0) / mean_image(0.0, 0.0)
    grazing = mean_image(1.0, 80.0) / mean_image(0.0, 80.0)
    assert np.all(np.abs(head_on - 1.0) < 0.01), head_on
    assert np.all(grazing > 1.05), grazing


# -----------------------------------------------------------------------------------------------------------------
# The diversity print (bench/subject_diversity.py)
# -----------------------------------------------------------------------------------------------------------------
def _diversity_module():
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "bench" / "subject_diversity.py"
    spec = importlib.util.spec_from_file_location("subject_diversity", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_hair_colour_names_recover_the_palette():
    from rh_dataset.characters.recipe_draws import HAIR_COLOUR_NAMES, _HAIR_PALETTE, hair_colour_name

    for name, rgb in zip(HAIR_COLOUR_NAMES, _HAIR_PALETTE):
        assert hair_colour_name(tuple(rgb * 1.06)) == name  # a brightness jitter of 6% keeps the name


def test_diversity_counts_every_subject_and_picks_up_new_fields():
    mod = _diversity_module()
    recipes = [recipe_from_seed(2 * (i + 1), "benchmark", i) for i in range(6)]
    lines = mod.summarise(recipes)
    text = "\n".join(lines)
    assert "subjects        6:" in text
    styles = next(line for line in lines if line.startswith("hair styles"))
    assert sum(int(w) for w in styles.replace(",", " ").split()[3::2]) == 6
    cats = next(line for line in lines if line.strip().startswith("categories"))
    assert sum(int(tok.split()[-1]) for tok in cats.split("(")[0].replace("categories", "").split(",")) == 6
    # A recipe field the script does not know by name (a later part's headwear, say) gets its own row, counted
    # by its kind.
    class WithHat:
        def __init__(self, r, hat):
            self._r, self._hat = r, hat

        def __getattr__(self, name):
            return getattr(self._r, name)

        def to_json(self):
            return {**self._r.to_json(), "headwear": self._hat}

    hats = [WithHat(r, h) for r, h in zip(recipes, [{"kind": "cap"}, None, {"kind": "cap"}, {"kind": "hijab"},
                                                      None, None])]
    row = next(line for line in mod.summarise(hats) if line.startswith("headwear"))
    assert "none 3" in row and "cap 2" in row and "hijab 1" in row
