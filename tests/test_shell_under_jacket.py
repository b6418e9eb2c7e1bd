"""A shell top under the open jacket over a draped bottom (drape.SHELLS_UNDER): its trunk is capped under the
jacket's panels at rest (garments._under_cover), and pose_character keeps it under them (character._shell_under_panels).

Benchmark subject 7 of seed 0 wears a shell long sleeve under the open jacket over straight-leg draped trousers
(since 5 December). Built at the coarse drape level (bench/bench_shell_top_under_jacket.py --subjects 7 --poses 2
--drape coarse --modes skinned, 5 December 05:56 UTC, load ~1.6): without the cap and push 44 of the top's vertices
(all but the sleeves') lay over the panels at rest (11.7 mm at worst), all seen by a camera around the subject, and
44-46 in its two test poses; with them, none in any of the three, and the panels' own bits are the same.
"""
from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def subject7():
    from rh_dataset.characters import build_character, sample_recipe
    from rh_dataset.generate.seeding import rng_for

    recipe = sample_recipe(rng_for(0, "character", 7), pool="benchmark", index=7)
    assert [g.kind for g in recipe.garments] == ["shoes", "draped_straight_trousers", "longsleeve", "draped_jacket"]
    return recipe, build_character(recipe, 32, drape="coarse")


def test_shells_under_names_a_shell_top_only_over_a_draped_bottom():
    from rh_dataset.characters.drape import shells_under

    assert shells_under("draped_jacket", ["shoes", "draped_shorts", "longsleeve", "coat", "draped_jacket"]) == (
        "longsleeve",)
    assert shells_under("draped_jacket", ["draped_skirt", "tshirt", "coat"]) == ("tshirt",)
    assert shells_under("draped_jacket", ["shoes", "trousers", "longsleeve", "coat"]) == ()  # a shell bottom
    assert shells_under("draped_coat", ["draped_shorts", "longsleeve", "coat"]) == ()
    assert shells_under("draped_jacket", ["draped_shorts", "draped_longsleeve", "longtop"]) == ()  # a loose top


def test_the_panels_are_draped_as_without_the_top_and_the_top_capped_under_them(subject7):
    """The cap moves the top, not the panels: the jacket's part at rest is its drape over the body and the trousers
    alone (to float32), as the generator drapes it without a shell top. The top's trunk, lifted over the trousers'
    waistband, is capped under the panels where they cover it (some of its offsets lowered below the lift), its
    sleeves not (their offsets reach the long sleeve's own 6 mm)."""
    from rh_common.body_model import ANNY_TOPOLOGY
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import group_mask
    from rh_dataset.characters.drape import SLEEVE_GROUPS
    from rh_dataset.characters.drape import drape_garment, drape_settings

    recipe, ch = subject7
    trousers = drape_garment("draped_straight_trousers", recipe.phenotype,
                             drape_settings("draped_straight_trousers", "coarse"))
    panels = drape_garment("draped_jacket", recipe.phenotype, drape_settings("draped_jacket", "coarse"),
                           over=(trousers,))
    from scipy.spatial import cKDTree

    rest = {m.name: m for m in pose_character(ch, {})}
    assert cKDTree(panels.vertices).query(rest["draped_jacket"].vertices.astype(np.float64))[0].max() < 1e-6
    part = ch.part("longsleeve")
    nearer = part.blend_vertices[np.arange(len(part.blend_vertices)), np.argmax(part.blend_weights, axis=1)]
    trunk = ~group_mask(ANNY_TOPOLOGY, *SLEEVE_GROUPS)[nearer]
    assert part.offset[~trunk].max() >= 0.006 - 1e-6
    assert part.offset[trunk].max() > 0.01  # lifted over the trousers' waistband where the panels do not cover it


def test_the_shell_top_stays_under_the_open_jacket(subject7):
    """At rest and in the subject's first test pose (skinned, as draft and standard pose it), none of the long
    sleeve's trunk vertices lies over the jacket's panels (layer_depth < 0 within LAYER_REACH, beyond none of their
    open edges)."""
    from rh_common.body_model import ANNY_TOPOLOGY, load_anny
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import group_mask
    from rh_dataset.characters.drape import SLEEVE_GROUPS
    from rh_dataset.characters.cloth_pose import LAYER_REACH, layer_depth
    from rh_dataset.generate.seeding import rng_for
    from rh_dataset.poses import sample_pose

    _, ch = subject7
    part = ch.part("longsleeve")
    nearer = part.blend_vertices[np.arange(len(part.blend_vertices)), np.argmax(part.blend_weights, axis=1)]
    trunk = ~group_mask(ANNY_TOPOLOGY, *SLEEVE_GROUPS)[nearer]
    for bones in ({}, dict(sample_pose(rng_for(0, "pose", 7, "test", 0), load_anny()).bones)):
        posed = {m.name: m for m in pose_character(ch, bones)}
        panels = posed["draped_jacket"]
        d = layer_depth(posed["longsleeve"].vertices.astype(np.float64), panels.vertices.astype(np.float64),
                        panels.faces, LAYER_REACH)
        assert not (trunk & (np.nan_to_num(d, nan=1.0) < 0.0)).any()


def test_over_shell_bottoms_nothing_is_capped(subject7):
    """Over shell trousers the rule names no shell (the top lies on the body under the panels' clearance there, and
    those subjects' geometry is what it was)."""
    from rh_dataset.characters.drape import shells_under

    recipe, _ = subject7
    shell = [("trousers" if g.kind == "draped_straight_trousers" else g.kind) for g in recipe.garments]
    assert shells_under("draped_jacket", shell) == ()
