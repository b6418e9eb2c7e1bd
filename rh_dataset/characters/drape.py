"""Loose garments draped by a real cloth solver (newton's VBD) onto the anny body in its rest pose.

In: a phenotype, a draped garment kind (`DRAPED_KINDS`: a skirt, a dress's cloth (its bodice is a shell), wide-leg
or straight-leg trousers or loose shorts, an open coat's or an open jacket's panels, a hoodie's hood (`HoodCut`,
`_hood_pattern`: a bag pinned on the back of the neckline, laid back and let fall down the upper back, over the
hoodie's body), a loose t-shirt's, long sleeve's or hoodie's body (a tube hanging from over the bust to the hips;
its shoulders and sleeves are the shell "tee", "longtop" or "hoodie", laid where the fabric hangs over the bust:
`hanging_surface`), the loose t-shirt's short sleeves
(`draped_sleeves`: two tubes round the upper arms, cut by sleeves.py), the loose long sleeve's
(`draped_long_sleeves`: down to the wrists, bent at the elbows) and the hoodie's and the open coat's
(`draped_hoodie_sleeves`, `draped_coat_sleeves`: the same cut in the hood's fleece, and kept 16 mm off the arm));
`PROFILES` cuts the others from one pattern function, `garment_pattern`: the trousers' waist tube divides into two
leg tubes, `_trouser_pattern`; the coat's and the jacket's tubes are cut open at the front, `DrapeProfile.opening`,
and their shoulders and sleeves are one shell, garments.py's "coat", whose hem `shell_hem` places, as it places the
dress's bodice) and its `DrapeSettings` (per kind and drape level: `drape_settings`).
Out: `DrapedGarment`, the garment's settled rest-pose surface (vertices, faces, UVs) after `DrapeSettings.steps`
steps of newton's `SolverVBD` with gravity, cloth self-contact and the body mesh (arms and hands left out) as a
static collider (with the draped cloth under it, `DRAPED_OVER`: a loose top's skirt or wide trousers, an open
jacket's or coat's loose top and skirt), plus the
skinning that moves it per frame (`SkinBinding`: the body's linear-blend weights
transferred from the closest body point and, below the hips, diffused over the cloth so it stays one piece in a
stride (`bind_loose`); the garment expressed in anny's bind space) and `push_out`, which puts skinned cloth that a
limb swung into back on the skin (`push_clearance` off it: the coat and jacket, worn over other clothes, farther).
`penetration` measures.

Why a solver, not a shell: a skirt's hem is longer than the body it hangs around, so it folds; only a cloth
simulation finds where. The drape runs once per (phenotype, kind, settings) and is cached in a content-hashed
.npz (`drape_cache_dir()`), so frames only skin it. Two simulations on this machine give the same bits and the
cached file reads back as a fresh run (`tests/test_drape.py -m slow`); other machines or Warp/newton versions are
not promised the same bits, which is why those versions are part of the cache key.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rh_common.body_model import ANNY_TOPOLOGY
from rh_common.imageio import atomic_path

from rh_dataset.mesh import vertex_normals

from .body import PHENOTYPE_LABELS, body_topology, run_anny
from .body_features import body_features
from .geometry import (closest_point, edge_counts, faces_in_box, hull_anchors, metre_uvs, query_mesh, seamed_grid,
                       smoothstep)
from .sleeves import SLEEVE_CUTS, sleeve_pattern, sleeves_render_mesh

__all__ = ["DRAPED_KINDS", "DrapeSettings", "DrapedGarment", "SkinBinding", "drape_garment", "garment_pattern",
           "DRAPED_OVER", "draped_over", "DRAPED_PIECES", "draped_pieces",
           "SHELLS_UNDER", "SLEEVE_GROUPS", "shells_under", "SHELL_TOPS", "BOTTOMS_UNDER",
           "DrapeProfile", "PROFILES", "drape_settings", "DRAPE_LEVELS",
           "bind_to_skeleton", "bind_loose", "loose_iterations", "skin_points", "drape_cache_dir", "DRAPE_VERSION",
           "draped_part", "penetration", "closest_on_surface", "push_out", "push_clearance", "PUSH_CLEARANCES",
           "collider_faces",
           "cloth_model", "cloth_solver", "binding_faces", "SLEEVE_CLEARANCE",
           "shell_hem", "shell_hems", "ring_height", "hanging_surface", "HangingSurface", "BRIDGE_BAND",
           "piece_settings", "BUST_UNDER_NOT",
           "SHELL_KINDS_OVER", "SHELL_OVERLAP", "COAT_CLEARANCE", "HOOD",
           "HoodCut", "HOOD_CLEARANCE", "FRONT_OPENING", "JACKET_HEM", "TSHIRT_CLEARANCE",
           "TSHIRT_HEM", "SHORTS_HEM", "SHORTS_MIN_LEG", "STRAIGHT_LEGS"]

DRAPED_KINDS = ("draped_skirt", "draped_dress", "draped_trousers", "draped_coat", "draped_hoodie", "draped_jacket",
                "draped_tshirt", "draped_longsleeve", "draped_shorts", "draped_straight_trousers", "draped_sleeves",
                "draped_long_sleeves", "draped_hoodie_sleeves", "draped_coat_sleeves", "draped_hoodie_body")
DRAPE_VERSION = 5  # bump when the simulation changes (the pattern's bytes are part of the cache key too)
CACHE_ENV = "RH_DRAPE_CACHE"
PUSH_CLEARANCE = 0.003  # metres the skinned cloth is kept above the posed skin (push_out)
# The coat's panels are the outermost layer: they hang over the shell trousers (7 mm), shorts and the tops' hems
# (up to ~10 mm where a top lies over a waistband), so push_out keeps them this far off the skin instead; a little
# less than the drape keeps them at rest (its particle radius, COAT_CLEARANCE), so that push_out leaves the rest
# drape as it settled and moves only what a limb swung into.
# The open jacket (`draped_jacket`) is the coat cut short: the same layers under it, the same clearances.
# The loose t-shirt's body (`draped_tshirt`) hangs over the shell trousers' or shorts' waistband (7 mm): push_out
# keeps it 10 mm off the skin (the waistband's offset and `garments.LAYER_GAP`), its drape TSHIRT_CLEARANCE (its
# particles settle a little closer than their radius where the cloth rests on the body, as the coat's do).
# The loose t-shirt's sleeves (`draped_sleeves`, sleeves.py) lie over the shell "tee"'s sleeves (6 mm) just under
# their pinned rings: 8 mm, their cut's ring gap; the loose long sleeve's (`draped_long_sleeves`) likewise.
PUSH_CLEARANCES = {"draped_coat": 0.012, "draped_jacket": 0.012, "draped_hoodie": 0.010, "draped_tshirt": 0.010,
                   "draped_sleeves": 0.008, "draped_long_sleeves": 0.008,
                   "draped_hoodie_sleeves": 0.008, "draped_coat_sleeves": 0.012}
COAT_CLEARANCE = 0.014
TSHIRT_CLEARANCE = 0.012
SLEEVE_CLEARANCE = 0.006
# The hood lies over the hoodie's shell (6 mm off the skin, a longsleeve's): its particles keep this far off the skin
# at rest (the coat's; where its weight rests on the shoulders' slope the worst particle comes to 2-6 mm,
# tests/test_drape_hoodie.py), push_out 10 mm (PUSH_CLEARANCES) when posed.
HOOD_CLEARANCE = 0.014


@dataclasses.dataclass(frozen=True)
class DrapeSettings:
    """The simulation: `steps` VBD steps of `dt` seconds (collision detection every `collide_every` steps),
    `iterations` VBD sweeps per step. Stiffnesses are newton's (tri: membrane, edge: bending), for a light woven
    fabric of `density` kg/m^2. `clearance`: particle radius, the gap newton keeps between cloth and body.
    `self_contact`: VBD's cloth-cloth contact (vertex-triangle and edge-edge, interacting within
    `self_contact_margin`, detected within margin + `self_contact_gap`), so folds do not pass through each other.
    `settle`: steps of dynamic relaxation after `steps`, in which each particle keeps the fraction `settle_keep` of
    its velocity from one step to the next (a viscous damping; 0: each step from rest), so the drape ends nearer the
    cloth's static equilibrium than at a moment of its swing. Only the full hood settles, from rest: on the body
    neither way reaches rest in 100 steps (docs/ARCHITECTURE.md, "Does a drape end at rest?")."""

    steps: int = 300
    settle: int = 0
    settle_keep: float = 0.0
    dt: float = 0.01
    iterations: int = 10
    collide_every: int = 5
    density: float = 0.2
    tri_ke: float = 1.0e4
    tri_ka: float = 1.0e4
    tri_kd: float = 1.0e-5
    edge_ke: float = 1.0e-3
    edge_kd: float = 1.0e-6
    clearance: float = 0.004
    contact_gap: float = 0.01
    contact_ke: float = 1.0e4
    contact_kd: float = 1.0e-2
    friction: float = 0.5
    self_contact: bool = True
    self_contact_margin: float = 0.003
    self_contact_gap: float = 0.0015
    flare: float = 0.6  # radians: the pattern's cone half-angle (a circle skirt is pi/2)
    n_around: int = 72
    n_rings: int = 24
    # A loose top (BRIDGE_BAND) hung over the bust (its ring over the apex, its front spanning bust and belly, its
    # shell laid there: "Over the bust"), or, under an open jacket or a coat (`piece_settings`), from under the arms as
    # their panels are. Left out of the drape cache key where True (a key without it reads back as before).
    over_bust: bool = True


@dataclasses.dataclass(frozen=True)
class DrapedGarment:
    """Settled garment in the rest pose (anny's A-pose, metres, Z up): vertices (V, 3) float64, faces (F, 3) int32
    (outward), uvs (V, 2) float32 in [0, 1], `pinned` (V,) bool (the waistband, held on the body). `pattern`
    (V, 3): the undraped cloth it was simulated from, whose triangles and bends are the cloth's rest shape (a
    simulation that goes on from `vertices` must keep them: taking the draped, gravity-stretched surface as the
    rest shape would let the skirt sag further and keep its folds as memory). `pieces`: for kinds that are not one
    tube (trousers), the tubes the cloth is made of, each a (rings, around) grid of vertex indices whose columns
    wrap (None: one tube of `n_rings` x `n_around`)."""

    kind: str
    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    pinned: np.ndarray
    metres_per_uv: float
    pattern: np.ndarray | None = None
    pieces: tuple[np.ndarray, ...] | None = None  # trousers: (rings, around) vertex grids (`_trouser_pattern`)


@dataclasses.dataclass(frozen=True)
class SkinBinding:
    """Linear-blend skinning of garment points: posed_i = sum_k w_ik T[b_ik] @ bind_i with T = bone_poses @
    inverse(rest_bone_poses) of the frame's anny run. bind (V, 3) float64 in anny's bind space; bones (V, K) int64;
    weights (V, K) float32, rows sum to 1."""

    bind: np.ndarray
    bones: np.ndarray
    weights: np.ndarray


def drape_cache_dir() -> Path:
    env = os.environ.get(CACHE_ENV)
    return Path(env) if env else Path.home() / ".cache" / "relighting-humans" / "drape"


@dataclasses.dataclass(frozen=True)
class DrapeProfile:
    """The cut of a draped kind, in body landmarks: the pinned top ring at `top` ("waist": between the pelvis and
    spine04, where a skirt's waistband sits; "chest": halfway between spine02 and spine01, under the arms, lowered
    where the ring would touch the A-pose body, arms included (`_under_the_arms`): the coat's and the jacket's
    panels are held there; "bust": the loose tops' and the dress's, raised from there to over the bust where the
    arms leave room, `_bust_height`,
    the pattern as long as from "chest" plus the rise, so the hem stays where it was; but from "chest" under an
    open jacket or a coat: `DrapeSettings.over_bust`), the cloth hanging straight down from there to `flare_from`
    ("top": at once; "hips": the hip joints),
    then flaring at `DrapeSettings.flare` for `hem` times the drop from there to the knee (measured along the
    cloth): the skirt's hem ends about 10 cm above the knee; the dress, whose 70 cm of cloth hang from the chest and
    give way by ~15 cm under their weight (measured: the hem of a 0.9 pattern settled 17 cm lower, 9 cm under the
    knee), is cut shorter; the loose t-shirt flares from the chest (`TSHIRT_HEM`). Every ring stays `clearance` +
    2 mm outside the convex hull of the trunk's, shoulders' and thighs' cross-section at its height, so the pattern
    starts clear of the body wherever the hips are wider than the cloth above them.

    `ring_gap` (the loose t-shirt): metres the pinned ring keeps outside that hull instead (0: `clearance` + 2 mm),
    so it closes onto the shell it covers (`SHELL_KINDS_OVER`) and no slot opens between shell and cloth where one
    looks up under the ring; the rings below keep the cloth's own gap (the pattern steps out over the first ring
    spacing). Its height under the arms is found with this gap too (`_ring_levels`, `shell_hem`).

    `legs` (trousers, `_trouser_pattern`): the tube from the waist hangs straight (kept outside the hips) down to
    just under the crotch, where it divides into two leg tubes along a crotch seam between the thighs; each leg
    is a cone of half-angle `DrapeSettings.flare` whose top radius is `legs` times half the hips' width at the
    split, its hem `hem` metres above the floor (`hem` is not a fraction for trousers), or, where `leg_hem` > 0
    (the shorts), `leg_hem` of the hip-joint-to-ankle drop under the hip joints (the shell shorts' cut is measured
    along the leg the same way, garments.py).

    `opening` (the coat, the jacket): metres between the two front edges at the top ring; the tube is cut open there (no
    particles in the front sector that width subtends at the ring's front radius, all the way down), so the two
    front panels hang free. The coat's and the jacket's cloth is only their lower body: the shell "coat"
    (garments.py) makes their shoulders, yoke and sleeves down to just below the pinned ring (`SHELL_OVERLAP`)."""

    top: str
    flare_from: str
    hem: float = 0.9
    legs: float = 0.0
    opening: float = 0.0
    ring_gap: float = 0.0
    leg_hem: float = 0.0


# The open jacket's cut (`draped_jacket`): the coat's, its flared part JACKET_HEM of the hip-to-knee drop, so the
# hem settles between the hip joints and the crotch. Measured by bench/bench_drape_hem.py (4 builds: slim woman,
# heavy man, thin tall man, heavy short woman; 3 December): the pattern's hem, 2.2-3.2 cm under the hip joints,
# settles 2.9-4.1 cm above the crotch (5.2-7.0 cm under the hip joints) in the full drape, 5.4-6.2 cm above it in the
# coarse one (150 steps: it sags less far); cut at 0.15 the full drape's hem settled at the crotch (-0.6 to +1.7 cm),
# at 0.2 on or under it (-3.2 to 0.0 cm).
JACKET_HEM = 0.08
# The loose t-shirt's cut (`draped_tshirt`): flaring from the chest at its settings' 0.12 rad (so ~3.7 cm wider at the
# hem than under the arms: enough cloth to fall in soft waves, not enough for a tent) for TSHIRT_HEM of the chest-to-
# knee drop. Measured (3 December, slim and heavy test builds and seed-0 subjects 3, 9, 12, 31): the pattern's hem,
# 2.6 cm under to 0.4 cm over the hip joints, settles 1.6-4.6 cm under them in the full drape (5 cm or more above the
# crotch), 0.1-3.1 cm in the coarse one; at 0.4 it settled 0.7-2.0 cm above them on four of the six.
TSHIRT_HEM = 0.45
# Metres the loose t-shirt's pinned ring keeps outside the trunk's hull (`DrapeProfile.ring_gap`): its push clearance,
# so posing leaves it where it was draped (push_out would move it there anyway), over the shell "tee" lifted to 7.5 mm
# under it (garments.TUCK). At the cloth's own 14 mm the ring stood 8 mm or more off the shell (tapered to ~4.5 mm at
# the ring's height), and seen from above (a bending pose, bench_cloth_pose.py --figure) the slot between them showed
# as a dark line across the chest.
TSHIRT_RING_GAP = 0.010
# The loose shorts' cut (`draped_shorts`): the wide trousers' pattern, its legs cut SHORTS_HEM of the hip-joint-to-
# ankle drop under the hip joints (the shell shorts end at 0.42 of the leg's length from the hip joint).
SHORTS_HEM = 0.38
# Metres the shorts' legs reach under the crotch at least: on a heavy, short adult (anny height 0, weight 1) the cut at
# SHORTS_HEM comes within 2.3 cm of the crotch; the benchmark's shorts wearers have 20 cm or more, which this leaves
# as cut. LEG_RINGS_MIN: rings each leg tube has at least below the split ring (a pants pattern with fewer is no
# pair of legs); bodies whose legs cannot take them (an infant's) are refused with a message.
SHORTS_MIN_LEG = 0.08
LEG_RINGS_MIN = 2
# The straight-leg trousers' cut (`draped_straight_trousers`): the wide trousers' pattern, hem and fabric, each leg a
# cylinder (no flare) whose radius is STRAIGHT_LEGS of the wide legs' top radius (`DrapeProfile.legs`; a quarter of
# the split ring's width: the wide trousers' 1.0 and 0.06 rad flare hang as palazzos): ordinary trousers, loose on
# the thigh, hanging straight past the knee.
STRAIGHT_LEGS = 0.7
FRONT_OPENING = 0.05  # metres between the open coat's and jacket's front edges at the pinned ring (their one shell's V)
PROFILES = {"draped_skirt": DrapeProfile("waist", "top"), "draped_dress": DrapeProfile("bust", "hips", 0.7),
            "draped_trousers": DrapeProfile("waist", "top", 0.16, legs=1.0),
            "draped_shorts": DrapeProfile("waist", "top", legs=1.0, leg_hem=SHORTS_HEM),
            "draped_straight_trousers": DrapeProfile("waist", "top", 0.16, legs=STRAIGHT_LEGS),
            "draped_coat": DrapeProfile("chest", "hips", 1.2, opening=FRONT_OPENING),
            "draped_jacket": DrapeProfile("chest", "hips", JACKET_HEM, opening=FRONT_OPENING),
            "draped_tshirt": DrapeProfile("bust", "top", TSHIRT_HEM, ring_gap=TSHIRT_RING_GAP)}
SHELL_OVERLAP = 0.015  # metres a shell over draped cloth (SHELL_KINDS_OVER) reaches below its pinned ring, inside it


@dataclasses.dataclass(frozen=True)
class HoodCut:
    """The cut of the hoodie's hood (`draped_hoodie`; its shoulders are the longsleeve's shell "hoodie", garments.py,
    its body `draped_hoodie_body`, draped under the hood, and its sleeves `draped_hoodie_sleeves`).
    The hood is cut as it is worn up, in horizontal sections around the head: `DrapeSettings.n_rings` C-shaped
    rows of `n_around` particles, from the pinned neckline ring (row 0) to the crown (the last row), open at the front
    (the face opening: the two end columns and the crown's small last row are the cloth's free edge).

    Row 0 lies on the longsleeve's neckline lowered by `drop` metres (so the hood's edge covers the shell's),
    `clearance` + 2 mm off the skin along its normal, from `front` radians off the front (-Y, about the neck's
    centre) round the back to the other side: `front` = pi/2 pins the back half of the neckline. Going up, the rows
    reach `widen` radians further forward (the sides of the hood round the cheeks; the face opening), and swell from
    the neckline to an ellipse of half-axes `width` (across) by `depth` (front to back) around the head by 40 % of
    the way up, then close over the crown, `height` metres over the neckline (measured along the hood-up axis). This
    shape is the cloth's rest shape: a bag (a dome over the crown, a saddle where it swells from the neckline),
    which cannot lie flat, so it folds where it falls.

    Hood down: each row is then turned back about the horizontal line across the back of the neckline ring by
    `tilt` radians times a smoothstep of its height (rows above 35 % fully), so the cloth starts laid back, clear of
    head and back, its opening facing up; under gravity the solver lets it fall onto the shoulders and upper back."""

    front: float = 0.5 * np.pi
    widen: float = float(np.radians(50.0))
    drop: float = 0.008
    width: float = 0.105
    depth: float = 0.115
    height: float = 0.13
    tilt: float = float(np.radians(105.0))


HOOD = HoodCut()
# The simulation per (kind, level). "full": the benchmark's. The dress is about twice the skirt's length; 36 rings
# (2 cm apart, the skirt's 1.6 cm) keep its drape to ~1.5x the skirt's particles. "coarse": half the particles
# around and along, half the steps (~1/8 of the work): the draft preset's, for quick looks, the demo and tests
# (bench/bench_drape_cost.py measures both).
DRAPE_LEVELS = ("full", "coarse")
_HOOD_FABRIC = dict(density=0.3, tri_ke=1.0e5, tri_ka=1.0e5, edge_ke=0.1, contact_ke=2.0e5, clearance=HOOD_CLEARANCE)
_SETTINGS = {
    ("draped_skirt", "full"): DrapeSettings(),
    ("draped_dress", "full"): DrapeSettings(n_rings=36, contact_ke=5.0e4),
    ("draped_skirt", "coarse"): DrapeSettings(n_around=36, n_rings=12, steps=150),
    ("draped_dress", "coarse"): DrapeSettings(n_around=36, n_rings=18, steps=150, contact_ke=5.0e4),
    ("draped_trousers", "full"): DrapeSettings(n_around=64, n_rings=32, iterations=20, flare=0.06, tri_ke=1.0e5,
                                               tri_ka=1.0e5, contact_ke=5.0e4),
    ("draped_trousers", "coarse"): DrapeSettings(n_around=32, n_rings=16, steps=150, iterations=20, flare=0.06,
                                                 tri_ke=1.0e5, tri_ka=1.0e5, contact_ke=5.0e4),
    # The coat: the dress's cut from the chest, longer, kept further off the skin (the layers under it).
    ("draped_coat", "full"): DrapeSettings(n_rings=40, contact_ke=5.0e4, clearance=COAT_CLEARANCE),
    ("draped_coat", "coarse"): DrapeSettings(n_around=36, n_rings=20, steps=150, contact_ke=5.0e4,
                                             clearance=COAT_CLEARANCE),
    # The open jacket: the coat's fabric and spacing (rings ~1.8 cm apart, coarse ~3.8 cm) over its 33-36 cm of cloth.
    ("draped_jacket", "full"): DrapeSettings(n_rings=20, contact_ke=5.0e4, clearance=COAT_CLEARANCE),
    ("draped_jacket", "coarse"): DrapeSettings(n_around=36, n_rings=10, steps=150, contact_ke=5.0e4,
                                               clearance=COAT_CLEARANCE),
    # The loose t-shirt's body: a closed cone of the skirt's light fabric from under the arms to the hips, flaring
    # at 0.12 rad (TSHIRT_HEM), the coat's contact stiffness; rings ~2.1 cm apart (coarse ~4.6 cm) over its ~32 cm.
    ("draped_tshirt", "full"): DrapeSettings(n_rings=16, contact_ke=5.0e4, clearance=TSHIRT_CLEARANCE, flare=0.12),
    ("draped_tshirt", "coarse"): DrapeSettings(n_around=36, n_rings=8, steps=150, contact_ke=5.0e4,
                                               clearance=TSHIRT_CLEARANCE, flare=0.12),
    # The hood: a heavier, firmer knit (sweatshirt fleece: 0.3 kg/m^2, ten times the skirt's membrane stiffness and a
    # hundred times its bending stiffness), so it sags less and folds in rounder rolls; 32 x 24 particles (~1.5 cm
    # apart), contact found every step and the fleece's contact stiffness, 2e5, as its body and sleeves have (it
    # rests on the shoulders' slope; at 5e4 particles came to 1.5 mm off the skin, under the shell; at 1e5, to 6
    # December, the slim test body's particle next to the pinned ring over the right trapezius was pressed into the
    # skin by the stretched first row and stayed there, 1.1 mm in, its triangles folded over: 2e5 holds it 10 mm
    # off), its collider keeping the upper arms
    # (`collider_faces`: without them a heavy body's hood corners sank 6 mm into the deltoids). The coarse level
    # keeps 16 rows (with 12 a corner next to the pinned ring fell 12 mm into the shoulder; measured before the ring
    # was put on the neckline) and the full level's 300 steps
    # (256 particles; with 150 the hood was still falling). After its 300 steps the full hood still swings: 100 settle
    # steps (+5 s) moved subject 13's by up to 32 mm, 99 % of it by 29 mm or less (bench/bench_drape_settle.py), and
    # brought tests/test_drape_hoodie.py's slim build from a particle beside the neck 4.9 mm in the skin (caught
    # mid-swing) to every particle 1.5 mm or more off it.
    ("draped_hoodie", "full"): DrapeSettings(n_around=32, n_rings=24, collide_every=1, settle=100, **_HOOD_FABRIC),
    ("draped_hoodie", "coarse"): DrapeSettings(n_around=16, n_rings=16, collide_every=1, **_HOOD_FABRIC),
}


# The loose t-shirt's sleeves (`draped_sleeves`, sleeves.py): the t-shirt body's fabric, particles SLEEVE_CLEARANCE
# (the cut keeps its rings 8 mm off the arm's hull), 32 around (~1 cm apart) and 10 rings (~1 cm) over their 7-10 cm;
# coarse, half of each.
_SETTINGS[("draped_sleeves", "full")] = DrapeSettings(n_around=32, n_rings=10, contact_ke=5.0e4,
                                                      clearance=SLEEVE_CLEARANCE)
_SETTINGS[("draped_sleeves", "coarse")] = DrapeSettings(n_around=16, n_rings=5, steps=150, contact_ke=5.0e4,
                                                        clearance=SLEEVE_CLEARANCE)
# The loose long sleeve's sleeves (`draped_long_sleeves`): the same fabric and spacing round the arm, 28 rings
# (~1.2-1.6 cm apart) over their 33-43 cm from the ring to the hem; coarse, 16 x 10.
_SETTINGS[("draped_long_sleeves", "full")] = dataclasses.replace(_SETTINGS["draped_sleeves", "full"], n_rings=28)
_SETTINGS[("draped_long_sleeves", "coarse")] = dataclasses.replace(_SETTINGS["draped_sleeves", "coarse"], n_rings=10)
# The hoodie's sleeves (`draped_hoodie_sleeves`): the long sleeves' cut and particles in the hood's fleece (`_FLEECE`:
# half as heavy again, a tenfold stiffer membrane, bending a hundredfold stiffer than the jersey's, and a contact
# four times the jersey sleeves', 2e5): at their 5e4 the heavier, stiffer tube's coarse drape put a particle 2.8 mm
# into the slim test body's forearm (tests/test_sleeves.py's coarse drape keeps every particle half its radius off). The
# particle radius stays the sleeves' (the hood's 14 mm is for lying over the shell's back, not round an arm).
_FLEECE = {k: _HOOD_FABRIC[k] for k in ("density", "tri_ke", "tri_ka", "edge_ke", "contact_ke")}
for _level in ("full", "coarse"):
    _SETTINGS[("draped_hoodie_sleeves", _level)] = dataclasses.replace(_SETTINGS["draped_long_sleeves", _level],
                                                                       **_FLEECE)
# The open coat's sleeves (`draped_coat_sleeves`): the long sleeves' particles and fabric (the coat's panels are
# simulated in the same default fabric), the coat's particle radius, so the drape keeps them over the top's shell
# sleeve (6 mm off the arm) as the panels keep over the clothes under them; pushed out to the coat's 12 mm posed.
for _level in ("full", "coarse"):
    _SETTINGS[("draped_coat_sleeves", _level)] = dataclasses.replace(_SETTINGS["draped_long_sleeves", _level],
                                                                     clearance=COAT_CLEARANCE)


# The loose long sleeve (`draped_longsleeve`) is the loose t-shirt's body of cloth under the longsleeve's shell:
# the same cut, settings and clearances.
PROFILES["draped_longsleeve"] = PROFILES["draped_tshirt"]
PUSH_CLEARANCES["draped_longsleeve"] = PUSH_CLEARANCES["draped_tshirt"]
_SETTINGS.update({("draped_longsleeve", level): _SETTINGS["draped_tshirt", level] for level in DRAPE_LEVELS})
# The hoodie's body (`draped_hoodie_body`, since 6 December; a shell cut like the longsleeve's before, which showed
# the body's shape under a hood and sleeves of loose fleece): the loose t-shirt's cut, clearances and particles in
# the hood's fleece, its contact stiffness included (2e5: the heavier cloth rests on the hips' slope and on a draped
# bottom's waistband, where the jersey's 5e4 is the light cloth's).
PROFILES["draped_hoodie_body"] = PROFILES["draped_tshirt"]
PUSH_CLEARANCES["draped_hoodie_body"] = PUSH_CLEARANCES["draped_tshirt"]
_SETTINGS.update({("draped_hoodie_body", level): dataclasses.replace(_SETTINGS["draped_tshirt", level], **_FLEECE)
                  for level in DRAPE_LEVELS})
# The loose shorts: the wide trousers' settings with half their rings (the same ~2.7 cm spacing, coarse ~6 cm, over
# their ~45 cm).
_SETTINGS.update({("draped_shorts", level): dataclasses.replace(st, n_rings=st.n_rings // 2)
                  for level in DRAPE_LEVELS for st in (_SETTINGS["draped_trousers", level],)})
# The straight-leg trousers: the wide trousers' settings without the flare.
_SETTINGS.update({("draped_straight_trousers", level): dataclasses.replace(_SETTINGS["draped_trousers", level],
                                                                           flare=0.0) for level in DRAPE_LEVELS})


def drape_settings(kind: str, level: str = "full") -> DrapeSettings:
    """The `DrapeSettings` a draped kind is draped with at `level` (one of DRAPE_LEVELS; `RenderSettings.drape`)."""
    if kind not in DRAPED_KINDS:
        raise ValueError(f"drape: kind must be one of {DRAPED_KINDS}, got {kind!r}")
    if level not in DRAPE_LEVELS:
        raise ValueError(f"drape: level must be one of {DRAPE_LEVELS}, got {level!r}")
    return _SETTINGS[kind, level]


def _hull_radii(feats, v: np.ndarray, z: float, centre: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Radii (len(ang),) from `centre` (xy) at angles `ang` (0 = -Y, the front, then towards +X) to where rays
    leave the convex hull of the cross-section of the body `v` (the A-pose the cloth is draped on, not anny's bind
    space) within 1.5 cm of height z, trunk, shoulders and
    thighs (the collider; `hull_anchors`; arms and hands are not part of it); -inf where the band has too few
    vertices."""
    band = np.flatnonzero(feats.in_groups("torso", "shoulder", "upperleg") & (np.abs(v[:, 2] - z) < 0.015))
    return _band_radii(v, band, centre, ang)


