"""Garment shells cut from the body's own surface, so they are skinned by anny's weights and follow every pose.

A garment is either
- a shell: the part of the body's surface where a smooth field (`garment_level`: height, distance along a limb)
  is negative, cut out along the field's zero level through the triangles (`geometry.split_faces`), so necklines,
  hems and cuffs are smooth curves, not the triangles' zigzag; its vertices sit `offset` metres out along the posed
  body normal (a cut vertex: blended between the two ends of its body edge), or
- (skirts) a generated cone whose vertices are convex blends of body vertices on the hips and thighs: the blend of
  posed vertices plus an offset along the blended normal follows both legs the way a skirt does.

Layers are resolved on the body vertices (interpolated along the edge at a cut): every garment's offset is at least
the offset of the layers under it plus a gap, so an outer garment never dips under an inner one. Offsets taper
towards a garment's open edges so a hem closes onto the skin (no visible gap between cloth and body at cuffs and
collars).

In: a recipe's garments and the phenotype's `BodyFeatures`. Out: one `PartGeometry` per garment, innermost first
(the draped coat, jacket, dress, loose t-shirt and loose long sleeve: a shell over the cloth, "coat", "bodice", "tee"
or "longtop", then the draped cloth, then the coat's and the loose tops' draped sleeves; the draped hoodie: the shell
"hoodie", a longsleeve cut short at the shoulders and the chest, its draped body, its draped hood over that, and its
draped sleeves; `garment_parts`).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from rh_common.body_model import ANNY_TOPOLOGY

from rh_dataset.mesh import vertex_normals

from .body import anchor_points, blended_normals, body_topology, run_anny, smoothed_normals
from .body_features import BodyFeatures
from .drape import (BRIDGE_BAND, BRIDGE_CAP_OVER, DRAPED_KINDS, FRONT_OPENING, SHELL_KINDS_OVER, SHELL_OVERLAP,
                    SHELLS_UNDER, SLEEVE_GROUPS, DrapeSettings, SkinBinding, drape_garment, draped_over, draped_part,
                    draped_pieces, drape_settings, hanging_surface, piece_settings, push_clearance, push_out, shell_hem,
                    shell_hems, shells_under)
from .cloth_pose import LIFT_KINDS, skin_inside
from .geometry import boundary_distance, closed_tube, hull_anchors, smoothstep, split_faces, unique_rows
from .sleeves import SLEEVE_CUTS, sleeve_axis, sleeve_tops
from .recipe import GARMENT_KINDS, Garment

__all__ = ["PartGeometry", "Bridge", "build_garments", "garment_level", "garment_parts", "SHELL_KINDS", "BASE_OFFSET",
           "LAYER_GAP", "GARMENT_PARTS", "COAT_LAPEL", "TUCK", "lift_turn", "lift_directions"]

# Cloth thickness above the skin, metres (outer garments thicker: a jacket stands off the body more than a tee).
BASE_OFFSET = {
    "shoes": 0.008,
    "trousers": 0.007,
    "shorts": 0.007,
    "skirt": 0.007,
    "tshirt": 0.006,
    "longsleeve": 0.006,
    "jacket": 0.017,
    "coat": 0.017,  # the draped coat's and jacket's shoulders, yoke and sleeves (a jacket's cut down to the chest)
    "bodice": 0.006,  # the draped dress's top: a t-shirt's cut with cap sleeves and a scoop neck, down to the chest
    "hoodie": 0.006,  # the hoodie's shoulders: the longsleeve's cut down to the chest, its sleeves cut short under
    # the draped sleeves (its body, hood and sleeves are draped: drape.py, sleeves.py)
    "tee": 0.006,  # the loose t-shirt's shoulders, sleeves and chest: the t-shirt's cut down to the chest (its sleeves
    # cut short under the draped sleeves, sleeves.py, where the t-shirt wears them)
    "longtop": 0.006,  # the loose long sleeve's: the longsleeve's cut down to the chest (its sleeves cut short under
    # the draped long sleeves where it wears them)
}
# The coat's (and open jacket's) front opening in its shell: a V from the panels' gap (drape.FRONT_OPENING wide at
# the shell's hem) widening by COAT_LAPEL metres per metre up to the collar, so the coat reads as open from the
# neck down and the yoke's front edges meet the panels' front edges.
COAT_LAPEL = 0.25
# Metres: a shell's offset where the draped cloth under its hem overlaps it (`_shell`): less than the cloth's own
# distance from the skin there (the coat's panels >= ~13 mm, the dress's cloth >= its 4 mm particle radius). Above
# the shell's own offset it is a lift, not a cap: the loose t-shirt's shell rises to 2.5 mm under its cloth's pinned
# ring (10 mm off the skin once posed, `drape.push_clearance`) instead of tapering to its hem, since the slot
# between a 4-6 mm shell and the ring showed as a dark line across the chest seen from above; the loose long
# sleeve's shell over the same cloth likewise.
TUCK = {"coat": 0.009, "bodice": 0.003, "tee": 0.0075}
TUCK["longtop"] = TUCK["hoodie"] = TUCK["tee"]
# Shells tucked to TUCK only at their hem and lifted over it to their own offset at the cloth's pinned ring: the
# coat's, whose panels' ring stands ~16 mm off the skin (`drape.COAT_CLEARANCE` + 2 mm out of the hull). Tucked to
# 9 mm from its hem up to 5 mm above the ring, the shell left the ring standing 6.5-7.0 mm (median) over it, a dark
# slot across the chest seen from above (bench/bench_coat_shell.py); lifted to 17 mm down to its hem, it came out
# through panels that swung in when simulated (a bending pose).
RING_LIFT = ("coat",)
# Metres above its hem over which such a shell's lift over the layers under it (`under` + LAYER_GAP) fades in: below
# the ring it lies under the panels and may pass through a loose top's cloth, and lifted over that cloth down to its
# hem (18-33 mm off the skin behind the armpits) it came out through the posed panels there (bench_coat_shell.py).
UNDER_FADE = 0.008
# Shells cut as another kind but for their hem (`garment_level`): neckline and sleeves of the named kind.
CUT_AS = {"hoodie": "longsleeve", "tee": "tshirt", "longtop": "longsleeve"}
LAYER_GAP = 0.003  # minimum distance between two layers (well above ray-tracing epsilon at body scale)
# A shell lifted over draped cloth (`drape.layer_lift`: a top over the loose shorts' waistband, 2-3 cm off the skin
# where the band bridges the hollow of the back) sits that far out along normals that converge in every groove of the
# body (the spine, the top of the buttocks' cleft), and its triangles there turned over: dark facets in renders
# (bench/bench_shell_folds.py). Where a shell vertex's offset rises more than LIFT_SMOOTH_FROM over its garment's own
# (BASE_OFFSET), its offset direction turns, over the next LIFT_SMOOTH_WIDTH, to the posed body's normals averaged
# LIFT_SMOOTH_ROUNDS times over each vertex's edge neighbours (`body.smoothed_normals`; some 3-5 cm on the trunk): the
# lift no longer follows the grooves it bridges (`lift_turn`, `lift_directions`; posing: character.py). Shells not
# lifted keep their points bit for bit, and so do shell tops held under draped panels (`drape.SHELLS_UNDER`). On a
# shell laid over the bust (BRIDGED) the same turn takes its shading from the skin's normals to the shell's own
# surface: shaded as the skin, it showed the bust's underside and the cleavage it spans. (The other lifted shells keep
# the skin's shading: their own surface's showed a few turned-over triangles in the hollow of the back,
# tests/test_layer_lift.py.)
LIFT_SMOOTH_FROM = 0.002
LIFT_SMOOTH_WIDTH = 0.008
LIFT_SMOOTH_ROUNDS = 8
# Metres a bridged shell (`_bridged`) is lifted at most: a vertex whose offset direction is nearly vertical (the
# underside of the bust) would reach the hanging surface only far along it.
BRIDGE_MAX = 0.04
# Halvings of `_bridged`'s search for each shell vertex's offset (from BRIDGE_MAX: 40 mm / 2^16 = 0.6 um).
BRIDGE_ROUNDS = 16
# Shells laid over the bust as their loose top's or dress's fabric hangs (`drape.hanging_surface`):
# {shell part: its draped kind}.
BRIDGED = {shell: kind for kind, shell in SHELL_KINDS_OVER.items() if kind in BRIDGE_BAND}
TAPER_WIDTH = 0.025  # metres over which the offset falls towards an open edge
TAPER_MIN = 0.3  # fraction of the offset left at the very edge


@dataclasses.dataclass(frozen=True)
class PartGeometry:
    """Geometry of one character part, independent of pose.

    Posed position of split vertex i: anchor_i + offset_i * n_i, where anchor_i / n_i are the posed body vertex
    `body_vertex[i]` and its normal, or, when `blend_vertices` is set, the `blend_weights`-weighted sums of posed
    body vertices / normals (normal renormalised). Shells (`body_faces` set) are blends of the two ends of a body
    edge, so their cut edges can run across the body's triangles.
    """

    name: str
    faces: np.ndarray  # (F, 3) int32
    uvs: np.ndarray  # (V, 2) float32 in [0, 1], v up
    body_vertex: np.ndarray  # (V,) int64
    offset: np.ndarray  # (V,) float32 metres
    uv_layout: str  # "body" (anny's UV layout) or "own" (a layout generated with the part)
    metres_per_uv: float  # approximate surface metres per UV unit (pattern scale)
    blend_vertices: np.ndarray | None = None  # (V, K) int64
    blend_weights: np.ndarray | None = None  # (V, K) float32, rows sum to 1
    skinning: "SkinBinding | None" = None  # draped garments: linear-blend skinning instead of anchors (drape.py)
    body_faces: np.ndarray | None = None  # (F,) shells: the body face each face lies in (normals are the body's)
    drape: "DrapeSettings | None" = None  # draped garments: the simulation they were draped with (drape.py)
    # Draped `cloth_pose.LIFT_KINDS`: the body vertices inside the cloth at rest (`cloth_pose.skin_inside`), which
    # posing keeps under it (`cloth_pose.lift_over_skin`).
    inside_skin: np.ndarray | None = None


def _z(feats: BodyFeatures, bone: str) -> float:
    return float(feats.bone_heads[bone][2])


def garment_level(kind: str, feats: BodyFeatures, hem: float | np.ndarray | None = None,
                  sleeves: Mapping[str, float] | None = None) -> np.ndarray:
    """A smooth field (V,) float64 over the body vertices (rest pose of this phenotype), in metres, negative where
    a shell garment covers the body: its zero level set is the garment's open edges (neckline, hem, cuffs, waist),
    along which `split_faces` cuts the body's triangles. Each edge is a level of a smooth function (height, a
    rounded scoop in front of the neck, distance along a limb's axis), so the cut is a smooth curve; bone-group
    labels only pick which function applies to a vertex (an arm takes the sleeve's, never the trunk's), so their
    ragged borders never become an edge. `hem` (bind-space height; the "coat", "bodice", "tee", "longtop" and
    "hoodie" shells only, whose hem is where the draped cloth under them is pinned: `drape.shell_hem`). Shells in
    CUT_AS take the neckline and sleeves of the kind named there. `sleeves` ({"L": metres, "R": metres}; the "tee",
    "longtop" and "hoodie" under the draped sleeves): each sleeve ends that far along its upper arm's axis
    (`sleeves.sleeve_axis`, from the upperarm01 joint) instead of at its cut's length."""
    v = feats.rest_vertices
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    z_neck = _z(feats, "neck01")
    y_neck = float(feats.bone_heads["neck01"][1])
    z_hip = 0.5 * (_z(feats, "upperleg01.L") + _z(feats, "upperleg01.R"))
    z_waist = 0.5 * (_z(feats, "root") + _z(feats, "spine04")) + 0.02
    out = np.full(len(v), 1.0)  # vertices no part of the garment applies to: 1 m outside
    shell, hem_given = kind, kind in TUCK
    kind = CUT_AS.get(kind, kind)
    if kind in ("tshirt", "longsleeve", "jacket", "coat", "bodice"):
        # A scoop at the front centre: the neckline drops in front of the neck, not behind it (smoothsteps, so
        # the collar's curve has no corners).
        front = smoothstep(-(y - y_neck) / 0.07) * smoothstep(1.0 - np.abs(x) / 0.1)
        drop = {"tshirt": 0.04, "longsleeve": 0.03, "jacket": 0.06, "coat": 0.06, "bodice": 0.08}[kind]
        collar = z - (z_neck - 0.012 - drop * front)
        if hem_given and hem is None:
            raise ValueError(f"garment_level: the {shell!r} shell needs its hem height (drape.shell_hem)")
        if kind == "coat":
            # The open front: a V, cut on the front half only (at the sides |x| is far wider than the V).
            half = 0.5 * FRONT_OPENING + COAT_LAPEL * np.maximum(z - hem, 0.0)
            collar = np.maximum(collar, np.where(y < y_neck, half - np.abs(x), -np.inf))
        # The hem: one bind-space height, or one per body vertex (drape.shell_hems).
        z_hem = (np.asarray(hem, np.float64) if hem_given
                 else z_hip + {"tshirt": 0.0, "longsleeve": -0.005, "jacket": -0.02}[kind])
        sleeve = {"tshirt": 0.3, "longsleeve": 0.95, "jacket": 0.97, "coat": 0.97, "bodice": 0.12}[kind]
        # Hem: a horizontal cut through trunk and hips alike (upper-leg vertices included), above the crotch so a
        # top never turns into a bodysuit between the legs.
        trunk = feats.in_groups("torso", "shoulder", "neck", "upperleg")
        arm = feats.in_groups("shoulder", "upperarm", "lowerarm", "hand")
        body = np.maximum(collar, z_hem - z)
        arm_len = {s: float(np.linalg.norm(feats.bone_heads[f"wrist.{s}"] - feats.bone_heads[f"upperarm01.{s}"]))
                   for s in "LR"}
        length = np.where(x > 0, arm_len["L"], arm_len["R"])
        cuff = np.maximum(collar, (np.nan_to_num(feats.arm_t, nan=9.0) - sleeve) * length)
        if sleeves is not None:
            along = {s: (v - sleeve_axis(feats.bone_heads, s)[0]) @ sleeve_axis(feats.bone_heads, s)[1] - sleeves[s]
                     for s in "LR"}
            cuff = np.maximum(collar, np.where(x > 0, along["L"], along["R"]))
        out = np.where(trunk, body, out)
        out = np.where(arm, np.minimum(cuff, np.where(trunk, body, np.inf)), out)
    elif kind in ("trousers", "shorts"):
        length = {"trousers": 0.965, "shorts": 0.42}[kind]
        leg_len = {s: float(np.linalg.norm(feats.bone_heads[f"foot.{s}"] - feats.bone_heads[f"upperleg01.{s}"]))
                   for s in "LR"}
        scale = np.where(x > 0, leg_len["L"], leg_len["R"])
        waist = z - z_waist
        leg = np.maximum(waist, (np.nan_to_num(feats.leg_t, nan=9.0) - length) * scale)
        out = np.where(feats.in_groups("torso"), waist, out)
        out = np.where(feats.in_groups("upperleg", "lowerleg", "foot"), leg, out)
    else:
        raise ValueError(f"garment_level: {kind!r} is not a shell garment (shells: {SHELL_KINDS})")
    return out


