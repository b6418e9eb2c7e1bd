"""The draped dress's bodice (garments.py shell "bodice", drape.SHELL_KINDS_OVER): a t-shirt's cut with cap sleeves
and a scoop neck whose hem lies SHELL_OVERLAP under the dress cloth's pinned ring (drape.shell_hem), tucked to
TUCK["bodice"] there so that it lies inside the cloth; without it the dress was strapless, its top edge across the
bust."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.body_model import ANNY_TOPOLOGY
from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.characters.body_features import body_features
from rh_dataset.characters.drape import (DRAPE_LEVELS, SHELL_KINDS_OVER, SHELL_OVERLAP, drape_settings,
                                         garment_pattern, shell_hem)
from rh_dataset.characters.garments import (BASE_OFFSET, TUCK, _shell, build_garments, garment_level,
                                            garment_parts)
from rh_dataset.characters.recipe import Garment

KIND = "draped_dress"
PHENO = {"gender": 0.0, "age": 0.5, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5}
HEAVY = {"gender": 0.0, "age": 0.6, "muscle": 0.5, "weight": 0.95, "height": 0.5, "proportions": 0.5}


def test_the_dress_is_built_as_its_bodice_then_its_cloth():
    assert SHELL_KINDS_OVER == {"draped_coat": "coat", "draped_jacket": "coat", "draped_dress": "bodice",
                                "draped_tshirt": "tee", "draped_longsleeve": "longtop", "draped_hoodie_body": "hoodie"}
    assert garment_parts(KIND) == ("bodice", KIND) and garment_parts("draped_skirt") == ("draped_skirt",)
    with pytest.raises(ValueError, match="shell_hem"):
        shell_hem("draped_skirt", PHENO)


@pytest.mark.parametrize("level", DRAPE_LEVELS)
@pytest.mark.parametrize("pheno", [PHENO, HEAVY], ids=["slim", "heavy"])
def test_bodice_hem_is_under_the_dress_ring(pheno, level):
    """The hem (bind space) is SHELL_OVERLAP under the pattern's pinned ring: bind space is the A-pose frame the
    cloth is cut in, raised by spine02's offset."""
    st = drape_settings(KIND, level)
    verts, _, _, pinned, _ = garment_pattern(KIND, pheno, st)
    run = run_anny(pheno)
    i = body_topology().bone_labels.index("spine02")
    shift = body_features(pheno).bone_heads["spine02"][2] - run["bone_poses"][i, 2, 3]
    z_ring = float(verts[pinned, 2].mean())
    assert shell_hem(KIND, pheno, st) == pytest.approx(z_ring + shift - SHELL_OVERLAP, abs=1e-9)


def test_bodice_is_a_short_sleeved_top_cut_at_the_chest():
    """Sleeves shorter than the t-shirt's, a deeper scoop in front, nothing of the trunk under the hem, the back
    above it covered; a bodice needs its hem."""
    feats = body_features(PHENO)
    hem = shell_hem(KIND, PHENO)
    bodice, tshirt = garment_level("bodice", feats, hem), garment_level("tshirt", feats)
    v = feats.rest_vertices
    arm = feats.in_groups("upperarm", "lowerarm", "hand")
    assert (bodice[arm] < 0).any() and not (bodice[arm] < 0)[tshirt[arm] >= 0].any()  # within the t-shirt's sleeves
    assert (bodice[arm] < 0).sum() < 0.7 * (tshirt[arm] < 0).sum()
    trunk = feats.in_groups("torso") & ~arm
    assert (bodice[trunk & (v[:, 2] < hem - 0.005)] > 0).all()
    assert (bodice[trunk & (v[:, 2] > hem + 0.005) & (v[:, 1] > 0.05)] < 0).any()
    # The neckline: at the front centre the bodice starts lower than the t-shirt does.
    front = trunk & (v[:, 1] < 0) & (np.abs(v[:, 0]) < 0.02)
    assert v[front & (bodice < 0), 2].max() < v[front & (tshirt < 0), 2].max() - 0.02
    with pytest.raises(ValueError, match="hem"):
        garment_level("bodice", feats)


def test_bodice_is_tucked_where_the_cloth_overlaps_it():
    feats = body_features(PHENO)
    hem = shell_hem(KIND, PHENO)
    shell = _shell("bodice", feats, np.zeros(len(feats.rest_vertices)), ANNY_TOPOLOGY, hem=hem)
    z = (feats.rest_vertices[shell.blend_vertices] * shell.blend_weights[..., None]).sum(1)[:, 2]
    tucked = z < hem + SHELL_OVERLAP
    assert tucked.any() and shell.offset[tucked].max() <= TUCK["bodice"] + 1e-6
    assert shell.offset.max() == pytest.approx(BASE_OFFSET["bodice"])
    assert TUCK["bodice"] < drape_settings(KIND).clearance  # inside the cloth's particle radius


@pytest.mark.slow
def test_bodice_lies_inside_the_dress_at_rest_and_in_poses(tmp_path, monkeypatch):
    """Built as the generator builds a dress wearer (full drape): the bodice's overlap lies under the draped cloth
    at rest, and in six sampled poses (skinned cloth) no cloth vertex sinks more than 1 mm under the bodice (measured
    on 3 December: the cloth nearest the bodice 1.0-1.1 mm outside it in every pose)."""
    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.cloth_pose import layer_depth
    from rh_dataset.characters.recipe import CharacterRecipe
    from rh_dataset.characters.recipe_draws import recipe_from_seed
    from rh_dataset.poses import sample_poses

    monkeypatch.setenv("RH_DRAPE_CACHE", str(tmp_path))
    base = recipe_from_seed(0, "benchmark", 0)
    recipe = CharacterRecipe(seed=base.seed, pool=base.pool, index=base.index, phenotype=PHENO, skin=base.skin,
                             hair=base.hair,
                             garments=(Garment("shoes", (0.1, 0.1, 0.1)), Garment(KIND, (0.2, 0.5, 0.3))))
    ch = build_character(recipe, 64)
    names = [p.name for p in ch.parts]
    assert names.index("bodice") + 1 == names.index(KIND)
    rest = {m.name: m for m in pose_character(ch, {})}
    z_ring = float(rest[KIND].vertices[:drape_settings(KIND).n_around, 2].mean())
    sv = rest["bodice"].vertices
    torso = body_features(PHENO).in_groups("torso")[ch.part("bodice").body_vertex]
    low = torso & (sv[:, 2] < z_ring - 0.003)
    depth = layer_depth(sv[low], rest[KIND].vertices, rest[KIND].faces)
    assert low.sum() > 50 and np.nan_to_num(depth, nan=1.0).min() > 0.0, np.nanmin(depth)
    under = {}
    for k, pose in enumerate(sample_poses(np.random.default_rng(7), load_anny(), 6)):
        posed = {m.name: m for m in pose_character(ch, dict(pose.bones))}
        d = np.nan_to_num(layer_depth(posed[KIND].vertices, posed["bodice"].vertices, posed["bodice"].faces), nan=-1)
        under[k, pose.label] = (float(d.max()), int((d > 0.001).sum()))
    print(under)
    assert all(n == 0 for _, n in under.values()), under