def _band_radii(v: np.ndarray, band: np.ndarray, centre: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Radii (len(ang),) from `centre` (xy) at angles `ang` to where rays leave the convex hull of the points
    `v[band]` (`hull_anchors`); -inf where the band has fewer than 3 points."""
    if len(band) < 3:
        return np.full(len(ang), -np.inf)
    idx, w = hull_anchors(v, band, centre, ang)
    ring = (v[idx] * w[..., None]).sum(1)
    return np.linalg.norm(ring[:, :2] - centre[:2], axis=1)


def _cloth_radii(cloth: np.ndarray, z: float, centre: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """As `_hull_radii`, for the points of draped cloth (all of them within 1.5 cm of height z); -inf where fewer
    than 3 are."""
    return _band_radii(cloth, np.flatnonzero(np.abs(cloth[:, 2] - z) < 0.015), centre, ang)


def _under_the_arms(feats, body: np.ndarray, heads: dict, centre: np.ndarray, gap: float,
                    start: float | None = None) -> float:
    """Height of a dress's top ring: from halfway between spine02 and spine01 (the chest, under the armpits; or
    `start`) down in 1 cm steps to spine03 at most, the first height where the ring (`gap` outside the trunk's
    cross-section) keeps `gap` / 2 off the whole A-pose body (trimesh closest points, `penetration`), arms included:
    the arms are no collider, and a ring through an inner upper arm pressed to the trunk would show as cloth cutting
    the arm."""
    faces = body_topology().faces
    z = 0.5 * (float(heads["spine01"][2]) + float(heads["spine02"][2])) if start is None else float(start)
    z_low = float(heads["spine03"][2])
    ang = np.arange(36) * (2.0 * np.pi / 36)
    while z > z_low:
        r = _hull_radii(feats, body, z, centre, ang) + gap
        ring = np.c_[centre[0] + r * np.sin(ang), centre[1] - r * np.cos(ang), np.full(len(ang), z)]
        if penetration(body, faces, ring).max() < -0.5 * gap:
            return z
        z -= 0.01
    return z_low


def _ring_gap(prof: DrapeProfile, st: DrapeSettings) -> float:
    """Metres a profile's pinned ring keeps outside the trunk's hull (`DrapeProfile.ring_gap`)."""
    return prof.ring_gap or st.clearance + 0.002


# Metres over the bust's apex a loose top's pinned ring is raised to where the arms leave room (`_bust_height`).
OVER_APEX = 0.005


def _bust_apex(feats, body: np.ndarray, centre: np.ndarray, chest: float) -> float:
    """Height of the trunk's front-most point within 12 cm of the middle, from 4 cm under the chest ring `chest` to
    12 cm over it: the bust's apex (or a man's chest's, or the belly's where it stands out further)."""
    front = np.flatnonzero(feats.in_groups("torso") & (np.abs(body[:, 0] - centre[0]) < 0.12)
                           & (body[:, 2] > chest - 0.04) & (body[:, 2] < chest + 0.12))
    return float(body[front[np.argmin(body[front, 1])], 2])


def _bust_height(feats, body: np.ndarray, heads: dict, centre: np.ndarray, gap: float, chest: float) -> float:
    """A loose top's pinned ring (`DrapeProfile.top` "bust"): OVER_APEX over the bust's apex (`_bust_apex`) where
    that is over the chest ring `chest` and the ring there (or as far down towards it as the arms need,
    `_under_the_arms`) keeps off the arms; else `chest`. Hung from under the bust, the cloth left the shell over it
    following the skin under the bust and into the cleavage, and a line showed across the chest where the two met;
    hung from over it, the cloth falls over the bust as fabric does (bench/bench_bust_seam.py)."""
    apex = _bust_apex(feats, body, centre, chest)
    if apex + OVER_APEX <= chest:
        return chest
    return max(chest, _under_the_arms(feats, body, heads, centre, gap, start=apex + OVER_APEX))


# Draped kinds whose cloth hangs from under the arms and whose top is a shell (garments.py) tucked under the
# cloth's pinned ring: {draped kind: the shell's part name}. The coat's and the jacket's shoulders, yoke and sleeves
# (one shell "coat": both are pinned from the chest with the same clearance, so `shell_hem` puts its hem at the same
# height, and the front is open as wide, FRONT_OPENING); the dress's bodice (without it the dress is strapless, its
# top edge across the bust); the loose t-shirt's shoulders, sleeves and chest ("tee": the t-shirt's cut, its hem
# under the ring; its sleeves end under the draped sleeves' rings, sleeves.py); the loose long sleeve's ("longtop":
# the longsleeve's cut, its hem under the ring); the hoodie's ("hoodie", likewise; its hood is draped over it).
SHELL_KINDS_OVER = {"draped_coat": "coat", "draped_jacket": "coat", "draped_dress": "bodice", "draped_tshirt": "tee",
                    "draped_longsleeve": "longtop", "draped_hoodie_body": "hoodie"}


# Draped kinds hung over draped cloth worn under them: {draped kind: the draped kinds under it its drape collides
# with}. The loose tops' hems hang over a draped bottom's waistband and hips (_BOTTOMS_UNDER: the skirt, either
# trousers, the shorts): draped on the body alone, the top's cloth would settle through the skirt. The open jacket's
# and the coat's panels hang over a loose top (recipe.OVER_LOOSE_TOP) and over the bottom under it
# (recipe.JACKET_OVER_LOOSE_TOP, recipe.COAT_OVER_DRAPED). Their pattern is cut outside that cloth too
# (`garment_pattern`'s `over`), and `drape_garment` adds the cloth to the collider. The hoodie's body hangs over
# the bottoms as the loose tops do, and its hood falls onto that body's cloth down the upper back, below the body's
# pinned ring; the hood's pattern starts laid back above the shoulders, clear of it, so only its collider takes the
# cloth.
_BOTTOMS_UNDER = ("draped_skirt", "draped_trousers", "draped_shorts", "draped_straight_trousers")
DRAPED_OVER = {"draped_tshirt": _BOTTOMS_UNDER, "draped_longsleeve": _BOTTOMS_UNDER,
               "draped_hoodie_body": _BOTTOMS_UNDER, "draped_hoodie": ("draped_hoodie_body",),
               "draped_jacket": _BOTTOMS_UNDER + ("draped_tshirt", "draped_longsleeve"),
               "draped_coat": _BOTTOMS_UNDER + ("draped_tshirt", "draped_longsleeve")}
# The draped kinds a recipe garment is draped as, in order (each over those before it that DRAPED_OVER names); any
# other draped recipe kind is draped as itself. Its draped sleeves are draped over the arm alone (garments.py).
DRAPED_PIECES = {"draped_hoodie": ("draped_hoodie_body", "draped_hoodie")}
# Kinds a loose top or a dress is not hung over the bust under (`piece_settings`): the open jacket and the coat, whose
# panels are pinned under the arms and draped over the top's cloth; and the shell jacket, which follows the skin: a
# bridged bodice, up to 3 cm off the skin over the cleavage and the belly, would stand through it. The generator
# never draws a jacket over a dress (its draws replace top, bottom and jacket), but a recipe may name one.
BUST_UNDER_NOT = ("jacket", "draped_jacket", "draped_coat")


# Shells held under draped cloth: {draped kind: the shell parts}. Only where a draped bottom is worn
# (`_BOTTOMS_UNDER`, `shells_under`): a shell top over it is lifted over the bottom's waistband (`draped_part`'s
# `under`, then garments.py's layers) and showed through the open jacket's panels at the hips, which are draped over
# the body and the bottom (docs/ARCHITECTURE.md, "A shell top under the open jacket"). So its offset is capped under
# the panels at rest (garments.build_garments, `_under_cover`, as the coat's shell is) and, posed, it is put back under
# them where it came out (character._shell_under_panels). Over shell bottoms the top lies on the body, under the
# panels' clearance, and nothing changes. Making the top's trunk a collider of the panels' drape instead (tried
# 5 December) kept it under them too, but the panels' hem caught on the top's and folded through itself (130
# crossing edges at rest for subject 30, 21 for subject 19, against none draped without it: bench/draped_garments.py).
# The coat likewise since 5 December (afternoon): its panels hang over the loose shorts or straight trousers the
# same way (recipe.COAT_OVER_DRAPED), and a shell top would show through them at the hips.
SHELLS_UNDER = {"draped_jacket": ("tshirt", "longsleeve"), "draped_coat": ("tshirt", "longsleeve")}
# The bone groups (body_features.GROUPS) of a held shell's sleeves, by each vertex's nearer body vertex: held under
# nothing (they lie under the jacket's own shell). Not only "torso": the top's lowest band, over the hips, is on
# "upperleg" vertices, and left out it came through the panels' hem in the pictures.
SLEEVE_GROUPS = ("upperarm", "lowerarm", "hand")


# A shell top worn over a draped bottom with no draped jacket or coat over both (those hold the top under their
# panels instead: SHELLS_UNDER): the top's hem hangs over the bottom's waistband, raised over its cloth at rest
# (garments.build_garments' `under`), but posed, the bottom's skinned, pushed-out and lifted cloth came out through
# it: seed 0's subject 23 bending, 16 of its shorts' vertices over its t-shirt, 12 of them seen. Posing puts them
# back under the top (character._bottoms_under_shell_top; bench/bench_shell_top_over_bottom.py). Part names; the
# hoodie's shell ends at the chest since 6 December, over its draped body (DRAPED_OVER holds that over a bottom).
SHELL_TOPS = ("tshirt", "longsleeve")
BOTTOMS_UNDER = _BOTTOMS_UNDER


def shells_under(kind: str, worn: Sequence[str]) -> tuple[str, ...]:
    """The shell parts of `worn` (a character's part or garment kinds) held under a draped `kind`'s cloth
    (`SHELLS_UNDER`, only over a draped bottom), in `worn`'s order."""
    if kind not in SHELLS_UNDER or not any(k in _BOTTOMS_UNDER for k in worn):
        return ()
    return tuple(k for k in worn if k in SHELLS_UNDER[kind])


def shell_hem(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None) -> float:
    """Height in anny's bind space (where `BodyFeatures` and the shells' level sets live) of the hem of the shell
    over a draped kind (`SHELL_KINDS_OVER`): `SHELL_OVERLAP` under the cloth's pinned ring, so the shell's lower edge
    lies inside the cloth and no gap opens between them. The trunk's bind space is the A-pose frame the cloth is cut
    in raised by 8-9 cm (spine02's offset, the same for every spine bone to a millimetre)."""
    if kind not in SHELL_KINDS_OVER:
        raise ValueError(f"shell_hem: kind must be one of {tuple(SHELL_KINDS_OVER)}, got {kind!r}")
    feats = body_features(phenotype)
    run = run_anny(phenotype)
    spine02 = body_topology().bone_labels.index("spine02")
    z = ring_height(kind, phenotype, settings)
    return z + float(feats.bone_heads["spine02"][2] - run["bone_poses"][spine02, 2, 3]) - SHELL_OVERLAP


def shell_hems(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None) -> np.ndarray:
    """(V,) per body vertex, the bind-space height at which the shell over a draped kind (`SHELL_KINDS_OVER`) is cut
    so that its hem lies `SHELL_OVERLAP` under the cloth's pinned ring in the A-pose the cloth is draped in, all the
    way round. `shell_hem`'s one height is that only where bind space is the A-pose raised: on seed 0's subject 28
    (a heavy build) the trunk leans in bind space against the A-pose, and a shell cut there lay 2.3 cm under the ring
    at the back and 1 mm over it at the front, where a slot opened between shell and ring."""
    if kind not in SHELL_KINDS_OVER:
        raise ValueError(f"shell_hems: kind must be one of {tuple(SHELL_KINDS_OVER)}, got {kind!r}")
    feats = body_features(phenotype)
    rest = run_anny(phenotype)["vertices"]
    return feats.rest_vertices[:, 2] - rest[:, 2] + ring_height(kind, phenotype, settings) - SHELL_OVERLAP


def ring_height(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None) -> float:
    """Height of a chest-hung draped kind's pinned ring in the A-pose frame the cloth is draped in (`PROFILES`)."""
    return _rings(kind, phenotype, drape_settings(kind) if settings is None else settings)[0]


def _rings(kind: str, phenotype: dict[str, float], st: DrapeSettings) -> tuple[float, float]:
    """`_ring_levels` for a phenotype dict and settings: keyed on the kind's profile (a `PROFILES` entry changed at
    run time, as bench/bench_bust_seam.py's "before" does, finds its own rings), the phenotype made hashable and the
    only two settings the rings depend on (the ring's gap and `over_bust`), so both drape levels share one finding."""
    prof = PROFILES[kind]
    return _ring_levels(prof, tuple(sorted((k, float(v)) for k, v in phenotype.items())), _ring_gap(prof, st),
                        st.over_bust)


@functools.lru_cache(maxsize=32)
def _ring_levels(prof: DrapeProfile, phenotype: tuple[tuple[str, float], ...], gap: float,
                 over_bust: bool) -> tuple[float, float]:
    """(pinned top ring's height, the chest ring's) of a `PROFILES` kind in the A-pose frame: its top ring at the
    waist (`DrapeProfile.top`, both the same), the chest under the arms (`_under_the_arms`, `gap` off the trunk's
    hull), or ("bust", where `over_bust`) that raised to over the bust (`_bust_height`). Found once per (profile,
    phenotype, gap, over_bust): the pattern, the shell's hem (`shell_hems`) and the bridged shell's surface
    (`hanging_surface`) all need it for one build, and each finding runs closest-point queries against the body,
    twice where the ring is raised."""
    run = run_anny(dict(phenotype))
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    if prof.top == "waist":
        top = 0.5 * (float(heads["root"][2]) + float(heads["spine04"][2])) + 0.01
        return top, top
    feats, body = body_features(dict(phenotype)), run["vertices"]
    centre = np.asarray(heads["root"], np.float64)
    chest = _under_the_arms(feats, body, heads, centre, gap)
    top = _bust_height(feats, body, heads, centre, gap, chest) if prof.top == "bust" and over_bust else chest
    return top, chest


# A loose top's fabric spans the bust and the belly (`_hanging`): its cloth's pinned ring and, over it, its shell
# (garments.BRIDGED) lie where that fabric would. {draped kind: (metres above the pinned ring the shell is laid on
# that surface in full, metres more over which that fades)}. Under the arms the tops' rings sat 1.3-4.8 cm under the
# bust's (or chest's) apex on 20 of seed 0's 24 wearers, over the belly's hollow on heavy builds
# (bench/bench_bust_seam.py); the shell above them followed the skin into the cleavage and under the bust, the cloth
# under them stood out over the belly, and a dark line showed across the chest where the two met
# (docs/draped_hoodie_body.png before 6 December, morning).
# The dress likewise since 7 December: hung from under the arms, its ring 0.9-3.5 cm under the bust's apex on seed 0's
# 8 wearers, its bodice over the ring showed the same dark line across the chest in every frame.
BRIDGE_BAND = {"draped_tshirt": (0.06, 0.03), "draped_longsleeve": (0.06, 0.03), "draped_hoodie_body": (0.06, 0.03),
               "draped_dress": (0.06, 0.03)}
BRIDGE_STEP = 0.005  # metres between the heights the hanging surface is found at
BRIDGE_BELOW = 0.2  # metres under the ring the trunk's profile is spanned from (the belly)
BRIDGE_FRONT = (np.radians(60.0), np.radians(90.0))  # bridged in full this far round from the front, none past that
# Metres the bridged shell keeps under its cloth's pinned ring up to BRIDGE_CAP_OVER over it (lifted, or its tuck,
# garments.TUCK, lowered onto that): under a coarse drape's ring (36 particles round) a shell 1.8 mm under the ring's
# circle came 0.1 mm out between two particles at the bust's side (tests/test_drape_tshirt.py).
BRIDGE_SHELL_GAP = 0.003
BRIDGE_CAP_OVER = 0.005


def _hanging(feats, body: np.ndarray, centre: np.ndarray, ang: np.ndarray, z_ring: float, top: float,
             zs: np.ndarray) -> np.ndarray:
    """(len(zs), len(ang)) radii from `centre` (xy) of fabric hanging over the A-pose trunk `body` at heights `zs`,
    no thicker than the trunk: at each angle, the trunk's profile (the convex hulls of its cross-sections,
    `_hull_radii`, every BRIDGE_STEP from BRIDGE_BELOW under `z_ring` up to `top`) spanned from outside (its upper
    convex envelope: fabric stretched from the bust to the belly), and at least the most that stands out above (up
    to `top`: fabric hanging straight down from the bust)."""
    zk = np.arange(z_ring - BRIDGE_BELOW, top + 0.5 * BRIDGE_STEP, BRIDGE_STEP)
    h = np.stack([_hull_radii(feats, body, float(z), centre, ang) for z in zk])  # (K, A)
    h = np.where(np.isfinite(h), h, 0.0)
    out = np.empty((len(zs), len(ang)))
    for q, z in enumerate(zs):
        hi, lo = zk >= z, zk <= z
        if not lo.any() or not hi.any():
            out[q] = h[np.argmin(np.abs(zk - z))]
            continue
        zi, zj = zk[hi][:, None, None], zk[lo][None, :, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(zi > zj, (z - zj) / (zi - zj), 0.0)
        span = (1.0 - t) * h[lo][None] + t * h[hi][:, None]  # (I, J, A): chords from above z to below it
        out[q] = np.maximum(span.max(axis=(0, 1)), h[hi].max(0))
    return out


def _front_weight(ang: np.ndarray) -> np.ndarray:
    """(N,) 1 within BRIDGE_FRONT[0] radians of the front (angle 0), 0 past BRIDGE_FRONT[1], smooth between."""
    off_front = np.abs(np.mod(np.asarray(ang, np.float64) + np.pi, 2.0 * np.pi) - np.pi)
    lo, hi = BRIDGE_FRONT
    return 1.0 - smoothstep((off_front - lo) / (hi - lo))


def _ring_radii(kind: str, feats, body: np.ndarray, z_ring: float, centre: np.ndarray, ang: np.ndarray,
                ring_gap: float, over_bust: bool = True) -> np.ndarray:
    """(len(ang),) radii of a pinned ring at `z_ring`: `ring_gap` outside the trunk's hull, and for a loose top
    (`BRIDGE_BAND`, `over_bust`) on its front that far outside the fabric hanging there (`_hanging`)."""
    hull = _hull_radii(feats, body, z_ring, centre, ang)
    if kind not in BRIDGE_BAND or not over_bust:
        return hull + ring_gap
    full, fade = BRIDGE_BAND[kind]
    hang = _hanging(feats, body, centre, ang, z_ring, z_ring + full + fade, np.array([z_ring]))[0]
    return hull + ring_gap + _front_weight(ang) * np.maximum(hang - hull, 0.0)


@dataclasses.dataclass(frozen=True)
class HangingSurface:
    """Where a loose top's shell (garments.BRIDGED) lies over its cloth's pinned ring (`hanging_surface`), in the
    A-pose frame the cloth is draped in: `radius` (Z, A) metres from the axis (the pelvis's vertical through
    `centre` (2,)) at heights `z0` + BRIDGE_STEP * (0..Z-1) and angles 2 pi (0..A-1) / A (0 = -Y, the front, then
    towards +X); `z_ring`, and the band `full`, `fade` (BRIDGE_BAND) over it."""

    radius: np.ndarray
    z0: float
    centre: np.ndarray
    z_ring: float
    full: float
    fade: float

    def _polar(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(points, np.float64)
        return np.mod(np.arctan2(p[:, 0] - self.centre[0], -(p[:, 1] - self.centre[1])), 2.0 * np.pi), p[:, 2]

    def radius_at(self, points: np.ndarray) -> np.ndarray:
        """(N,) the surface's radius at the angle and height of each point (N, 3), bilinear, clamped to the band."""
        a, z = self._polar(points)
        nz, na = self.radius.shape
        fa = a / (2.0 * np.pi / na)
        i0 = np.floor(fa).astype(np.int64) % na
        i1, wa = (i0 + 1) % na, fa - np.floor(fa)
        fz = np.clip((z - self.z0) / BRIDGE_STEP, 0.0, nz - 1.0)
        j0 = np.minimum(np.floor(fz).astype(np.int64), nz - 2)
        wz = fz - j0
        r = self.radius
        return ((1 - wz) * ((1 - wa) * r[j0, i0] + wa * r[j0, i1])
                + wz * ((1 - wa) * r[j0 + 1, i0] + wa * r[j0 + 1, i1]))

    def front_weight_at(self, points: np.ndarray) -> np.ndarray:
        """(N,) 1 within BRIDGE_FRONT[0] of the front, 0 past BRIDGE_FRONT[1], smooth between."""
        return _front_weight(self._polar(points)[0])

    def weight_at(self, points: np.ndarray) -> np.ndarray:
        """(N,) how much of the way onto the surface a shell point there is laid (0..1): in full within BRIDGE_FRONT[0]
        of the front, from the shell's hem (SHELL_OVERLAP under the ring) up to `full` over the ring; none past
        BRIDGE_FRONT[1], BRIDGE_UNDER under the hem, or `full` + `fade` over the ring; smooth between."""
        a, z = self._polar(points)
        return (_front_weight(a) * smoothstep((z - self.z_ring + SHELL_OVERLAP + BRIDGE_UNDER) / BRIDGE_UNDER)
                * (1.0 - smoothstep((z - self.z_ring - self.full) / self.fade)))


# Metres under the shell's hem (SHELL_OVERLAP under the pinned ring) over which its lift onto the hanging surface
# fades out. Faded out over 5 mm under the ring, the shell's triangles (~2 cm) reached from a vertex in the
# cleavage under the ring to one lifted over it, and at the middle of the chest the ring stood 13-14 mm over them
# (seed 0's subject 28, bench/bench_bust_seam.py); under the ring the surface lies BRIDGE_SHELL_GAP under the ring.
BRIDGE_UNDER = 0.005


def hanging_surface(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None) -> HangingSurface:
    """The surface a loose top's shell (garments.BRIDGED) is laid on in the band over its cloth's pinned ring
    (`BRIDGE_BAND`): the fabric hanging over the trunk (`_hanging`), `ring_gap` less BRIDGE_SHELL_GAP out from it, so
    that it meets the ring (`_ring_radii`) BRIDGE_SHELL_GAP under it; up to BRIDGE_CAP_OVER over the ring at most
    that far under the ring, so the shell's hem stays inside the cloth."""
    if kind not in BRIDGE_BAND:
        raise ValueError(f"hanging_surface: kind must be one of {tuple(BRIDGE_BAND)}, got {kind!r}")
    st = drape_settings(kind) if settings is None else settings
    if not st.over_bust:
        raise ValueError(f"hanging_surface: {kind} is hung from under the arms here (DrapeSettings.over_bust False)")
    prof = PROFILES[kind]
    feats = body_features(phenotype)
    run = run_anny(phenotype)
    body = run["vertices"]
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    centre = np.asarray(heads["root"], np.float64)
    ring_gap = _ring_gap(prof, st)
    z_ring = ring_height(kind, phenotype, st)
    full, fade = BRIDGE_BAND[kind]
    top = z_ring + full + fade
    zs = z_ring + np.arange(-int(np.ceil((SHELL_OVERLAP + 0.015) / BRIDGE_STEP)),
                            int(np.ceil((full + fade) / BRIDGE_STEP)) + 1) * BRIDGE_STEP
    ang = np.arange(180) * (2.0 * np.pi / 180)
    hang = _hanging(feats, body, centre, ang, z_ring, top, zs) + ring_gap - BRIDGE_SHELL_GAP
    ring = _ring_radii(kind, feats, body, z_ring, centre, ang, ring_gap) - BRIDGE_SHELL_GAP
    hang = np.where((zs <= z_ring + BRIDGE_CAP_OVER)[:, None], np.minimum(hang, ring[None, :]), hang)
    return HangingSurface(hang, float(zs[0]), centre[:2].copy(), float(z_ring), full, fade)


def garment_pattern(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None,
                    over: np.ndarray | None = None):
    """The undraped cloth of a draped kind (`PROFILES`): a closed tube of `n_rings` rings of `n_around` particles,
    its top ring on the body (pinned), hanging straight down to the profile's `flare_from` and then a cone at
    `settings.flare` to just above the knee; each ring pushed out where the body's cross-section reaches it. Returns
    (vertices (V, 3), faces (F, 3) int32 outward, uvs (V, 2), pinned (V,) bool, metres_per_uv). A seam column is
    not duplicated: the cloth is one closed tube (u wraps; UVs are per vertex, so the last column's faces reuse u of
    the first, which the texture's period hides). `over` (P, 3): the rest-pose vertices of draped cloth the garment
    hangs over (`DRAPED_OVER`); the rings are also kept outside their cross-section's hull, so that no particle starts
    under that cloth."""
    st = drape_settings(kind) if settings is None else settings
    if over is not None and (kind in SLEEVE_CUTS or (kind in PROFILES and PROFILES[kind].legs)):
        raise ValueError(f"drape: {kind} is not draped over other cloth (DRAPED_OVER)")
    if kind == "draped_hoodie":  # laid back above the shoulders: clear of the body's cloth it then falls onto
        return _hood_pattern(phenotype, st)
    if kind in SLEEVE_CUTS:
        return sleeve_pattern(phenotype, st.n_around, st.n_rings, SLEEVE_CUTS[kind])[:5]
    prof = PROFILES[kind]
    if prof.legs:
        return _trouser_pattern(phenotype, st, prof)[:5]
    feats = body_features(phenotype)
    # Everything in the frame the cloth is simulated in: the A-pose body (the collider), whose pelvis anny puts at
    # the origin, 8-9 cm below where it is in the bind space `BodyFeatures` and its bone heads live (the skirt's
    # pattern was placed in bind space before the dress came: its waistband sat that much above the waist).
    run = run_anny(phenotype)
    body = run["vertices"]
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    na, nr = int(st.n_around), int(st.n_rings)
    gap, ring_gap = st.clearance + 0.002, _ring_gap(prof, st)
    centre = np.asarray(heads["root"], dtype=np.float64)
    # A ring raised over the bust ("bust") keeps the chest ring's hem: the cloth it adds hangs over the bust.
    z_top, z_cut = _rings(kind, phenotype, st)
    z_flare = z_top if prof.flare_from == "top" else \
        0.5 * (float(heads["upperleg01.L"][2]) + float(heads["upperleg01.R"][2]))
    z_knee = 0.5 * (float(heads["lowerleg01.L"][2]) + float(heads["lowerleg01.R"][2]))
    straight = z_top - z_flare  # path length of the part hanging straight down
    length = straight + prof.hem * (z_flare - z_knee) + (1.0 - prof.hem) * (z_top - z_cut)  # the slant length
    ang = np.arange(na) * (2.0 * np.pi / na)
    if prof.opening:  # open at the front: na columns from one front edge round the back to the other
        half = 0.5 * prof.opening / float(_hull_radii(feats, body, z_top, centre, np.zeros(1))[0] + gap)
        ang = half + np.arange(na) * ((2.0 * np.pi - 2.0 * half) / (na - 1))
    ts = np.linspace(0.0, 1.0, nr)
    s = ts * length
    cone = np.maximum(s - straight, 0.0)  # path length along the flared part
    zs = np.where(s <= straight, z_top - s, z_flare - cone * np.cos(st.flare))
    flare_out = cone * np.sin(st.flare)
    # r_i = flare_out_i + m_i, m_i the running maximum of (body + gap - flare_out): the cone as drawn where the
    # body stays inside it, pushed out (and kept out further down) where the body reaches it.
    m = _ring_radii(kind, feats, body, float(zs[0]), centre, ang, ring_gap, st.over_bust)
    rr = np.empty((nr, na))
    for i in range(nr):
        if i:
            m = np.maximum(m, _hull_radii(feats, body, float(zs[i]), centre, ang) + gap - flare_out[i])
            if over is not None:
                m = np.maximum(m, _cloth_radii(over, float(zs[i]), centre, ang) + gap - flare_out[i])
        rr[i] = flare_out[i] + m
    x = centre[0] + rr * np.sin(ang)[None, :]
    y = centre[1] - rr * np.cos(ang)[None, :]
    zz = np.broadcast_to(zs[:, None], rr.shape)
    verts = np.stack([x, y, zz], -1).reshape(-1, 3)
    faces = _grid_faces(np.arange(nr * na).reshape(nr, na), wrap=not prof.opening)
    circ = float(2.0 * np.pi * rr[-1].mean())
    uvs = np.stack(np.broadcast_arrays((ang[None, :] - ang[0]) / (2.0 * np.pi), (1.0 - ts[:, None]) * length / circ),
                   -1)
    pinned = np.zeros(len(verts), dtype=bool)
    pinned[:na] = True
    return verts, faces.astype(np.int32), np.clip(uvs.reshape(-1, 2), 0, 1).astype(np.float32), pinned, circ


def _hood_pattern(phenotype: dict[str, float], st: DrapeSettings, cut: HoodCut = HOOD):
    """The undraped hood (`HoodCut`), in the A-pose frame `garment_pattern` uses: an open sheet of `st.n_rings` rows
    of `st.n_around` particles, row 0 the pinned neckline ring. Returns garment_pattern's five values; UVs are metres
    along the rows (from the middle column) and up the columns (from the neckline) of the hood-up shape, over one
    scale (`metres_per_uv`: the longest row or column)."""
    na, nr = int(st.n_around), int(st.n_rings)
    if na < 4 or nr < 4:
        raise ValueError(f"drape: draped_hoodie needs n_around >= 4 and n_rings >= 4 in DrapeSettings, got {na} x {nr}")
    run = run_anny(phenotype)
    body = run["vertices"]
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    feats = body_features(phenotype)
    gap = st.clearance + 0.002
    t = np.linspace(0.0, 1.0, nr)[:, None]
    front = cut.front - cut.widen * smoothstep((t - 0.1) / 0.35)  # (nr, 1): each row's ends, off the front
    ang = front + np.arange(na)[None, :] / (na - 1) * (2.0 * np.pi - 2.0 * front)  # (nr, na), 0 = -Y towards +X
    # The ring: on the longsleeve's neckline lowered by `drop` (its level set, cut along the body's edges and placed
    # on the A-pose body), where rays from the neck's centre leave its convex hull seen from above, then `gap` out
    # along the skin's normal there.
    from .garments import garment_level

    level = garment_level("longsleeve", feats) + cut.drop
    faces_all = body_topology().faces
    e = _edges(faces_all)
    e = e[(level[e[:, 0]] < 0) != (level[e[:, 1]] < 0)]
    k = (level[e[:, 0]] / (level[e[:, 0]] - level[e[:, 1]]))[:, None]
    neck = (1.0 - k) * body[e[:, 0]] + k * body[e[:, 1]]
    neck = neck[neck[:, 2] > float(heads["neck01"][2]) - 0.08]  # not the hem or the cuffs
    if len(neck) < 3:
        raise ValueError("drape: no neckline under the hood's ring; is the phenotype's body complete?")
    centre = np.array([heads["neck01"][0], heads["neck01"][1], neck[:, 2].mean()], np.float64)
    idx, w = hull_anchors(neck, np.arange(len(neck)), centre, ang[0])
    on_skin = (neck[idx] * w[..., None]).sum(1)
    _, closest, normal = closest_on_surface(body, faces_all, on_skin)
    ring = closest + gap * normal
    ring_r = np.linalg.norm(ring[:, :2] - centre[:2], axis=1)
    head_r = 1.0 / np.sqrt((np.sin(ang) / cut.width) ** 2 + (np.cos(ang) / cut.depth) ** 2)
    swell = smoothstep(t / 0.4)
    crown = np.where(t > 0.4, np.sqrt(np.clip(1.0 - ((t - 0.4) / 0.62) ** 2, 0.0, 1.0)), 1.0)
    rho = ((1.0 - swell) * ring_r[None, :] + swell * head_r) * crown
    # Hood up, about the neckline ring's centre: (across, back, up); row 0 the ring itself.
    x, y = rho * np.sin(ang), -rho * np.cos(ang)
    z = (ring[:, 2] - centre[2])[None, :] + cut.height * t
    x[0], y[0] = ring[:, 0] - centre[0], ring[:, 1] - centre[1]
    # Laid back about the line across the back of the ring (y = y_back, z = 0), row by row.
    y_back = float(y[0].max())
    g = cut.tilt * smoothstep(t / 0.35)
    yb = (y - y_back) * np.cos(g) + z * np.sin(g) + y_back
    zb = -(y - y_back) * np.sin(g) + z * np.cos(g)
    up = np.stack([x, y, z], -1)  # the hood-up shape: its UVs
    verts = (np.stack([x, yb, zb], -1) + centre).reshape(-1, 3)
    # Anything the laid-back shape brings within the gap of the body (the hood's collider: forearms and hands left
    # out) is put `gap` off it, so the simulation starts clear.
    cf = collider_faces(phenotype, "draped_hoodie")
    depth, closest, n = closest_on_surface(body, cf, verts)
    near = depth > -gap
    near[:na] = False
    verts[near] = closest[near] + gap * n[near]
    # `_grid_faces` faces outwards for rows going down; the hood's rows go up (hood up), so its faces are flipped.
    faces = _grid_faces(np.arange(nr * na).reshape(nr, na), wrap=False)[:, ::-1]
    along = np.concatenate([np.zeros((nr, 1)), np.cumsum(np.linalg.norm(np.diff(up, axis=1), axis=-1), 1)], 1)
    along -= along[:, na // 2 - 1:na // 2 + 1].mean(1, keepdims=True)
    height = np.concatenate([np.zeros((1, na)), np.cumsum(np.linalg.norm(np.diff(up, axis=0), axis=-1), 0)], 0)
    mpu = float(max(np.ptp(along, axis=1).max(), height.max()))
    uvs = np.stack([0.5 + along / mpu, height / mpu], -1).reshape(-1, 2)
    pinned = np.zeros(len(verts), dtype=bool)
    pinned[:na] = True
    return verts, faces.astype(np.int32), np.clip(uvs, 0.0, 1.0).astype(np.float32), pinned, mpu


def _crotch_height(mesh, centre: np.ndarray, z_from: float) -> float:
    """The lowest point of the body's underside on the midplane (x = centre's x): rays cast down from `z_from`
    at depths across the pelvis (trimesh), the lowest hit. The thighs stand apart under it in the A-pose (at
    least 1.5 cm each side of the midplane for every build measured), so the midplane below it is free."""
    ys = centre[1] + np.linspace(-0.12, 0.12, 25)
    origins = np.c_[np.full(len(ys), centre[0]), ys, np.full(len(ys), z_from)]
    loc, _, _ = mesh.ray.intersects_location(
        origins, np.tile([0.0, 0.0, -1.0], (len(ys), 1)), multiple_hits=True)
    if len(loc) == 0:
        raise ValueError("drape: no body under the waist on the midplane; is the phenotype's body complete?")
    return float(np.asarray(loc)[:, 2].min())


def _section(mesh, z: float, side: float = 0.0) -> np.ndarray:
    """Points (P, 3) of the cross-sections of the collider mesh (trimesh) at heights z and z +- 1 cm, on one side
    of the midplane (side +1: +X, anny's left leg; -1: the right; 0: both): the body's mesh rings are 2-3 cm
    apart along the shin, so a band of vertices (`_hull_radii`) can miss a ring or be empty where a slice never
    is."""
    import trimesh

    segs = [trimesh.intersections.mesh_plane(mesh, [0.0, 0.0, 1.0], [0.0, 0.0, z + dz]) for dz in (-0.01, 0.0, 0.01)]
    pts = np.concatenate([np.asarray(q).reshape(-1, 3) for q in segs])
    if side:
        pts = pts[side * pts[:, 0] > 0]
    if len(pts) < 3:
        raise ValueError(f"drape: no body at height {z:.3f} m under the trousers; is the phenotype's body complete?")
    return pts


def _grid_faces(grid: np.ndarray, wrap: bool = True) -> np.ndarray:
    """Faces (F, 3) of a tube given as a grid (rings, around) of vertex indices, the columns wrapping around (or,
    `wrap` False, an open sheet: no faces between the last column and the first): with angles growing from -Y
    towards +X and rings going down, (a, c, b) faces outwards."""
    a, c = grid[:-1], grid[1:]
    b, d = np.roll(a, -1, axis=1), np.roll(c, -1, axis=1)
    if not wrap:
        a, b, c, d = a[:, :-1], b[:, :-1], c[:, :-1], d[:, :-1]
    return np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])


MIDPLANE_GAP = 0.01  # metres each leg tube's inner wall keeps off the midplane (and so off the other leg)


def _trouser_pattern(phenotype: dict[str, float], st: DrapeSettings, prof: DrapeProfile):
    """Undraped wide-leg trousers (`DrapeProfile.legs`), in the A-pose frame `garment_pattern` uses. Topology: a
    waist tube (`st.n_around` particles around, even) from the pinned waistband down to the split ring just under
    the crotch; a crotch seam of k particles on the midplane from the split ring's back point to its front point
    (spaced as the ring is); two leg tubes, each starting from a D-shaped ring (half the split ring plus the seam,
    which both legs share) and turning, over the first 10 cm, into a circle around the leg that flares at
    `st.flare` to the hem (centred on the middle of the leg's cross-section, moved out where the circle would come
    closer than `MIDPLANE_GAP` to the midplane). Every ring is kept `clearance` + 2 mm outside the convex hull of the
    body's cross-section at its height (the waist tube: the whole collider, kept out further down as the skirt; a leg
    ring: that leg's side; `_section`). Rings are spaced evenly in height, `st.n_rings` from waistband to hem.
    Returns garment_pattern's five values plus the pieces: (rings, around) grids of vertex indices (waist, left
    leg, right leg) whose columns wrap; the legs' first rows are split-ring and seam vertices."""
    import trimesh

    run = run_anny(phenotype)
    body = run["vertices"]
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    na = int(st.n_around)
    if na % 2 or na < 8 or int(st.n_rings) < 6:
        raise ValueError(f"drape: draped trousers and shorts need an even n_around >= 8 and n_rings >= 6 in "
                         f"DrapeSettings, got {na} x {st.n_rings}")
    gap = st.clearance + 0.002
    centre = np.asarray(heads["root"], dtype=np.float64)
    z_top = 0.5 * (float(heads["root"][2]) + float(heads["spine04"][2])) + 0.01
    mesh = trimesh.Trimesh(body, collider_faces(phenotype), process=False)
    z_split = _crotch_height(mesh, centre, z_top) - gap
    floor = float(body[:, 2].min())
    if prof.leg_hem > 0:  # the shorts: along the leg, as the shell shorts' cut
        hip = 0.5 * (float(heads["upperleg01.L"][2]) + float(heads["upperleg01.R"][2]))
        ankle = 0.5 * (float(heads["foot.L"][2]) + float(heads["foot.R"][2]))
        z_hem = min(hip - prof.leg_hem * (hip - ankle), z_split - SHORTS_MIN_LEG)
    else:
        z_hem = floor + prof.hem
    if z_hem > z_split - 0.02 or z_hem < floor + 0.02:
        what = "shorts" if prof.leg_hem > 0 else "trousers"
        raise ValueError(f"drape: this body has no room for draped {what}' legs (crotch {z_split:.3f} m, hem "
                         f"{z_hem:.3f} m, floor {floor:.3f} m over the root's origin; anny age "
                         f"{phenotype.get('age')}): dress it in shell trousers or shorts instead")
    h = (z_top - z_hem) / (int(st.n_rings) - 1)
    n_w = min(max(2, int(round((z_top - z_split) / h)) + 1), int(st.n_rings) - LEG_RINGS_MIN)
    n_l = int(st.n_rings) - n_w + 1
    # The waist tube: straight down, each ring pushed out where the hips reach it and kept out below (as the skirt).
    ang = np.arange(na) * (2.0 * np.pi / na)
    zw = np.linspace(z_top, z_split, n_w)
    m = np.zeros(na)
    rw = np.empty((n_w, na))
    for i in range(n_w):
        sec = _section(mesh, float(zw[i]))
        idx, wt = hull_anchors(sec, np.arange(len(sec)), centre, ang)
        m = np.maximum(m, np.linalg.norm((sec[idx, :2] * wt[..., None]).sum(1) - centre[:2], axis=1) + gap)
        rw[i] = m
    waist = np.stack([centre[0] + rw * np.sin(ang), centre[1] - rw * np.cos(ang),
                      np.broadcast_to(zw[:, None], rw.shape)], -1).reshape(-1, 3)
    split = waist[-na:]
    front, back = split[0], split[na // 2]
    spacing = 2.0 * np.pi * float(rw[-1].mean()) / na
    k = max(2, int(round(abs(back[1] - front[1]) / spacing)) - 1)
    t = np.linspace(0.0, 1.0, k + 2)[1:-1]
    seam = np.c_[np.full(k, centre[0]), back[1] + t * (front[1] - back[1]), np.full(k, z_split)]  # back to front
    s0 = n_w * na  # index of the first seam vertex
    seam_bf = s0 + np.arange(k)
    ring_w = (n_w - 1) * na + np.arange(na)
    half_width = 0.5 * (float(np.abs(split[:, 0] - centre[0]).max()))
    r_top = prof.legs * half_width
    zl = np.linspace(z_split, z_hem, n_l)
    verts = [waist, seam]
    pieces = [np.arange(n_w * na).reshape(n_w, na)]
    nxt = s0 + k
    for side in (1.0, -1.0):
        if side > 0:  # front, round the +X side to the back, then the seam forwards: angles grow about the leg
            ring0 = np.concatenate([ring_w[:na // 2 + 1], seam_bf])
        else:  # front, the seam backwards, the back, round the -X side to the front
            ring0 = np.concatenate([ring_w[:1], seam_bf[::-1], ring_w[na // 2:]])
        nl = len(ring0)
        p0 = np.concatenate(verts)[ring0]
        c0 = _section(mesh, z_split - 0.01, side)[:, :2].mean(0)
        d0 = p0[:, :2] - c0
        phi = np.unwrap(np.arctan2(d0[:, 0], -d0[:, 1]))  # from -Y towards +X, increasing along the ring
        if phi[-1] < phi[0]:
            raise RuntimeError("drape: the trousers' first leg ring does not run round its leg; report this body")
        rho = np.linalg.norm(d0, axis=1)
        even = np.arange(nl) * (2.0 * np.pi / nl)
        psi = even + float(np.mean(phi - even))
        rings = [p0]
        for i in range(1, n_l):
            z = float(zl[i])
            r_leg = r_top + (z_split - z) * np.tan(st.flare)
            sec = _section(mesh, z, side)
            c = sec[:, :2].mean(0)  # inside the section's hull
            # The leg's circle, moved out from the leg's middle as far as keeps it off the midplane; radii from
            # the middle (inside the circle) to it, at the ring's angles.
            off = np.array([side * max(side * c[0], r_leg + MIDPLANE_GAP) - c[0], 0.0])
            w = float(smoothstep((z_split - z) / 0.1))
            a = (1.0 - w) * phi + w * psi
            dirs = np.c_[np.sin(a), -np.cos(a)]
            proj = dirs @ off
            circle = proj + np.sqrt(np.maximum(proj ** 2 - off @ off + r_leg ** 2, 0.0))
            idx, wt = hull_anchors(sec, np.arange(len(sec)), c, a)
            hull = np.linalg.norm((sec[idx, :2] * wt[..., None]).sum(1) - c, axis=1)
            r = np.maximum((1.0 - w) * rho + w * circle, hull + gap)
            xy = c + r[:, None] * dirs
            # The inner wall leaves the midplane at once (the seam is shared; a particle of each leg at one place
            # would start in contact with itself).
            xy[:, 0] = side * np.maximum(side * xy[:, 0], MIDPLANE_GAP * min(1.0, i / 2.0))
            rings.append(np.c_[xy, np.full(nl, z)])
        grid = np.empty((n_l, nl), dtype=np.int64)
        grid[0] = ring0
        grid[1:] = nxt + np.arange((n_l - 1) * nl).reshape(n_l - 1, nl)
        nxt += (n_l - 1) * nl
        verts.append(np.concatenate(rings[1:]))
        pieces.append(grid)
    verts = np.concatenate(verts)
    faces = np.concatenate([_grid_faces(g) for g in pieces]).astype(np.int32)
    # UVs of the particles: metres along the ring and up from the hem, over one scale that fits the longest ring and
    # the whole length; each piece's columns from u = 0. The render mesh has its own (`_pieces_render_mesh`: the wrap
    # column duplicated, u continuous across the split ring), which is what the texture is drawn on.
    circ = [float(np.linalg.norm(verts[g[-1]] - verts[np.roll(g[-1], -1)], axis=1).sum()) for g in pieces]
    mpu = max(max(circ), z_top - z_hem)
    uvs = np.zeros((len(verts), 2))
    for g, cc in zip(pieces[::-1], circ[::-1]):  # the waist piece last: the split ring takes its UVs
        uvs[g] = np.stack(np.broadcast_arrays(np.arange(g.shape[1])[None, :] / g.shape[1] * cc / mpu,
                                              (verts[g][..., 2] - z_hem) / mpu), -1)
    pinned = np.zeros(len(verts), dtype=bool)
    pinned[:na] = True
    return verts, faces, np.clip(uvs, 0, 1).astype(np.float32), pinned, mpu, pieces


def cloth_model(cloths, body_v, body_f, st: DrapeSettings, fabrics=None):
    """newton's model of cloth around the body: each of `cloths` ((vertices (V, 3), faces (F, 3), pinned (V,) bool),
    inner first) as cloth particles whose rest shape (and start) is `vertices`, its pinned particles kinematic (not
    ACTIVE: the caller places them), the body (body_v, body_f) as one triangle-mesh shape. Each cloth's material
    (density, membrane and bending stiffness, particle radius) is `fabrics[i]` (a DrapeSettings per cloth; None: `st`
    for every cloth); the soft contact's stiffness, damping and friction, which newton keeps one of for all particles,
    are `st`'s. Returns (model, the body's `newton.Mesh`, whose Warp mesh a caller may move between steps). The drape
    and the per-frame simulation (cloth_pose.py) build the same cloth this way."""
    import warp as wp

    import newton

    fabrics = [st] * len(cloths) if fabrics is None else list(fabrics)
    if len(fabrics) != len(cloths):
        raise ValueError(f"drape: cloth_model needs one fabric per cloth, got {len(fabrics)} for {len(cloths)}")
    builder = newton.ModelBuilder(up_axis=newton.Axis.Z, gravity=(0.0, 0.0, -9.81))
    for (verts, faces, _), fab in zip(cloths, fabrics):
        builder.add_cloth_mesh(
            pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
            vertices=[wp.vec3(*p) for p in np.asarray(verts, np.float64)], indices=np.asarray(faces).ravel().tolist(),
            density=fab.density, tri_ke=fab.tri_ke, tri_ka=fab.tri_ka, tri_kd=fab.tri_kd, edge_ke=fab.edge_ke,
            edge_kd=fab.edge_kd, particle_radius=fab.clearance)
    cfg = newton.ModelBuilder.ShapeConfig(mu=st.friction)
    body = newton.Mesh(np.asarray(body_v).astype(np.float32), np.asarray(body_f).ravel().astype(np.int32))
    builder.add_shape_mesh(body=-1, mesh=body, cfg=cfg)
    builder.color(include_bending=True)
    model = builder.finalize(device="cpu")
    pinned = np.concatenate([np.asarray(p, bool) for _, _, p in cloths])
    flags = model.particle_flags.numpy()
    flags[pinned] = flags[pinned] & ~int(newton.ParticleFlags.ACTIVE)
    model.particle_flags = wp.array(flags, device="cpu")
    model.soft_contact_ke, model.soft_contact_kd, model.soft_contact_mu = st.contact_ke, st.contact_kd, st.friction
    return model, body


def cloth_solver(model, st: DrapeSettings, iterations: int | None = None):
    """newton's VBD solver for a `cloth_model`, with `st`'s self-contact (`iterations`: VBD sweeps per step, default
    `st.iterations`)."""
    import newton

    extra = (dict(particle_enable_self_contact=True, particle_self_contact_margin=st.self_contact_margin,
                  particle_self_contact_gap=st.self_contact_gap) if st.self_contact else {})
    return newton.solvers.SolverVBD(model, iterations=st.iterations if iterations is None else iterations, **extra)


def _simulate(verts, faces, pinned, body_v, body_f, st: DrapeSettings) -> np.ndarray:
    """newton: the garment as cloth particles, the body as a static triangle mesh, gravity -Z; the settled
    particle positions (V, 3) float64."""
    import newton

    model, _ = cloth_model([(verts, faces, pinned)], body_v, body_f, st)
    solver = cloth_solver(model, st)
    pipe = newton.CollisionPipeline(model, soft_contact_gap=st.contact_gap, deterministic=True)
    contacts = pipe.contacts()
    s0, s1, ctrl = model.state(), model.state(), model.control()
    for k in range(int(st.steps) + int(st.settle)):
        if k % int(st.collide_every) == 0:
            pipe.collide(s0, contacts)
        if k >= st.steps:  # the settle: the swing left after `steps` damped out
            if st.settle_keep:
                s0.particle_qd.assign(s0.particle_qd.numpy() * np.float32(st.settle_keep))
            else:
                s0.particle_qd.zero_()
        s0.clear_forces()
        solver.step(s0, s1, ctrl, contacts, st.dt)
        s0, s1 = s1, s0
    q = s0.particle_q.numpy().astype(np.float64)
    if not np.all(np.isfinite(q)):
        raise RuntimeError("drape: newton's VBD solver diverged (non-finite particle positions); lower dt or "
                           "raise iterations in DrapeSettings")
    return q


def collider_faces(phenotype: dict[str, float], kind: str | None = None) -> np.ndarray:
    """Body faces the cloth collides with and takes its skinning from: all but the arms and hands, which hang beside
    the hips in the A-pose; cloth bound to a hand would fly up with every reach. `kind` "draped_hoodie": the drape's
    collider keeps the upper arms, on whose deltoids the hood's sides come to rest on a broad body (its skinning
    still comes from the collider without them); the sleeves (`SLEEVE_CUTS`): all but the hands (the sleeves hang
    round the arms)."""
    feats = body_features(phenotype)
    if kind in SLEEVE_CUTS:
        arm = feats.in_groups("hand")
    elif kind == "draped_hoodie":
        arm = feats.in_groups("lowerarm", "hand")
    else:
        arm = feats.in_groups("upperarm", "lowerarm", "hand")
    faces = body_topology().faces
    return faces[~arm[faces].any(axis=1)]


def binding_faces(phenotype: dict[str, float], kind: str) -> np.ndarray:
    """Body faces a draped kind takes its skinning weights from (`bind_loose`): `collider_faces` without the arms,
    but for the sleeves, the arms' own (upper arm, forearm): a sleeve bound to the closest point of the whole body
    would take the chest's weights where it hangs by the armpit and stay behind when the arm is raised."""
    if kind not in SLEEVE_CUTS:
        return collider_faces(phenotype)
    arm = body_features(phenotype).in_groups("upperarm", "lowerarm")
    faces = body_topology().faces
    return faces[arm[faces].all(axis=1)]


def push_clearance(kind: str) -> float:
    """How far `push_out` keeps a draped kind's skinned cloth off the posed skin (`PUSH_CLEARANCES`, else
    `PUSH_CLEARANCE`)."""
    return PUSH_CLEARANCES.get(kind, PUSH_CLEARANCE)


def push_out(points: np.ndarray, body_vertices: np.ndarray, body_normals: np.ndarray, body_faces: np.ndarray,
             clearance: float = PUSH_CLEARANCE, rounds: int = 2) -> np.ndarray:
    """The skinned path's collision fix: points closer than `clearance` to the posed skin, or under it, moved to
    their closest skin point plus `clearance` along the interpolated normal there (a second round catches a point
    moved out of one thigh into the other). Linear-blend skinning cannot make a hanging skirt give way to a thigh
    that swings into it; this puts the cloth back on the skin instead, which removes the penetration but not the
    stretch. Exact closest points for every point: a tangent-plane pre-test missed a few deep ones. A `clearance`
    above PUSH_CLEARANCE (the coat's) ends with the same rounds at PUSH_CLEARANCE: where two limbs pinch the cloth
    closer than twice the clearance (an arm hanging against the trunk), a point pushed out of one lands inside the
    other's clearance and the rounds leave it inside the body; the narrower pass puts it back on the skin.

    Only the skin within PUSH_REACH of the points' box is searched, with one search tree for every round: building
    trimesh's tree over the whole body was most of a frame's posing (bench/bench_drape_cost.py --posing-only). The
    result is the whole body's closest points (a point whose closest skin lies farther than PUSH_REACH is outside,
    since no point of the body lies that deep, and clear), to the bit but where a point is equally close to two
    faces, which the smaller search may visit in another order (1e-18 m apart, seen once in 300 test points).
    Tried and not kept (2 December): moving a point under the skin out along its cloth's outward normal instead, so
    a thigh lifted into a skirt carries the panel over it rather than the closest skin (its underside) taking the
    panel behind it: it put 3-5x fewer vertices behind a limb (bench_skirt_stride.py's `inward`), but neighbours
    that took different ways made spikes of cloth on the shins."""
    p = np.array(points, dtype=np.float64)
    if not len(p):
        return p
    v = np.asarray(body_vertices, np.float64)
    f = np.asarray(body_faces)
    local = f[faces_in_box(v, f, p.min(axis=0) - PUSH_REACH, p.max(axis=0) + PUSH_REACH)]
    if not len(local):
        return p
    mesh = query_mesh(v, local)
    todo = np.arange(len(p))
    moved = np.zeros(len(p), bool)
    pushed = np.zeros_like(p)  # the sum of the normals each point was pushed along
    for r in range(rounds + 1):
        depth, closest, n = closest_on_surface(v, local, p[todo], body_normals, mesh=mesh)
        bad = (depth > -clearance + 1e-6) & (np.abs(depth) < PUSH_REACH)
        todo = todo[bad]
        if not len(todo) or r == rounds:
            break
        p[todo] = closest[bad] + clearance * n[bad]
        pushed[todo] += n[bad]
        moved[todo] = True
    stuck = depth[bad] > -0.5 * clearance  # in or on the skin after every round (a crease): walked out
    if stuck.any():
        todo = todo[stuck]
        p[todo] = _walk_out(p[todo], depth[bad][stuck], pushed[todo], v, local, body_normals, mesh, clearance)
    if clearance > PUSH_CLEARANCE and moved.any():  # points never moved are `clearance` off: nothing to redo
        idx = np.flatnonzero(moved)
        p[idx] = push_out(p[idx], body_vertices, body_normals, body_faces, PUSH_CLEARANCE, rounds)
    return p


WALK_STEPS = 16  # steps of half the clearance `_walk_out` takes at most (8 clearances beyond where the rounds left it)
# The ways `_walk_out` tries besides the bisector: the 26 directions to a cube's faces, edges and corners.
_WALK_WAYS = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if x or y or z], float)
_WALK_WAYS /= np.linalg.norm(_WALK_WAYS, axis=1, keepdims=True)


def _walk_out(p: np.ndarray, depth: np.ndarray, pushed: np.ndarray, v: np.ndarray, faces: np.ndarray, normals,
              mesh, clearance: float) -> np.ndarray:
    """`push_out`'s points still under the skin, or within half the clearance of it, after its rounds (`depth`:
    their depth there, push_out's last query): each walked out, half a clearance a step, along the sum of the
    normals it was pushed along (`pushed`) and along 26 fixed directions, to the first step at which a way is
    `clearance` off the skin, taking the clear way nearest that sum. These are points in a crease, where two skin
    surfaces meet at an angle (a thigh lifted against the belly, an arm against the chest): stepping `clearance`
    off one surface lands inside the other, and alternating between the two approaches the crease's bisector by a
    fraction of a millimetre a round (3 December: 0.9-2.6 mm deep after the rounds in 5 of 24 posed frames,
    bench/bench_cloth_pose.py), whereas the sum of the two normals is that bisector. Where the two skins face each
    other (a slot, the normals cancel) the bisector says little, and a fixed direction finds the slot's way out. A
    point with no clear way within WALK_STEPS keeps the position farthest from the skin it reached."""
    bisector = pushed / np.maximum(np.linalg.norm(pushed, axis=1, keepdims=True), 1e-12)
    ways = np.concatenate([bisector[:, None], np.broadcast_to(_WALK_WAYS, (len(p),) + _WALK_WAYS.shape)], axis=1)
    best = p.copy()
    best_depth = np.array(depth, np.float64)  # push_out's last query, at these positions
    todo = np.arange(len(p))
    for k in range(1, WALK_STEPS + 1):
        w = ways[todo]
        q = p[todo, None] + (0.5 * clearance * k) * w  # (T, 27, 3)
        depth = closest_on_surface(v, faces, q.reshape(-1, 3), normals, mesh=mesh)[0].reshape(len(todo), -1)
        clear = depth <= -clearance + 1e-6
        # The clear way nearest the bisector (the bisector itself if it is clear), else the way farthest out.
        nearest = np.argmax(np.where(clear, (w * w[:, :1]).sum(-1), -2.0), axis=1)
        pick = np.where(clear.any(1), nearest, np.argmin(depth, axis=1))
        d = depth[np.arange(len(todo)), pick]
        better = d < best_depth[todo]
        best[todo[better]] = q[better, pick[better]]
        best_depth[todo[better]] = d[better]
        todo = todo[~clear.any(1)]
        if not len(todo):
            break
    return best


PUSH_REACH = 0.2  # metres: deeper than any point of the body lies under its skin


KEY_DECIMALS = 9
"""Decimals of a metre the drape cache key keeps of a pattern's points (and of the cloth under it): 1 nm. The
pattern comes from anny's body through torch, whose last bits may differ on another CPU or torch build; hashed to
the bit, such a pattern missed a cache made elsewhere and was draped afresh (docs/TRADEOFFS.md, the GPU pipeline's
drape-cache misses). Rounded, two patterns a few ulps apart share a key unless a coordinate lies on a rounding
boundary (about one in 10^7 per coordinate for differences of 1e-16 m); a change to the cut moves points by far
more than 1 nm."""


def _key_points(points: np.ndarray) -> bytes:
    """Points rounded to KEY_DECIMALS, as bytes for the cache key (+0.0 folds -0.0 into 0.0: a coordinate rounded to
    zero from below must hash as one rounded from above)."""
    return (np.round(np.asarray(points, np.float64), KEY_DECIMALS) + 0.0).tobytes()


def _cache_key(kind: str, phenotype: dict[str, float], st: DrapeSettings, pattern: np.ndarray, faces: np.ndarray,
               pinned: np.ndarray, over: Sequence[DrapedGarment] = ()) -> str:
    # The installed versions from their metadata (the same strings as the modules' __version__): importing newton
    # only to read its version cost every process ~2 s, also where every drape comes from the cache.
    from importlib.metadata import version

    key = {"v": DRAPE_VERSION, "kind": kind, "phenotype": {k: float(phenotype[k]) for k in PHENOTYPE_LABELS},
           # over_bust where False, settle and settle_keep where set: keys without them read back as before.
           "settings": {k: v for k, v in dataclasses.asdict(st).items()
                        if (k != "over_bust" or not v) and (k not in ("settle", "settle_keep") or v)},
           "newton": version("newton"), "warp": version("warp-lang"),
           "topology": ANNY_TOPOLOGY,
           # The pattern itself, points, triangles and pins: a change to how it is cut or sewn (the same points
           # joined otherwise, as the hood's flipped faces were) cannot read back a drape of the old one.
           "pattern": hashlib.sha256(_key_points(pattern) + np.ascontiguousarray(faces, np.int64).tobytes()
                                     + np.ascontiguousarray(pinned, np.bool_).tobytes()).hexdigest()}
    if over:  # the draped cloth it hangs over is part of the collider (a key without it reads back as before)
        key["over"] = [hashlib.sha256(_key_points(g.vertices) + np.ascontiguousarray(g.faces, np.int64).tobytes())
                       .hexdigest() for g in over]
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:24]


def drape_garment(kind: str, phenotype: dict[str, float], settings: DrapeSettings | None = None,
                  use_cache: bool = True, over: Sequence[DrapedGarment] = ()) -> DrapedGarment:
    """The draped rest-pose garment, from the cache or simulated (then cached, written atomically). `settings`:
    the kind's default (`drape_settings`) unless given. `over`: the draped garments under it whose cloth its drape
    collides with besides the body (`draped_over` picks them: `DRAPED_OVER`); its pattern is cut outside them."""
    settings = drape_settings(kind) if settings is None else settings
    over = tuple(over)
    if any(g.kind not in DRAPED_OVER.get(kind, ()) for g in over):
        raise ValueError(f"drape: {kind} is draped over {DRAPED_OVER.get(kind, ())} only, got "
                         f"{[g.kind for g in over]}")
    pieces = None
    if kind in PROFILES and PROFILES[kind].legs:
        verts, faces, uvs, pinned, mpu, pieces = _trouser_pattern(phenotype, settings, PROFILES[kind])
        pieces = tuple(pieces)
    elif kind in SLEEVE_CUTS:
        verts, faces, uvs, pinned, mpu, pieces = sleeve_pattern(phenotype, settings.n_around, settings.n_rings,
                                                                SLEEVE_CUTS[kind])
    else:
        verts, faces, uvs, pinned, mpu = garment_pattern(
            kind, phenotype, settings, np.concatenate([g.vertices for g in over]) if over else None)
    path = drape_cache_dir() / f"{kind}-{_cache_key(kind, phenotype, settings, verts, faces, pinned, over)}.npz"
    q = None
    if use_cache and path.is_file():
        try:
            with np.load(path) as z:
                q = z["vertices"]
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"{path}: unreadable drape cache ({exc}); delete the file to re-simulate") from exc
        if q.shape != verts.shape:
            raise ValueError(f"{path}: drape cache holds {q.shape} vertices, expected {verts.shape}; delete it")
    if q is None:
        body_v, body_f = run_anny(phenotype)["vertices"], collider_faces(phenotype, kind)
        for g in over:  # one collider mesh: the body's faces, then each cloth's
            body_f = np.concatenate([body_f, np.asarray(g.faces) + len(body_v)])
            body_v = np.concatenate([body_v, g.vertices])
        q = _simulate(verts, faces, pinned, body_v, body_f, settings)
        if use_cache:
            with atomic_path(path) as tmp:
                with open(tmp, "wb") as fh:
                    np.savez(fh, vertices=q)
    return DrapedGarment(kind, q, faces, uvs, pinned, mpu, verts, pieces)


def draped_over(kind: str, draped: Mapping[str, DrapedGarment]) -> tuple[DrapedGarment, ...]:
    """The garments of `draped` (kind -> the character's draped garments under this one, already draped) that a
    draped `kind` is draped over (`DRAPED_OVER`), in `DRAPED_OVER`'s order."""
    return tuple(draped[k] for k in DRAPED_OVER.get(kind, ()) if k in draped)


def draped_pieces(kind: str) -> tuple[str, ...]:
    """The draped kinds a recipe garment of `kind` is draped as, in order (`DRAPED_PIECES`; a draped kind itself,
    nothing for a shell; its draped sleeves aside)."""
    return DRAPED_PIECES.get(kind, (kind,) if kind in DRAPED_KINDS else ())


def piece_settings(kind: str, level: str, worn: Sequence[str]) -> DrapeSettings:
    """A draped piece's simulation worn with `worn` (a recipe's garment kinds): `drape_settings`, but a loose top or
    a dress (`BRIDGE_BAND`) under a jacket or a coat (`BUST_UNDER_NOT`) hung from under the arms (`over_bust` False):
    raised over the bust, its cloth stood up to 29 mm out over the panels' ring, pinned under the arms
    (tests/test_drape_jacket.py)."""
    st = drape_settings(kind, level)
    if kind in BRIDGE_BAND and any(k in BUST_UNDER_NOT for k in worn):
        return dataclasses.replace(st, over_bust=False)
    return st


def drape_layers(kinds: Sequence[str], phenotype: dict[str, float], level: str = "full",
                 worn: Sequence[str] | None = None) -> dict[str, DrapedGarment]:
    """Each draped piece of `kinds` (a recipe's garments, innermost first; `draped_pieces`) draped as
    `build_garments` drapes it: in that order, each over those before it that `DRAPED_OVER` names, at drape `level`
    with `piece_settings` for the garments `worn` (the recipe's, where `kinds` are the first of them; None: `kinds`)
    (the same cache entries)."""
    draped: dict[str, DrapedGarment] = {}
    worn = kinds if worn is None else worn
    for k in (p for kind in kinds for p in draped_pieces(kind)):
        draped[k] = drape_garment(k, phenotype, piece_settings(k, level, worn), over=draped_over(k, draped))
    return draped


def _closest_weights(mesh, points: np.ndarray) -> np.ndarray:
    """Dense bone weights (P, J) of `points` from their closest point on `mesh` (a trimesh of anny's topology
    restricted to the collider): the three corner vertices' linear-blend weights blended by barycentrics."""
    import trimesh

    topo = body_topology()
    closest, _, tri = closest_point(mesh, points)
    corners = np.asarray(mesh.faces)[tri]  # (P, 3)
    bary = trimesh.triangles.points_to_barycentric(mesh.vertices[corners], closest)
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(1, keepdims=True)
    dense = np.zeros((len(points), len(topo.bone_labels)))
    rows = np.arange(len(points))[:, None]
    for c in range(3):
        np.add.at(dense, (rows, topo.bone_indices[corners[:, c]]), bary[:, c:c + 1] * topo.bone_weights[corners[:, c]])
    return dense


def _binding(dense: np.ndarray, pts: np.ndarray, run: dict, max_bones: int, in_bind_space: bool) -> SkinBinding:
    """The `max_bones` largest of the dense weights (P, J), renormalised, and the points in anny's bind space (the
    blended rest-pose transform inverted, unless they already are there)."""
    bones = np.argsort(-dense, axis=1, kind="stable")[:, :max_bones]
    w = np.take_along_axis(dense, bones, axis=1)
    w /= w.sum(1, keepdims=True)
    if in_bind_space:
        return SkinBinding(pts, bones.astype(np.int64), w.astype(np.float32))
    T = run["bone_poses"] @ np.linalg.inv(run["rest_bone_poses"])
    M = np.einsum("pk,pkij->pij", w, T[bones])
    bind = np.einsum("pij,pj->pi", np.linalg.inv(M), np.c_[pts, np.ones(len(pts))])[:, :3]
    return SkinBinding(bind, bones.astype(np.int64), w.astype(np.float32))


def bind_to_skeleton(points: np.ndarray, phenotype: dict[str, float], max_bones: int = 8,
                     in_bind_space: bool = False) -> SkinBinding:
    """Skinning weights of rest-pose points from the closest point of the rest-pose body (trimesh), the three
    corner vertices' weights blended by barycentrics; the points mapped to anny's bind space by inverting the
    blended rest-pose transform, so `skin_points` with the rest pose returns them. `in_bind_space`: the points
    are already in anny's bind space (its `rest_vertices`, where `BodyFeatures` live; headwear is designed there),
    so the weights come from the closest point of that mesh and the points are kept as they are."""
    import trimesh

    run = run_anny(phenotype)
    mesh = trimesh.Trimesh(run["rest_vertices" if in_bind_space else "vertices"], collider_faces(phenotype),
                           process=False)
    pts = np.asarray(points, dtype=np.float64)
    return _binding(_closest_weights(mesh, pts), pts, run, max_bones, in_bind_space)


# The loose garments' binding (`bind_loose`): the closest-point weights diffused over the cloth, fully from
# LOOSE_BELOW metres under the A-pose hip joints down, fading to none LOOSE_FADE metres above that (the waist and
# hips keep the body's own weights), in Jacobi steps of the cloth's graph Laplacian (each vertex moved towards the
# mean of its edge neighbours). Steps = (LOOSE_REACH / mean edge length)^2, so the weights spread as far in metres at
# either drape level (a random walk of n steps of length h reaches ~h sqrt(n)): 23-29 steps at the full drape's
# 21-23 mm edges, ~6 at the coarse one's 41-45 mm. bench/bench_skirt_stride.py chose the values.
LOOSE_REACH = 0.11
LOOSE_BELOW = 0.05
LOOSE_FADE = 0.15
# Kinds whose weights are diffused over the whole cloth but its pinned ring, wherever it hangs: the hood, whose
# particles lie nearest the neck, the head or the upper back by turns (binding each to its own nearest bone would tear
# the hood where the head turns); the ring keeps the neckline's weights and the diffusion carries them into the hood.
# And the open jacket's and coat's sleeves, which stand 16 mm off the arm: bound to the closest point of the arm, the
# upper arm's and the forearm's weights meet in a band as narrow as the skin's crease, and at a bent elbow the wide
# tube folded through itself there (benchmark subject 25's `random` poses: 81-90 crossing edges, 66-76 crossing points
# a camera around could see). Spread along the sleeve the bend is shared by a longer stretch of cloth: 0-3 crossing
# edges there, and over 8 posed frames of 4 wearers 773 -> 567 crossing edges, 179 -> 33 crossing points in view
# (docs/ARCHITECTURE.md, "The open jacket's sleeves"). The narrower sleeves gained nothing measurable from it (tried
# on 4 wearers, 8 posed frames) and keep the closest point's weights.
LOOSE_EVERYWHERE = ("draped_hoodie", "draped_coat_sleeves")
# The reach of the diffusion where a kind's differs from LOOSE_REACH (metres, `loose_iterations`): 8 cm along the
# coat's sleeves, about the 30 steps of its full drape's ~14 mm edges first tried (11 cm, 60 steps, did no better on
# subject 14; 10 steps about half as well).
LOOSE_REACHES = {"draped_coat_sleeves": 0.08}


def _edges(faces: np.ndarray) -> np.ndarray:
    """The unique edges (E, 2) int64 of a triangle mesh, each (low, high)."""
    return edge_counts(faces)[0]


def loose_iterations(garment: DrapedGarment) -> int:
    """The diffusion steps `bind_loose` takes for this garment's mesh by default (its kind's `LOOSE_REACHES`, else
    `LOOSE_REACH`)."""
    v = np.asarray(garment.vertices, np.float64)
    e = _edges(garment.faces)
    reach = LOOSE_REACHES.get(garment.kind, LOOSE_REACH)
    return int(round((reach / float(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1).mean())) ** 2))


def bind_loose(garment: DrapedGarment, phenotype: dict[str, float], max_bones: int = 8,
               iterations: int | None = None) -> SkinBinding:
    """The skinning of a draped garment (`DrapedGarment`, rest pose), made so the cloth below the hips stays one
    piece when the legs part: `bind_to_skeleton`'s closest-point weights would bind the hem's left half to the left
    thigh and its right half to the right one, so a stride splits the cloth around each leg like trouser legs.
    Here the dense weights are diffused over the cloth mesh (`iterations` steps of W <- W + a (mean of the edge
    neighbours' W - W), a per vertex: 0 on the pinned top ring and from `LOOSE_FADE` - `LOOSE_BELOW` above the
    A-pose hip joints up, rising by a smoothstep to 1 at `LOOSE_BELOW` under them), so the front and back of the
    hem blend both thighs and the pelvis and the forward leg carries the cloth in front of it with its neighbours;
    `push_out` keeps the legs inside afterwards. Kinds in LOOSE_EVERYWHERE (the hood, the coat's sleeves) diffuse
    everywhere but on the pinned ring. Deterministic (fixed-order sparse products).
    `iterations`: default `loose_iterations(garment)`; 0 is `bind_to_skeleton` (the binding of before)."""
    import trimesh
    from scipy.sparse import coo_matrix, diags

    run = run_anny(phenotype)
    pts = np.asarray(garment.vertices, dtype=np.float64)
    mesh = trimesh.Trimesh(run["vertices"], binding_faces(phenotype, garment.kind), process=False)
    dense = _closest_weights(mesh, pts)
    labels = body_topology().bone_labels
    z_hip = 0.5 * sum(float(run["bone_poses"][labels.index(b), 2, 3]) for b in ("upperleg01.L", "upperleg01.R"))
    rate = smoothstep((z_hip + LOOSE_FADE - LOOSE_BELOW - pts[:, 2]) / LOOSE_FADE)  # no kink where diffusion starts
    if garment.kind in LOOSE_EVERYWHERE:
        rate[:] = 1.0
    rate[np.asarray(garment.pinned, bool)] = 0.0
    e = _edges(garment.faces)
    n = len(pts)
    adj = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    mean = diags(1.0 / np.maximum(np.asarray(adj.sum(1)).ravel(), 1.0)) @ adj
    step = diags(1.0 - rate) + diags(rate) @ mean  # rows sum to 1: weights stay convex
    iterations = loose_iterations(garment) if iterations is None else int(iterations)
    if iterations < 0:
        raise ValueError(f"bind_loose: iterations must be >= 0, got {iterations}")
    used = np.flatnonzero(dense.any(0))  # bones with any weight on the cloth: diffusing the rest is a no-op
    w = dense[:, used]
    for _ in range(iterations):
        w = step @ w
    dense = np.zeros_like(dense)
    dense[:, used] = w
    return _binding(dense, pts, run, max_bones, False)


def skin_points(binding: SkinBinding, bone_poses: np.ndarray, rest_bone_poses: np.ndarray) -> np.ndarray:
    """Posed points (V, 3) float64 of a binding for one anny run's bone poses."""
    T = np.asarray(bone_poses) @ np.linalg.inv(np.asarray(rest_bone_poses))
    M = np.einsum("pk,pkij->pij", binding.weights.astype(np.float64), T[binding.bones])
    return np.einsum("pij,pj->pi", M, np.c_[binding.bind, np.ones(len(binding.bind))])[:, :3]


LAYER_GAP_DRAPE = 0.004  # what a top laid over the draped waistband keeps above it (metres)
LIFT_SLOPE = 0.5  # how steeply a layer over draped cloth falls back to the skin past the cloth's edge (`layer_lift`)
DIP = 0.003  # metres under the skin from which `cloth_height` looks for the cloth over it
NEAR_BODY = 0.03  # cloth closer than this to the skin in the rest pose registers as a layer under the tops


def cloth_height(body: np.ndarray, cloth: np.ndarray, cloth_faces: np.ndarray, reach: float) -> np.ndarray:
    """Per body vertex (`body`: anny's vertices in the pose the cloth was draped in), how far out along its normal the
    cloth (`cloth`, `cloth_faces`) first lies, in metres (negative where it dips into the skin); inf where it lies
    farther than `reach` or not over that vertex at all."""
    from .geometry import first_hit

    normals = vertex_normals(body, body_topology().faces)
    lo, hi = cloth.min(axis=0) - reach, cloth.max(axis=0) + reach
    idx = np.flatnonzero(((body >= lo) & (body <= hi)).all(axis=1))
    out = np.full(len(body), np.inf)
    # From DIP under the skin: the cloth may dip a millimetre or two into it (the loaded waistband), and a ray from
    # the skin itself would pass it by and find the cloth's far side or nothing.
    hit = first_hit(cloth, cloth_faces, body[idx] - DIP * normals[idx], normals[idx]) - DIP
    out[idx] = np.where(hit < reach, hit, np.inf)
    return out


def layer_lift(body: np.ndarray, height: np.ndarray, slope: float = LIFT_SLOPE) -> np.ndarray:
    """The least offset (metres, per body vertex) a layer over cloth `height` over the skin (`cloth_height`, inf
    where none) must keep: LAYER_GAP_DRAPE over the cloth where it lies, and beyond its edge falling off no faster
    than `slope` metres per metre along the surface (the body's edges in the pose `body`), 0 once it has fallen off.
    A shell over the draped shorts' waistband, where the band bridges the hollow of the back 1-2 cm off the skin,
    rose by that in one row of triangles and folded over when posed; so does a top over a sparse subset of body
    vertices (each cloth vertex's nearest: the rule until 5 December, afternoon)."""
    from scipy import sparse
    from scipy.sparse import csgraph

    covered = np.isfinite(height)
    lift = np.where(covered, np.maximum(height, 0.0) + LAYER_GAP_DRAPE, 0.0)
    if not covered.any():
        return lift
    top = float(lift.max())
    # lift'(v) = max_u lift(u) - slope * d(u, v): a shortest path from one source joined to every covered u by
    # (top - lift(u)) / slope, so every weight is >= 0.
    e, _ = edge_counts(body_topology().faces)
    n = len(body)
    src = np.flatnonzero(covered)
    w = np.concatenate([np.linalg.norm(body[e[:, 0]] - body[e[:, 1]], axis=1) + 1e-9,
                        (top - lift[src]) / slope + 1e-9])
    i = np.concatenate([e[:, 0], np.full(len(src), n)])
    j = np.concatenate([e[:, 1], src])
    graph = sparse.coo_matrix((w, (i, j)), shape=(n + 1, n + 1)).tocsr()
    d = csgraph.dijkstra(graph, directed=False, indices=n)[:n]
    return np.maximum(np.maximum(top - slope * d, 0.0), lift)  # (the 1e-9's aside, the first term is >= lift)


def draped_part(kind: str, phenotype: dict[str, float], feats, under: np.ndarray,
                settings: DrapeSettings | None = None, over: Sequence[DrapedGarment] = (),
                garment: DrapedGarment | None = None):
    """The draped garment as a `PartGeometry` skinned by `SkinBinding`, with a seam column duplicated so u runs
    0..1 around. `under` (body vertices' outermost offset so far) is raised to `layer_lift` over every body vertex
    the cloth covers within `NEAR_BODY` of the skin, so a top hanging over the waistband stays outside it. `over`:
    as `drape_garment`'s; `garment`: the drape itself, if the caller has it (`drape_garment(kind, phenotype,
    settings, over=over)`)."""
    from scipy.spatial import cKDTree

    from .garments import PartGeometry

    settings = drape_settings(kind) if settings is None else settings
    g = drape_garment(kind, phenotype, settings, over=over) if garment is None else garment
    mpu = g.metres_per_uv
    if kind in SLEEVE_CUTS:
        src, faces, uvs, mpu = sleeves_render_mesh(g.pattern, g.pieces)
    elif g.pieces is not None:
        src, faces, uvs, mpu = _pieces_render_mesh(g)
    elif kind == "draped_hoodie":  # an open sheet cut with its own UVs (the hood-up shape's metres)
        src, faces, uvs = np.arange(len(g.vertices)), g.faces, g.uvs
    else:
        na, nr = int(settings.n_around), int(settings.n_rings)
        opened = PROFILES[kind].opening > 0  # the coat, the jacket: an open sheet, no seam column to duplicate
        cols = np.arange(na) if opened else np.concatenate([np.arange(na), [0]])
        src = (np.arange(nr)[:, None] * na + cols[None, :]).ravel()  # render vertex -> simulated vertex
        faces = _grid_faces(np.arange(nr * len(cols)).reshape(nr, len(cols)), wrap=False)
        ts = np.repeat(np.linspace(0.0, 1.0, nr), len(cols))
        length = float(np.linalg.norm(np.diff(g.vertices[::na][:nr], axis=0), axis=1).sum())
        u = np.tile(g.uvs[:na, 0].astype(np.float64) if opened else np.arange(na + 1) / na, nr)
        uvs = np.clip(np.stack([u, (1.0 - ts) * length / g.metres_per_uv], 1), 0.0, 1.0)
    binding = bind_loose(g, phenotype)
    rest = run_anny(phenotype)["vertices"]  # the A-pose the cloth was draped on
    np.maximum(under, layer_lift(rest, cloth_height(rest, g.vertices, g.faces, NEAR_BODY)), out=under)
    nn = cKDTree(rest).query(g.vertices)[1]
    skin = SkinBinding(binding.bind[src], binding.bones[src], binding.weights[src])
    body_vertex = nn[src].astype(np.int64)
    return PartGeometry(
        name=kind,
        faces=faces.astype(np.int32),
        uvs=uvs.astype(np.float32),
        body_vertex=body_vertex,
        offset=np.zeros(len(src), np.float32),
        uv_layout="own",
        metres_per_uv=mpu,
        skinning=skin,
        drape=settings,
    )


def _pieces_render_mesh(g: DrapedGarment):
    """The render mesh of a garment made of several tubes (`DrapedGarment.pieces`: the waist tube, then the legs):
    each tube's grid with its first column repeated at the end. Where tubes meet (the split ring, the crotch seam)
    each keeps its own copies, at the same simulated vertex. Returns (render vertex -> simulated vertex (R,), faces
    (F, 3), uvs (R, 2), metres per UV).

    UVs are metres of the cut (`pattern`, undraped), so the fabric's print stays where it was cut: v the height over
    the hem; u the length along each ring, every ring of a tube centred on the middle of the tube's reference ring
    (the waist's split ring, its last; a leg's first, which is half the split ring and the crotch seam). A leg's
    first ring takes the waist's u where it shares the split ring and runs on along the seam, so a print carries
    across the split ring unbroken (each tube once u-per-column of its own, before 5 December: checks and prints
    broke there, docs/SUBJECTS.md); u jumps only at each tube's wrap column: the waist's centre front (a fly) and
    each leg's front crotch point (an inseam), where the crotch seam mirrors the print as a sewn one does. One scale
    for every piece: the wider of the u span and the length."""
    pat = np.asarray(g.pattern, np.float64)
    z_hem = float(pat[:, 2].min())
    src, faces, us, vs = [], [], [], []
    waist_u: dict[int, float] = {}  # split-ring vertex (but the wrap column's) -> the waist's u there
    n = 0
    for j, grid in enumerate(g.pieces):
        rows, cols = grid.shape
        full, f, arc = seamed_grid(grid, n, pat)  # arc (rows, cols + 1): metres along each ring from its first column
        faces.append(f)
        if j == 0:
            ref, first = rows - 1, 0.0
        else:
            ref = 0
            i = next(i for i, q in enumerate(grid[0]) if int(q) in waist_u)
            first = waist_u[int(grid[0][i])] - arc[0, i]
        middle = first + 0.5 * arc[ref, -1]
        u = middle - 0.5 * arc[:, -1:] + arc
        if j == 0:
            waist_u = {int(q): float(x) for q, x in zip(grid[-1, 1:], u[-1, 1:-1])}
        us.append(u.ravel())
        vs.append((pat[full][..., 2] - z_hem).ravel())
        src.append(full.ravel())
        n += full.size
    uvs, mpu = metre_uvs(us, vs)
    return np.concatenate(src), np.concatenate(faces), uvs, mpu


def closest_on_surface(body_vertices, body_faces, points, body_normals=None, mesh=None, triangles: bool = False):
    """(depth (P,) > 0 inside, closest surface points (P, 3), unit interpolated normals there (P, 3)), and with
    `triangles` the index of the face each closest point lies on (P,) as a fourth. `mesh`: the trimesh of
    (body_vertices, body_faces) if the caller has one (its search tree is reused)."""
    import trimesh

    v = np.asarray(body_vertices, np.float64)
    f = np.asarray(body_faces)
    vn = vertex_normals(v, f) if body_normals is None else np.asarray(body_normals, np.float64)
    p = np.asarray(points, np.float64)
    if mesh is None:
        mesh = query_mesh(v, f)
    closest, dist, tri = closest_point(mesh, p)
    # A triangle squashed to a line or a point (two cloth vertices pushed onto one surface point) has no
    # barycentrics: its corners' normals, averaged.
    with np.errstate(invalid="ignore", divide="ignore"):
        bary = trimesh.triangles.points_to_barycentric(v[f[tri]], closest)
    bary = np.where(np.isfinite(bary).all(1, keepdims=True), bary, 1.0 / 3.0)
    n = (vn[f[tri]] * bary[..., None]).sum(1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    depth = np.where(((p - closest) * n).sum(1) < 0.0, dist, -dist)
    return (depth, closest, n, tri) if triangles else (depth, closest, n)


def penetration(body_vertices: np.ndarray, body_faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Depth (metres, > 0 inside the body, <= 0 outside) of each point under the posed body surface: the distance to
    the closest surface point (trimesh), signed by the body's vertex normals interpolated there. trimesh's own
    `signed_distance` decides the sign by casting rays, ~30x slower here; for points near the skin, which is where
    cloth is, the interpolated normal gives the same answer (tests/test_drape.py compares them)."""
    return closest_on_surface(body_vertices, body_faces, points)[0]