SHELL_KINDS = ("tshirt", "longsleeve", "jacket", "trousers", "shorts")  # recipe kinds (the coat's shell is a part)
# Parts a recipe garment is built as, in build order: the draped coat and jacket are a shell (shoulders, yoke, and
# sleeves cut short under their draped sleeves) and the draped panels below it, the dress a shell (its bodice) and
# the draped skirt below it, the loose t-shirt and long sleeve a shell ("tee", "longtop": shoulders, sleeves, chest)
# and a draped body below it (drape.SHELL_KINDS_OVER), the draped hoodie the longsleeve's shell ("hoodie") down to
# the chest, a draped body below it (the loose tops' cut in fleece) and its draped hood over that body (drape.py's
# DRAPED_PIECES); all in the garment's fabric. The loose tops', the hoodie's, the open coat's and jacket's sleeves are
# draped too ("draped_sleeves", "draped_long_sleeves", "draped_hoodie_sleeves", "draped_coat_sleeves": sleeves.py;
# the jacket is the coat cut short and wears the coat's; nothing is worn over a hoodie, recipe_draws._hoodie), but a
# top's not under an open jacket or coat (SLEEVES_UNDER_NOT): their draped sleeves are draped over the arm alone,
# clear of a 6 mm shell sleeve under them (16 mm off the arm) but not of another draped one.
GARMENT_PARTS = {**{kind: (shell, kind) for kind, shell in SHELL_KINDS_OVER.items() if kind in GARMENT_KINDS},
                 "draped_hoodie": ("hoodie", "draped_hoodie_body", "draped_hoodie", "draped_hoodie_sleeves"),
                 "draped_coat": ("coat", "draped_coat", "draped_coat_sleeves"),
                 "draped_jacket": ("coat", "draped_jacket", "draped_coat_sleeves"),
                 "draped_tshirt": ("tee", "draped_tshirt", "draped_sleeves"),
                 "draped_longsleeve": ("longtop", "draped_longsleeve", "draped_long_sleeves")}
