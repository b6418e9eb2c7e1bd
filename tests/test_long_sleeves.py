"""The loose long sleeve's draped sleeves (drape.py kind `draped_long_sleeves`, cut by sleeves.py's `LONG_SLEEVES`):
two closed tubes from the short sleeves' pinned rings down to the wrists, bent at the elbow as anny's A-pose bends it,
faces outward, every particle off the body; a character in a loose long sleeve wears them (not under an open jacket
or coat), skinned to the arms and forearms. tests/test_sleeves.py checks them beside the short sleeves: the coarse
drape (off the arms, hanging), the shell "longtop"'s sleeves ending SHELL_OVERLAP under the rings, and posed (rest, a
raised arm, a bent elbow) off the body with the shell's sleeves inside. Bounds measured on this machine (5 December;
bench/bench_sleeves.py --kind draped_long_sleeves for the benchmark's wearers) and stated here."""
from __future__ import annotations

import numpy as np
import pytest

from rh_dataset.characters.body import body_topology, run_anny
from rh_dataset.characters.drape import (DRAPE_LEVELS, binding_faces, collider_faces, drape_settings,
                                         garment_pattern, penetration, push_clearance)
from rh_dataset.characters.geometry import edge_counts
from rh_dataset.characters.sleeves import LONG_SLEEVES, SIDES, SLEEVES, sleeve_axis, sleeve_pattern, sleeve_tops
from test_drape_coat import HEAVY, PHENO, _heads

KIND = "draped_long_sleeves"


@pytest.mark.parametrize("level", DRAPE_LEVELS)
@pytest.mark.parametrize("pheno", [PHENO, HEAVY], ids=["slim", "heavy"])
def test_long_sleeve_pattern_is_two_outward_tubes_bent_at_the_elbow(pheno, level):
    """Each tube: every edge in two faces but its top ring's and hem's, its top ring pinned and the short sleeves' own
    (the same place along the upper arm, `sleeve_tops`), every particle off the body by more than half the ring gap.
    Its rings run across the upper arm's axis at the top and across the forearm's at the hem, which lies within 5 cm
    of the wrist joint; each ring narrows from the one above by about `taper` per metre at most, and the hem is
    narrower than the top; faces outward (away from each ring's centre); the pattern function and the drape's agree."""
    st = drape_settings(KIND, level)
    na, nr = st.n_around, st.n_rings
    verts, faces, uvs, pinned, mpu, pieces = sleeve_pattern(pheno, na, nr, LONG_SLEEVES)
    assert verts.shape == (2 * na * nr, 3) and len(pieces) == 2
    np.testing.assert_array_equal(garment_pattern(KIND, pheno, st)[0], verts)
    _, counts = edge_counts(faces)
    assert set(counts.tolist()) == {1, 2} and (counts == 1).sum() == 4 * na
    assert np.array_equal(np.flatnonzero(pinned), np.sort(np.concatenate([g[0] for g in pieces])))
    short = sleeve_pattern(pheno, na, drape_settings("draped_sleeves", level).n_rings, SLEEVES)
    body = run_anny(pheno)["vertices"]
    assert penetration(body, body_topology().faces, verts).max() < -0.5 * LONG_SLEEVES.ring_gap
    heads = _heads(pheno)
    tops = sleeve_tops(pheno, na)
    for side, grid, sgrid in zip(SIDES, pieces, short[5]):
        np.testing.assert_allclose(verts[grid[0]], short[0][sgrid[0]], atol=1e-9)  # the short sleeves' ring
        o, a, _, _ = sleeve_axis(heads, side)
        assert ((verts[grid[0]] - o) @ a == pytest.approx(tops[side], abs=1e-9))
        fore = heads[f"wrist.{side}"] - heads[f"lowerarm01.{side}"]
        fore /= np.linalg.norm(fore)
        hem = verts[grid[-1]]
        assert np.ptp(hem @ fore) < 1e-6  # the hem ring lies across the forearm
        assert np.linalg.norm(hem.mean(0) - heads[f"wrist.{side}"]) < 0.05
        centres = verts[grid].mean(1)
        r = np.linalg.norm(verts[grid] - centres[:, None], axis=-1)
        step = np.linalg.norm(np.diff(centres, axis=0), axis=1)
        # (radii from each ring's vertex mean, which sits off the axis where the ring is not round: up to 1.31x
        # the taper measured on these two bodies)
        assert (np.diff(r, axis=0) >= -1.5 * LONG_SLEEVES.taper * step[:, None]).all()
        assert r[-1].mean() < r[0].mean() - 0.01  # narrower at the wrist
        own = np.isin(faces, grid.ravel()).all(1)
        ring_of = np.full(len(verts), -1)
        ring_of[grid] = np.arange(nr)[:, None]
        tri = verts[faces[own]]
        centre = centres[ring_of[faces[own]].min(1)]
        radial = tri.mean(1) - centre
        assert ((np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * radial).sum(1) > 0).all()
    assert uvs.min() >= 0.0 and uvs.max() <= 1.0 and mpu > 0.3
    assert push_clearance(KIND) == LONG_SLEEVES.ring_gap > st.clearance


def test_long_sleeves_collide_with_the_arms_and_are_bound_to_them():
    """As the short sleeves: the collider keeps the arms but the hands, the skinning comes from the arms alone."""
    for level in DRAPE_LEVELS:
        assert drape_settings(KIND, level).n_around == drape_settings("draped_sleeves", level).n_around
    np.testing.assert_array_equal(collider_faces(PHENO, KIND), collider_faces(PHENO, "draped_sleeves"))
    np.testing.assert_array_equal(binding_faces(PHENO, KIND), binding_faces(PHENO, "draped_sleeves"))


def test_parts_of_a_loose_long_sleeve():
    """The loose long sleeve is the shell, its body of cloth and its sleeves; none under an open jacket or a coat."""
    from rh_dataset.characters.garments import garment_parts

    assert garment_parts("draped_longsleeve") == ("longtop", "draped_longsleeve", KIND)
    for outer in ("draped_jacket", "draped_coat"):
        assert garment_parts("draped_longsleeve", ["draped_longsleeve", outer]) == ("longtop", "draped_longsleeve")


def test_hoodie_sleeves_are_the_long_cut_in_the_hoods_fleece():
    """The hoodie's draped sleeves: the long sleeves' cut and particles, the hood's fabric, a stiffer contact."""
    import dataclasses

    from rh_dataset.characters.drape import DRAPE_LEVELS, drape_settings
    from rh_dataset.characters.garments import garment_parts
    from rh_dataset.characters.sleeves import LONG_SLEEVES, SLEEVE_CUTS

    assert SLEEVE_CUTS["draped_hoodie_sleeves"] == LONG_SLEEVES
    assert garment_parts("draped_hoodie") == ("hoodie", "draped_hoodie_body", "draped_hoodie", "draped_hoodie_sleeves")
    for level in DRAPE_LEVELS:
        jersey, fleece = drape_settings(KIND, level), drape_settings("draped_hoodie_sleeves", level)
        hood = drape_settings("draped_hoodie", level)
        fabric = ("density", "tri_ke", "tri_ka", "edge_ke")
        assert all(getattr(fleece, k) == getattr(hood, k) != getattr(jersey, k) for k in fabric)
        assert fleece.contact_ke > jersey.contact_ke
        same = {f.name for f in dataclasses.fields(jersey)} - set(fabric) - {"contact_ke"}
        assert all(getattr(fleece, k) == getattr(jersey, k) for k in same)