SLEEVES_UNDER_NOT = ("draped_jacket", "draped_coat")


def garment_parts(kind: str, worn: Sequence[str] = ()) -> tuple[str, ...]:
    """The names of the parts (`PartGeometry.name`) `build_garments` makes of a recipe garment of this kind, worn
    with the garments `worn` (a recipe's garment kinds: the loose tops' draped sleeves are left out under an open
    jacket or a coat, whose own are kept)."""
    parts = GARMENT_PARTS.get(kind, (kind,))
    if kind not in SLEEVES_UNDER_NOT and any(k in SLEEVES_UNDER_NOT for k in worn):
        parts = tuple(p for p in parts if p not in SLEEVE_CUTS)
    return parts


def _draped_sleeves(kind: str, worn: Sequence[str]) -> str | None:
    """The draped sleeves' part (`SLEEVE_CUTS`) a garment of this kind makes when worn with `worn`, if any."""
    return next((p for p in garment_parts(kind, worn) if p in SLEEVE_CUTS), None)


LEVEL_MIN = 1e-5  # metres: no vertex sits on the level set itself (a cut there would make a zero-area face)


def _clean_level(level: np.ndarray, topology: str) -> np.ndarray:
    """The level with small holes filled and specks removed: an island of fewer than 60 uncovered faces inside a
    garment is covered, an island of fewer than 40 covered faces (any corner inside) is dropped. Vertices are
    also kept off the zero level by LEVEL_MIN."""
    topo = body_topology(topology)
    level = np.where(np.abs(level) < LEVEL_MIN, np.where(level < 0, -LEVEL_MIN, LEVEL_MIN), level)
    f = topo.faces
    nf = len(f)
    # Face adjacency through shared edges.
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(nf), 3)
    key = e[:, 0] * topo.n_vertices + e[:, 1]
    order = np.argsort(key, kind="stable")
    k_sorted = key[order]
    same = k_sorted[1:] == k_sorted[:-1]
    a, b = fid[order][:-1][same], fid[order][1:][same]

    def components(active: np.ndarray) -> tuple[int, np.ndarray]:
        keep = active[a] & active[b]
        g = sparse.coo_matrix((np.ones(keep.sum()), (a[keep], b[keep])), shape=(nf, nf))
        return csgraph.connected_components(g, directed=False)

    sel = (level[f] < 0).any(axis=1)
    n, lab = components(~sel)  # holes: small islands of uncovered faces
    small = np.bincount(lab[~sel], minlength=n) < 60
    fill = np.unique(f[~sel & small[lab]])
    level = level.copy()
    level[fill] = -np.abs(level[fill])
    sel = (level[f] < 0).any(axis=1)
    n, lab = components(sel)  # specks: small islands of covered faces
    tiny = np.bincount(lab[sel], minlength=n) < 40
    drop = np.unique(f[sel & tiny[lab]])
    level[drop] = np.abs(level[drop])
    return level


def _metres_per_uv(face_ids: np.ndarray, feats: BodyFeatures, topology: str) -> float:
    topo = body_topology(topology)
    tri = feats.rest_vertices[topo.faces[face_ids]]
    uv = topo.texcoords[topo.face_texcoords[face_ids]]
    a3 = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    a2 = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]).sum()
    return float(np.sqrt(a3 / max(a2, 1e-12)))


def lift_turn(kind: str, offset: np.ndarray) -> np.ndarray:
    """(V,) how far each vertex of a `kind` shell at `offset` (V,) metres turns its offset direction and shading to
    the smoothed normals and its own surface (0..1; LIFT_SMOOTH_FROM)."""
    rise = np.asarray(offset, np.float64) - BASE_OFFSET[kind] - LIFT_SMOOTH_FROM
    return np.clip(rise / LIFT_SMOOTH_WIDTH, 0.0, 1.0)


def lift_directions(own: np.ndarray, even: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Unit offset directions (P, 3): the blended body normals `own` turned by `turn` (P,) to the smoothed ones
    `even` (both (P, 3), `body.blended_normals` of the normals and of `smoothed_normals`, LIFT_SMOOTH_ROUNDS)."""
    d = own + np.asarray(turn, np.float64)[:, None] * (even - own)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclasses.dataclass(frozen=True)
class Bridge:
    """What a `BRIDGED` shell is laid over the bust with (`_bridged`): its wearer's `phenotype`, its draped cloth's
    simulation `settings` (`drape.piece_settings`: the surface meets that cloth's pinned ring) and `cloth`, that
    cloth's rest vertices (V, 3) and faces (F, 3), which the lift under the ring stays under (None: not held)."""

    phenotype: dict[str, float]
    settings: DrapeSettings
    cloth: tuple[np.ndarray, np.ndarray] | None = None


def _bridged(kind: str, split, off: np.ndarray, feats: BodyFeatures, topology: str, bridge: Bridge) -> np.ndarray:
    """A loose top's shell (`BRIDGED`) lifted, on the front of its trunk over its cloth's pinned ring, onto the surface
    its fabric would hang on (`drape.hanging_surface`): across the cleavage, down from the bust and out over the belly
    to the ring. Each vertex's offset is where its point, along the direction posing gives it at that offset
    (`lift_directions`), in the rest A-pose the cloth is cut in, meets that surface where it is (bisection,
    BRIDGE_ROUNDS), at most BRIDGE_MAX over its own; its weight there (`HangingSurface.weight_at`, at the skin) of the
    way. Only lifted, but up to BRIDGE_CAP_OVER over the ring, where the surface lies under the ring: a tuck
    (TUCK) standing out of it there is lowered onto it (by its weight round the trunk alone). `bridge.cloth` (its
    draped cloth, rest A-pose): under the ring, a lift is held LAYER_GAP under that cloth along its direction: under
    the bust the cloth falls in under the ring, and a shell lifted to the ring's radius there came 0.3-0.4 mm out
    through it (tests/test_drape_tshirt.py -m slow)."""
    rest = run_anny(bridge.phenotype)["vertices"]
    normals = vertex_normals(rest, body_topology(topology).faces)
    bv = np.stack([split.body_vertex, split.cut_vertex], 1)
    bw = np.stack([1.0 - split.cut_t, split.cut_t], 1)
    skin = anchor_points(rest, normals, bv, bw, np.zeros(len(bv)))
    surface = hanging_surface(BRIDGED[kind], bridge.phenotype, bridge.settings)
    weight = surface.weight_at(skin)
    nearest = np.where(split.cut_t > 0.5, split.cut_vertex, split.body_vertex)
    low = (skin[:, 2] <= surface.z_ring + BRIDGE_CAP_OVER) & (surface.front_weight_at(skin) > 0)
    sel = np.flatnonzero(((weight > 0) | low) & feats.in_groups("torso")[nearest])
    own = blended_normals(normals, bv[sel], bw[sel])
    even = blended_normals(smoothed_normals(normals, LIFT_SMOOTH_ROUNDS, topology), bv[sel], bw[sel])
    p = skin[sel]

    def out_of(o: np.ndarray) -> np.ndarray:  # metres the point at offset o stands out of the surface there
        q = p + o[:, None] * lift_directions(own, even, lift_turn(kind, o))
        return np.hypot(q[:, 0] - surface.centre[0], q[:, 1] - surface.centre[1]) - surface.radius_at(q)

    base = off[sel].astype(np.float64)
    inside = out_of(base) < 0.0
    # Out of the surface already: under the ring's height (where the surface lies BRIDGE_SHELL_GAP under the ring),
    # lowered onto it, so the shell's tuck stays under the cloth where the ring is pinned over the bust's apex.
    cap = ~inside & low[sel]
    lo = np.where(inside, base, 0.0)
    hi = np.where(inside, base + BRIDGE_MAX, base)
    for _ in range(BRIDGE_ROUNDS):
        mid = 0.5 * (lo + hi)
        below = out_of(mid) < 0.0
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    found = np.where(inside | cap, 0.5 * (lo + hi), base)  # a lift's hi stays at BRIDGE_MAX where never out
    w = np.where(cap, surface.front_weight_at(p), weight[sel])
    new = base + w * (found - base)
    low = np.flatnonzero((p[:, 2] < surface.z_ring) & (new > base))
    if bridge.cloth is not None and len(low):
        import trimesh

        d = lift_directions(own[low], even[low], lift_turn(kind, new[low]))
        cv, cf = bridge.cloth
        mesh = trimesh.Trimesh(np.asarray(cv, np.float64), np.asarray(cf), process=False)
        loc, ray, _ = mesh.ray.intersects_location(p[low], d, multiple_hits=False)
        hit = np.full(len(low), np.inf)
        hit[ray] = ((loc - p[low][ray]) * d[ray]).sum(1)
        new[low] = np.maximum(np.minimum(new[low], hit - LAYER_GAP), base[low])
    out = off.copy()
    out[sel] = new
    return out


def _shell(kind: str, feats: BodyFeatures, under: np.ndarray, topology: str, hem: float | np.ndarray | None = None,
           cover: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
           sleeves: Mapping[str, float] | None = None, bridge: Bridge | None = None) -> PartGeometry:
    """A shell cut from the body along `garment_level`'s zero level (`hem`: the coat's). Every vertex is a blend of
    the two ends of a body edge (weight 1 on one end except on the cut), offset along the blended normal: the taper
    runs over the surface distance from the cut, and layering compares with the layers below interpolated the same
    way. `cover` (the coat's shell, and a shell top's trunk under the open jacket or coat: drape.SHELLS_UNDER): (the
    body's vertices in anny's rest A-pose, and the vertices and faces of the draped cloth over the shell in that
    pose): the shell stays under that cloth (`_under_cover`). `sleeves`: as `garment_level`'s. `bridge`: a
    `BRIDGED` shell's, which is then laid over the bust (`_bridged`)."""
    level = _clean_level(garment_level(kind, feats, hem, sleeves), topology)
    topo = body_topology(topology)
    face_ids = np.flatnonzero((level[topo.faces] < 0).any(axis=1))
    split = split_faces(face_ids, topology, level=level)
    dist = boundary_distance(split, feats.rest_vertices)
    off = BASE_OFFSET[kind] * (TAPER_MIN + (1.0 - TAPER_MIN) * smoothstep(dist / TAPER_WIDTH))
    nearest = np.where(split.cut_t > 0.5, split.cut_vertex, split.body_vertex)  # each vertex's nearer body vertex
    if kind in TUCK:
        # Tucked under the draped cloth: at most TUCK off the skin up to 5 mm above its pinned ring (SHELL_OVERLAP
        # above the hem; the drape keeps the ring its particle radius + 2 mm off the body's hull), rising smoothly to
        # the full offset 2 cm above that. The 5 mm: bind space is the A-pose frame turned by ~1.5 degrees about X as
        # well as raised, so at the back a bind-space height is a few millimetres off the ring's.
        z = split.points(feats.rest_vertices)[:, 2]
        if np.ndim(hem):  # per body vertex (drape.shell_hems): along the cut edges as the points are
            hem = split.points(np.asarray(hem, np.float64)[:, None])[:, 0]
        rise = smoothstep((z - hem - SHELL_OVERLAP - 0.005) / 0.02)
        if kind in RING_LIFT:
            # The coat's: at most TUCK at its hem, rising to its own offset at the panels' ring (SHELL_OVERLAP
            # higher), and its trunk lifted to that over the hem's taper up to 5 mm above the ring, fading 2 cm
            # higher; `_under_cover` then holds it LAYER_GAP under the panels at rest. Sleeves (their cuffs hang at
            # the ring's height in the A-pose) keep their taper.
            cap = TUCK[kind] + (BASE_OFFSET[kind] - TUCK[kind]) * smoothstep((z - hem) / SHELL_OVERLAP)
            lifted = feats.in_groups("torso")[nearest]
            off = np.minimum(off, cap)
            off = np.where(lifted, np.maximum(off, cap * (1.0 - rise)), off)
        else:
            cap = TUCK[kind] + (BASE_OFFSET[kind] - TUCK[kind]) * rise
            off = np.maximum(off, cap) if TUCK[kind] > BASE_OFFSET[kind] else np.minimum(off, cap)
    t = split.cut_t
    need = np.where(under > 0, under + LAYER_GAP, 0.0)
    need = (1.0 - t) * need[split.body_vertex] + t * need[split.cut_vertex]
    if kind in RING_LIFT:
        need = need * smoothstep((z - hem) / UNDER_FADE)
    off = np.maximum(off, need)
    if kind in BRIDGED and bridge is not None:
        off = _bridged(kind, split, off, feats, topology, bridge)
    if cover is not None:
        capped = np.minimum(off, _under_cover(split, off, *cover, topology))
        # The coat's whole shell; a shell top but its sleeves (drape.SHELLS_UNDER: they lie under the coat's).
        off = capped if kind == "coat" else np.where(feats.in_groups(*SLEEVE_GROUPS)[nearest], off, capped)
    whole = t == 0
    np.maximum.at(under, split.body_vertex[whole], off[whole])
    bv = np.stack([split.body_vertex, split.cut_vertex], 1)
    bw = np.stack([1.0 - t, t], 1).astype(np.float32)
    return PartGeometry(
        name=kind,
        faces=split.faces,
        uvs=split.uvs,
        body_vertex=nearest,
        offset=off.astype(np.float32),
        uv_layout="body",
        metres_per_uv=_metres_per_uv(face_ids, feats, topology),
        blend_vertices=bv,
        blend_weights=bw,
        body_faces=split.body_faces,
    )


COVER_REACH = 0.05  # metres along a shell vertex's normal within which draped cloth over it caps its offset
COVER_RISE = 0.005  # metres above its pinned ring the cloth is taken to cover the shell (`_under_cover`)


def _under_cover(split, off: np.ndarray, rest: np.ndarray, cloth: np.ndarray, cloth_faces: np.ndarray,
                 topology: str) -> np.ndarray:
    """Per shell vertex, the highest offset (metres) that keeps it LAYER_GAP under the draped cloth hanging from
    its hem (`off` where no cloth lies within COVER_REACH along its normal), all in anny's rest A-pose (`rest`:
    the body's vertices there; `cloth`, `cloth_faces`: the drape). TUCK alone holds the shell inside cloth pinned
    near the skin; over a loose top the jacket's panels hang 14-39 mm off the skin, and the shell, lifted over the
    top's cloth by `under`, came out through them (bench_cloth --kind draped_jacket). Under the cap the shell may
    pass through the top's cloth, where both lie under the panels."""
    import trimesh

    bv = np.stack([split.body_vertex, split.cut_vertex], 1)
    bw = np.stack([1.0 - split.cut_t, split.cut_t], 1)
    normals = vertex_normals(rest, body_topology(topology).faces)
    origin = anchor_points(rest, normals, bv, bw, np.zeros(len(bv)))
    direction = blended_normals(normals, bv, bw)
    # The cloth and a copy of it COVER_RISE higher: the shell's vertices at the ring's height sit on normals that
    # tilt down past the ring's edge, so the cloth is taken to reach that much above its ring.
    cloth = np.asarray(cloth, np.float64)
    f = np.asarray(cloth_faces)
    mesh = trimesh.Trimesh(np.concatenate([cloth, cloth + (0.0, 0.0, COVER_RISE)]), np.concatenate([f, f + len(cloth)]),
                           process=False)
    loc, ray, _ = mesh.ray.intersects_location(origin, direction, multiple_hits=True)
    hit = np.full(len(origin), np.inf)
    np.minimum.at(hit, ray, ((loc - origin[ray]) * direction[ray]).sum(1))
    cap = np.where(hit < COVER_REACH, hit - LAYER_GAP, np.inf)
    return np.where(np.isfinite(cap), np.maximum(cap, LEVEL_MIN), off)


SHOE_CLEARANCE = 0.006  # metres between the foot and the shoe's upper
SHOE_SOLE = 0.01  # extra thickness under the foot
SHOE_TOE_ROOM = 0.02  # how far the toe cap reaches beyond the toes
SHOE_COLLAR = 0.085  # height of the shoe's opening above the bottom of the foot


def _polygon_exit(poly: np.ndarray, centre: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Distance from `centre` along each 2D unit direction to where it leaves a convex polygon (CCW vertices)."""
    a = poly - centre
    e = np.roll(a, -1, axis=0) - a
    out = np.zeros(len(dirs))
    for k, d in enumerate(dirs):
        den = d[0] * (-e[:, 1]) - d[1] * (-e[:, 0])
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (a[:, 0] * (-e[:, 1]) - a[:, 1] * (-e[:, 0])) / den
            t = (d[0] * a[:, 1] - d[1] * a[:, 0]) / den
        ok = (t >= -1e-9) & (t <= 1 + 1e-9) & (s > 0) & np.isfinite(s)
        out[k] = float(s[ok].max()) if ok.any() else float(np.max(a @ d))
    return out


def _shoe_shape(feats: BodyFeatures, side: str, n_sections: int = 24, n_around: int = 28):
    """A closed shoe around one foot, in the rest pose: rings (S, K, 3) swept from heel to toe, each the convex hull
    of the foot's cross-section (so toes and the gaps between them vanish) pushed out by the clearance, smoothed
    along the foot, with a flat thick sole; plus heel and toe poles."""
    from scipy.spatial import ConvexHull

    v = feats.rest_vertices
    sign = 1.0 if side == "L" else -1.0
    foot = (feats.in_groups("foot") | feats.masks[f"foot.{side}"]) & (v[:, 0] * sign > 0)
    z_floor = float(v[foot, 2].min())
    z_collar = z_floor + SHOE_COLLAR
    pts_m = (foot | (feats.in_groups("lowerleg") & (v[:, 0] * sign > 0))) & (v[:, 2] < z_collar)
    pts = v[pts_m]
    low = pts[pts[:, 2] < z_floor + 0.04]
    xy = low[:, :2] - low[:, :2].mean(0)
    w, vec = np.linalg.eigh(xy.T @ xy)
    ax = np.array([vec[0, 1], vec[1, 1], 0.0])
    if ax[1] > 0:
        ax = -ax  # heel to toe points to -Y (the front)
    lat = np.cross([0.0, 0.0, 1.0], ax)
    origin = np.array([low[:, 0].mean(), low[:, 1].mean(), 0.0])
    s_all = (pts - origin) @ ax
    s0, s1 = float(s_all.min()), float(s_all.max())
    ss = np.linspace(s0 + 0.004, s1 - 0.002, n_sections)
    half = 0.75 * (ss[1] - ss[0]) + 0.004
    phi = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)  # 0 = up, then towards +lat
    dirs2 = np.stack([np.sin(phi), np.cos(phi)], 1)  # (lateral, vertical)
    radii, centres = [], []
    prev = None
    for s in ss:
        sel = pts[np.abs(s_all - s) < half]
        q = np.stack([(sel - origin) @ lat, sel[:, 2]], 1) if len(sel) else np.zeros((0, 2))
        if len(q) >= 4 and np.ptp(q[:, 0]) > 1e-3 and np.ptp(q[:, 1]) > 1e-3:
            hull = q[ConvexHull(q).vertices]
            c = hull.mean(0)
            r = _polygon_exit(hull, c, dirs2)
            prev = (c, r)
        else:
            c, r = prev
        centres.append(c)
        radii.append(r)
    centres = ndimage_gaussian(np.array(centres), 1.0)
    radii = ndimage_gaussian(np.array(radii), 1.2)
    radii = radii + SHOE_CLEARANCE
    # Rings in 3D; the sole: everything within 1.5 cm of the floor is flattened onto a plane below the foot.
    ring = (origin + ss[:, None, None] * ax + centres[:, None, :1] * lat
            + radii[..., None] * dirs2[None, :, :1] * lat)
    z = centres[:, None, 1] + radii * dirs2[None, :, 1]
    bottom = z_floor - SHOE_CLEARANCE - SHOE_SOLE
    z = np.maximum(z, bottom)
    z = np.minimum(z, z_collar)
    ring[..., 2] = z
    # Toe box: the last sections round off forwards; the heel is pulled back a little.
    tip_c = ring[-1].mean(0) + ax * SHOE_TOE_ROOM
    tip_c[2] = bottom + 0.35 * (ring[-1, :, 2].max() - bottom)
    heel_c = ring[0].mean(0) - ax * 0.006
    heel_c[2] = bottom + 0.4 * (ring[0, :, 2].max() - bottom)
    frac = np.linspace(0.0, 1.0, n_sections)
    pull = smoothstep((frac - 0.85) / 0.15) * 0.25
    ring = ring + pull[:, None, None] * (tip_c - ring)
    return ring, heel_c, tip_c, z_floor


def _same_for_coincident(points: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The per-group maximum of `values` over points at equal positions (copies of a vertex at a UV seam)."""
    inv = unique_rows(np.round(points / 1e-7).astype(np.int64))[1]
    m = np.full(inv.max() + 1, -np.inf)
    np.maximum.at(m, inv, values)
    return m[inv]


def vol_sign(verts: np.ndarray, faces: np.ndarray) -> float:
    tri = verts[faces]
    return float((np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri[:, 0]).sum())


def ndimage_gaussian(a: np.ndarray, sigma: float) -> np.ndarray:
    from scipy import ndimage

    return ndimage.gaussian_filter1d(a, sigma, axis=0, mode="nearest")


def _shoes(feats: BodyFeatures, under: np.ndarray) -> PartGeometry:
    """Two closed shoes, bound to the feet and ankles (blend anchoring, like hair), with their own UV layout:
    u around the foot (0 = the top of the instep), v from the toe (1) to the heel (0)."""
    from .geometry import bind_points, drop_unreferenced, surface_clearance

    verts, faces, uvs = [], [], []
    v, nrm = feats.rest_vertices, feats.rest_normals
    for side in ("L", "R"):
        ring, heel, tip, z_floor = _shoe_shape(feats, side)
        S, K, _ = ring.shape
        sign = 1.0 if side == "L" else -1.0
        cand = np.flatnonzero((feats.in_groups("foot", "lowerleg")) & (v[:, 0] * sign > 0))
        # Push any ring point that still lies within the clearance of the skin straight out from its section's axis.
        centre = ring.mean(1, keepdims=True)
        d = ring - centre
        d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        flat = ring.reshape(-1, 3)
        for _ in range(3):
            h = surface_clearance(flat, v, nrm, cand)
            need = np.maximum(0.004 - h, 0.0)
            if not need.any():
                break
            flat = flat + 1.1 * need[:, None] * d.reshape(-1, 3)
        ring = flat.reshape(S, K, 3)
        n_rows, n_cols = S + 2, K + 1
        pv, f = closed_tube(ring, heel, tip)
        # Every foot vertex below the collar must be inside the shoe (with 3 mm to spare): where one is not, push the
        # shoe vertices around it outwards from their section's axis (the toe tips are the usual culprits).
        from scipy.spatial import cKDTree

        inner = v[cand[v[cand, 2] < z_floor + SHOE_COLLAR - 0.01]]
        axis_pt = np.concatenate([np.repeat(heel[None], K + 1, 0), np.repeat(ring.mean(1), K + 1, 0),
                                  np.repeat(tip[None], K + 1, 0)])
        for _ in range(4):
            sn = vertex_normals(pv, f if vol_sign(pv, f) > 0 else f[:, ::-1])
            h = surface_clearance(inner, pv, sn, np.arange(len(pv)))
            bad = h > -0.003
            if not bad.any():
                break
            dist, nn = cKDTree(pv).query(inner[bad], k=6)
            push = np.zeros(len(pv))
            np.maximum.at(push, nn.ravel(), np.repeat(h[bad] + 0.004, 6))
            push = _same_for_coincident(pv, push)
            dirs = pv - axis_pt
            dirs /= np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-9)
            pv = pv + push[:, None] * dirs
        tri = pv[f]
        vol = float((np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri[:, 0]).sum())
        if vol < 0:
            f = f[:, ::-1]
        u = np.arange(n_cols) / K
        vv = np.linspace(0.0, 1.0, n_rows)  # heel (0) to toe (1)
        uv = np.stack(np.broadcast_arrays(u[None, :], vv[:, None]), -1).reshape(-1, 2)
        pv, f, uv = drop_unreferenced(pv, f, uv)
        faces.append(f + sum(len(x) for x in verts))
        verts.append(pv)
        uvs.append(uv)
        # Register the shoe as the layer under the trouser hems: body vertices inside it get its clearance.
        inside = cand[v[cand, 2] < z_floor + SHOE_COLLAR]
        _, nn = cKDTree(pv).query(v[inside])
        h = ((pv[nn] - v[inside]) * nrm[inside]).sum(1)
        under[inside] = np.maximum(under[inside], np.clip(h, 0.0, 0.05))
    pv = np.concatenate(verts)
    region = np.flatnonzero(feats.in_groups("foot", "lowerleg"))
    b = bind_points(pv, region, feats, smooth_radius=0.015)
    all_faces = np.concatenate(faces)
    # The binding reproduces the design to within millimetres; re-check that the foot is inside the reconstructed
    # shoe and raise the offsets of the shoe vertices around any foot vertex that is not.
    from scipy.spatial import cKDTree

    w = b.blend_weights.astype(np.float64)[..., None]
    base = (v[b.blend_vertices] * w).sum(1)
    nb = (nrm[b.blend_vertices] * w).sum(1)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    off = b.offset.astype(np.float64)
    feet = feats.in_groups("foot", "lowerleg")
    z_floor = float(v[feats.in_groups("foot"), 2].min())
    inner = v[feet & (v[:, 2] < z_floor + SHOE_COLLAR - 0.01)]
    for _ in range(6):
        pos = base + off[:, None] * nb
        h = surface_clearance(inner, pos, vertex_normals(pos, all_faces), np.arange(len(pos)))
        bad = h > -0.004
        if not bad.any():
            break
        _, nn = cKDTree(pos).query(inner[bad], k=8)
        push = np.zeros(len(pos))
        np.maximum.at(push, nn.ravel(), np.repeat(h[bad] + 0.005, 8))
        # A smooth envelope of the needed lift (max over a 2 cm ball, then its mean over 2.5 cm), so fixing one toe
        # does not print a toe-shaped bump onto the shoe.
        tree = cKDTree(pv)
        env = np.array([push[b].max() for b in tree.query_ball_point(pv, r=0.02)])
        env = np.array([env[b].mean() for b in tree.query_ball_point(pv, r=0.025)])
        off += _same_for_coincident(pv, np.maximum(env, 0.5 * push))  # UV-seam and pole copies stay welded
    b = dataclasses.replace(b, offset=off.astype(np.float32))
    length = float(np.linalg.norm(verts[0][-1] - verts[0][0]))
    return PartGeometry(
        name="shoes",
        faces=all_faces.astype(np.int32),
        uvs=np.concatenate(uvs).astype(np.float32),
        body_vertex=b.body_vertex,
        offset=b.offset,
        uv_layout="own",
        metres_per_uv=max(length, 0.25),
        blend_vertices=b.blend_vertices,
        blend_weights=b.blend_weights,
    )


def shoe_height_map(part: PartGeometry, feats: BodyFeatures, resolution: int) -> np.ndarray:
    """Rest height above the bottom of the shoe (metres) of every texel of the shoes' own layout (H, W) float32,
    row 0 = v 1: where the sole band goes. The layout is a regular grid (u = column / K around the foot, v = row /
    (rows - 1) from heel to toe), so texel heights are a bilinear lookup in the left shoe's grid of vertex heights."""
    from scipy import ndimage

    v, nrm = feats.rest_vertices, feats.rest_normals
    w = part.blend_weights.astype(np.float64)[..., None]
    p = (v[part.blend_vertices] * w).sum(1)
    nb = (nrm[part.blend_vertices] * w).sum(1)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    pos = p + part.offset[:, None].astype(np.float64) * nb
    left = pos[:, 0] > 0
    z = pos[left, 2] - pos[left, 2].min()
    uv = part.uvs[left].astype(np.float64)
    vs, us = np.unique(np.round(uv[:, 1], 6)), np.unique(np.round(uv[:, 0], 6))
    grid = np.full((len(vs), len(us)), np.nan)
    grid[np.searchsorted(vs, np.round(uv[:, 1], 6)), np.searchsorted(us, np.round(uv[:, 0], 6))] = z
    rows_mean = np.nanmean(grid, axis=1, keepdims=True)
    grid = np.where(np.isnan(grid), rows_mean, grid)  # the poles' spare column
    res = int(resolution)
    g = (np.arange(res) + 0.5) / res
    rr = np.interp(1.0 - g, vs, np.arange(len(vs)))
    cc = np.interp(g, us, np.arange(len(us)))
    r2, c2 = np.meshgrid(rr, cc, indexing="ij")
    return ndimage.map_coordinates(grid, [r2, c2], order=1, mode="nearest").astype(np.float32)


def _skirt(feats: BodyFeatures, under: np.ndarray, n_rings: int = 14, n_around: int = 64) -> PartGeometry:
    """A cone from the waist to above the knee: each ring is the convex hull of the hip/thigh cross-section at its
    height (so it bridges the gap between the legs), flaring out towards the hem."""
    v = feats.rest_vertices
    z_waist = 0.5 * (_z(feats, "root") + _z(feats, "spine04")) + 0.01
    z_hip = 0.5 * (_z(feats, "upperleg01.L") + _z(feats, "upperleg01.R"))
    z_knee = 0.5 * (_z(feats, "lowerleg01.L") + _z(feats, "lowerleg01.R"))
    z_hem = z_hip + 0.75 * (z_knee - z_hip)
    centre = feats.bone_heads["root"]
    cand_all = np.flatnonzero(feats.in_groups("torso", "upperleg", "lowerleg"))
    angles = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    ring_idx, ring_w, ring_pos = [], [], []
    ts = np.linspace(0.0, 1.0, n_rings)
    for t in ts:
        zc = z_waist + t * (z_hem - z_waist)
        band = cand_all[np.abs(v[cand_all, 2] - zc) < 0.012]
        idx, w = hull_anchors(v, band, centre, angles)
        ring_idx.append(idx)
        ring_w.append(w)
        ring_pos.append((v[idx] * w[..., None]).sum(1))
    flare = 0.035 + 0.03 * float(np.clip((v[:, 0].max() - v[:, 0].min()) / 1.0 - 0.9, 0.0, 1.0))
    offsets = BASE_OFFSET["skirt"] + flare * ts**1.6
    # Register the skirt's top rings as an inner layer for the tops that hang over it.
    for r in range(n_rings):
        for j in range(2):
            i = ring_idx[r][:, j]
            under[i] = np.maximum(under[i], offsets[r] + 0.004)
    # Grid with a duplicated seam column so u runs 0..1 around (seam at the back, angle 0 = front).
    cols = np.concatenate([np.arange(n_around), [0]])
    circ = float(np.linalg.norm(np.diff(np.vstack([ring_pos[-1], ring_pos[-1][:1]]), axis=0)[:, :2], axis=1).sum())
    length = float(np.linalg.norm(np.diff(np.array([p.mean(0) for p in ring_pos]), axis=0), axis=1).sum()) + 0.05
    bv, bw, uvs, off = [], [], [], []
    for r in range(n_rings):
        for c_i, c in enumerate(cols):
            bv.append(np.pad(ring_idx[r][c], (0, 2)))
            bw.append(np.pad(ring_w[r][c], (0, 2)))
            u = c_i / n_around
            uvs.append((u, (1.0 - ts[r]) * length / circ))
            off.append(offsets[r])
    ncol = n_around + 1
    faces = []
    for r in range(n_rings - 1):
        for c in range(n_around):
            a, b = r * ncol + c, r * ncol + c + 1
            d, e = a + ncol, b + ncol
            # Angles grow from -Y towards +X (clockwise seen from above), rings go down: (a, d, b) faces outwards.
            faces += [(a, b, d), (b, e, d)]
    bv = np.array(bv, dtype=np.int64)
    bw = np.array(bw, dtype=np.float32)
    return PartGeometry(
        name="skirt",
        faces=np.array(faces, dtype=np.int32),
        uvs=np.clip(np.array(uvs, dtype=np.float32), 0.0, 1.0),
        body_vertex=bv[np.arange(len(bv)), np.argmax(bw, axis=1)],
        offset=np.array(off, dtype=np.float32),
        uv_layout="own",
        metres_per_uv=circ,
        blend_vertices=bv,
        blend_weights=bw,
    )


def _draped_piece(kind: str, feats: BodyFeatures, under: np.ndarray, topology: str, phenotype: dict[str, float],
                  drape: str, draped: dict, early: dict, ends: Mapping[str, float] | None,
                  worn: Sequence[str]) -> list[PartGeometry]:
    """One draped piece of a garment (`drape.draped_pieces`) as `build_garments` makes it: the shell over its cloth
    (`SHELL_KINDS_OVER`, its sleeves ending at `ends`), then the cloth, draped over the pieces in `draped` it hangs
    over (or taken from `early`, where it was draped before its turn) and added to `draped`; `under` is raised. Its
    simulation is `drape.piece_settings`' for the garments `worn` (a loose top under an open jacket or a coat is hung
    from under the arms, and its shell not laid over the bust)."""
    st = piece_settings(kind, drape, worn)
    over = draped_over(kind, draped)
    draped[kind] = early.pop(kind, None) or drape_garment(kind, phenotype, st, over=over)
    out = []
    if kind in SHELL_KINDS_OVER:
        # Only the coat's shell can be lifted past its own cloth: over a loose top `under` raises it by the
        # top's cloth, which hangs at the height of the panels' ring. The other shells sit at their TUCK
        # (under LAYER_GAP) below their cloth's ring, with nothing draped under them to lift them.
        shell = SHELL_KINDS_OVER[kind]
        cover = ((run_anny(phenotype)["vertices"], draped[kind].vertices, draped[kind].faces)
                 if shell == "coat" else None)
        hem = shell_hems(kind, phenotype, st) if shell in BRIDGED else shell_hem(kind, phenotype, st)
        out.append(_shell(shell, feats, under, topology, hem=hem, cover=cover, sleeves=ends,
                          bridge=Bridge(phenotype, st, (draped[kind].vertices, draped[kind].faces))
                          if st.over_bust else None))
    part = draped_part(kind, phenotype, feats, under, st, over, draped[kind])
    if kind in LIFT_KINDS:
        # The skin inside the cloth as posing leaves it at rest: pushed out (`push_out`, as pose_character
        # pushes every frame). The drape itself dips up to ~2 mm into the body (the loaded waistband, the
        # crotch); skin it dipped over lay outside it, so was never lifted, and came out through the
        # posed cloth (bench_cloth_pose.py, the straight trousers' deep seated pose: 20 seen -> 1, skinned).
        rest = run_anny(phenotype)["vertices"]
        faces = body_topology().faces
        normals = vertex_normals(rest, faces)
        cloth = push_out(draped[kind].vertices, rest, normals, faces, push_clearance(kind))
        part = dataclasses.replace(part, inside_skin=skin_inside(cloth, draped[kind].faces, rest, normals))
    return out + [part]


def build_garments(
    garments: tuple[Garment, ...],
    feats: BodyFeatures,
    topology: str = ANNY_TOPOLOGY,
    under: np.ndarray | None = None,
    phenotype: dict[str, float] | None = None,
    drape: str = "full",
) -> list[PartGeometry]:
    """Geometry of every garment, innermost first, with layer offsets resolved: one part per garment, but for
    kinds built of several (`garment_parts`: the draped coat's shell and panels).

    `under` (V,) float64, if given, holds per body vertex the outermost offset already used (zeros = bare skin);
    it is updated in place so that hair laid afterwards can stay outside the clothes. `phenotype` is needed by
    draped garments (the cloth simulation runs on the posed body); `drape`: their simulation's level
    (`drape.DRAPE_LEVELS`, `RenderSettings.drape`).
    """
    if under is None:
        under = np.zeros(len(feats.rest_vertices))
    out = []
    draped = {}  # kind -> DrapedGarment of the draped garments built so far (a loose top's drape collides with them)
    early = {}  # kind -> DrapedGarment draped before its turn (the open jacket or coat over a held shell top, below)
    kinds = [g.kind for g in garments]
    for g in garments:
        if g.kind == "skirt":
            out.append(_skirt(feats, under))
        elif g.kind == "shoes":
            out.append(_shoes(feats, under))
        elif g.kind in DRAPED_KINDS:
            if phenotype is None:
                raise ValueError(f"build_garments: {g.kind} needs the phenotype (it is draped on the body)")
            sleeves_kind = _draped_sleeves(g.kind, kinds)
            st_sleeves = None if sleeves_kind is None else drape_settings(sleeves_kind, drape)
            ends = None
            if sleeves_kind is not None:
                # The shell's sleeves end SHELL_OVERLAP under the draped sleeves' pinned rings, inside the cloth.
                tops = sleeve_tops(phenotype, st_sleeves.n_around, SLEEVE_CUTS[sleeves_kind])
                ends = {s: t + SHELL_OVERLAP for s, t in tops.items()}
            for kind in draped_pieces(g.kind):  # the hoodie: its body, then its hood over it
                out.extend(_draped_piece(kind, feats, under, topology, phenotype, drape, draped, early, ends, kinds))
            if sleeves_kind is not None:
                sleeves = drape_garment(sleeves_kind, phenotype, st_sleeves)
                out.append(draped_part(sleeves_kind, phenotype, feats, under, st_sleeves, (), sleeves))
        else:
            outer = next((k for k in SHELLS_UNDER if k in kinds and g.kind in shells_under(k, kinds)), None)
            cover = None
            if outer is not None:
                # A shell top under the open jacket or coat over a draped bottom, lifted over the bottom's waistband:
                # its trunk held LAYER_GAP under the panels at rest (drape.SHELLS_UNDER). The panels are draped now,
                # as at their own turn (over the body and the bottom: nothing draped comes between), and kept for it.
                early[outer] = drape_garment(outer, phenotype, drape_settings(outer, drape),
                                             over=draped_over(outer, draped))
                cover = (run_anny(phenotype)["vertices"], early[outer].vertices, early[outer].faces)
            out.append(_shell(g.kind, feats, under, topology, cover=cover))
    return out
