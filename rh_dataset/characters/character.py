"""A character = anny body + eyeballs, garments and headwear (textured meshes) + strand hair and brows, each
following the body's skinning.

UV convention: every `uvs` array is v-up (OpenGL): texture row 0 (the top of an albedo array) is v = 1. Mitsuba 3's
`bitmap` texture looks rows up the other way round (row 0 at v = 0, checked by rendering a two-colour quad), so a
Mitsuba mesh must be given texcoords (u, 1 - v) — or the albedo flipped vertically. `mitsuba_texcoords` does it.

Posing: the body is run through anny with the phenotype and the pose; vertex normals are recomputed on the posed
body; each part vertex sits at its anchor (a posed body vertex, or a blend of them) plus `offset` metres along the
anchor's normal. Nothing is simulated per frame, so shell garments fold only where the skin folds, but they follow
every pose. Draped garments (drape.py) are simulated once in the rest pose and then, per frame, either skinned with
the body's linear-blend weights transferred to them or simulated from the rest pose into the frame's
(cloth_pose.py, the `cloth` argument); headwear (headwear.py) is skinned the same way (caps, hats and glasses
rigidly to the head bone, head scarves with the body's weights), and presses or hides the hair under it; the
eyeballs (eyes.py) are rigid with anny's eye joints and, alone among skinned parts, are not pushed off the skin
(they sit in the sockets, inside the head). Hair is
strands (`hair.py`), and so are the brows (`face_hair.py`, of the hair's fibres): every control point is anchored
the same way as a shell vertex, and posing gives `PosedStrands` (control points and radii, one `HairFibre` per set
of strands) beside the `PosedMesh`es. Last, where skin came out through a lifted draped garment, the body's own
mesh (as rendered, not anny's body, which the pose describes) is tucked back under the cloth (`_tuck_skin`).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from rh_common.body_model import ANNY_TOPOLOGY
from rh_common.colourspace import srgb_decode

from rh_dataset.mesh import vertex_normals

from .body import anchor_points, blended_normals, body_topology, run_anny, smoothed_normals
from .garments import (BASE_OFFSET, BRIDGED, LAYER_GAP, LIFT_SMOOTH_ROUNDS, PartGeometry, build_garments, garment_parts,
                       lift_directions, lift_turn, shoe_height_map)
from .body_features import body_features, group_mask
from .cloth_pose import (CLOTH_MODES, INSIDE_NEAR, SIMULATE_ABOVE, SIMULATED_KINDS, STRETCH_KINDS, STRETCHED_ABOVE,
                         TUCK_DEPTH, ClothPoseSettings, layer_depth, lift_over_skin, overstretched, push_over_layers,
                         push_under, simulated_parts, skin_inside, skin_out, tuck_skin)
from .drape import (BOTTOMS_UNDER, DRAPE_LEVELS, DRAPED_KINDS, DRAPED_OVER, LAYER_GAP_DRAPE, SHELL_TOPS, SHELLS_UNDER,
                    DrapeSettings, SkinBinding, penetration, SLEEVE_GROUPS, push_clearance, push_out, shells_under,
                    skin_points)
from .eyes import eye_geometry
from .geometry import split_faces, unique_rows
from .face_hair import build_brows, build_lashes
from .hair import PUSHED_GROUPS, build_hair, push_out_of_body
from .headwear import build_headwear, press_hair
from .hair_fibre import HairFibre, fibres_for_colour
from .recipe import CharacterRecipe
from .textures import body_layout_coords, eye_texture, garment_texture, shoe_sole, skin_texture, texel_positions

__all__ = [
    "Material",
    "CharacterPart",
    "CharacterStrands",
    "Character",
    "PosedMesh",
    "PosedStrands",
    "build_character",
    "pose_character",
    "skin_out_count",
    "body_bounds",
    "mitsuba_texcoords",
    "DEFAULT_TEXTURE_RESOLUTION",
]

DEFAULT_TEXTURE_RESOLUTION = 1024


def _ro(a: np.ndarray, dtype) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=dtype)
    a.setflags(write=False)
    return a


@dataclasses.dataclass(frozen=True)
class Material:
    """albedo: linear float32 (H, W, 3) in [0, 1], row 0 = v 1. roughness: microfacet roughness in [0, 1].
    specular: weight of the specular lobe in [0, 1] (0 = purely Lambertian; 0.5 ~ a dielectric of IOR 1.5, the
    principled-BSDF convention). two_sided: shade back faces too (hems, skirts and hair sheets are seen from inside).
    sheen / sheen_tint: the principled BSDF's cloth sheen lobe (retro-reflection at grazing angles; 0 = none) and
    how much of the albedo's colour it takes. The albedo ground truth stays `albedo`: the sheen is a lobe added on
    top, like the specular one (docs/ARCHITECTURE.md, "Albedo"). clearcoat / clearcoat_gloss: the principled BSDF's
    clear coat (a second, colourless specular layer; 0 = none) and its glossiness (1 = mirror-like): the tear film
    on the eyes. Also not in the albedo.
    """

    albedo: np.ndarray
    roughness: float
    specular: float
    two_sided: bool = True
    sheen: float = 0.0
    sheen_tint: float = 0.5
    clearcoat: float = 0.0
    clearcoat_gloss: float = 0.0

    def __post_init__(self) -> None:
        a = np.asarray(self.albedo)
        if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"Material.albedo must be (H, W, 3), got {a.shape}")
        if not np.all(np.isfinite(a)) or a.min() < 0.0 or a.max() > 1.0:
            raise ValueError("Material.albedo must be finite and within [0, 1]")
        object.__setattr__(self, "albedo", _ro(a, np.float32))
        for name in ("roughness", "specular", "sheen", "sheen_tint", "clearcoat", "clearcoat_gloss"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and 0.0 <= float(v) <= 1.0):
                raise ValueError(f"Material.{name} must be in [0, 1], got {v!r}")
            object.__setattr__(self, name, float(v))


@dataclasses.dataclass(frozen=True)
class CharacterPart:
    """One textured mesh of a character, in split-vertex form (a vertex per (body vertex, UV) pair).

    faces (F, 3) int32 into the split vertices; uvs (V, 2) float32 in [0, 1], v up; body_vertex (V,) int64 the anny
    vertex each split vertex follows; offset (V,) float32 metres along the posed normal. Optional blend_vertices /
    blend_weights (V, K): the anchor is then the weighted sum of those posed body vertices (skirts, hanging hair,
    shells). Optional body_faces (F,) int64: the body face each face lies in (shells cut from the body's surface);
    such a part is shaded with the blended body normals, not its own.
    """

    name: str
    faces: np.ndarray
    uvs: np.ndarray
    body_vertex: np.ndarray
    offset: np.ndarray
    material: Material
    blend_vertices: np.ndarray | None = None
    blend_weights: np.ndarray | None = None
    skinning: SkinBinding | None = None  # draped garments: skinned by anny's bone transforms (drape.py)
    body_faces: np.ndarray | None = None
    # Skinned points are pushed clear of the posed skin (cloth, headwear); eyeballs sit inside the head by design.
    collide: bool = True
    drape: DrapeSettings | None = None  # draped garments: the simulation they were draped with (drape.py)
    inside_skin: np.ndarray | None = None  # draped LIFT_KINDS: body vertices kept under the cloth (cloth_pose.py)
    # (len(inside_skin),) metres: their depths under the cloth as posed at rest (`_with_rest_depths`); with them,
    # posing tucks the rendered skin back under the cloth where it came out through it (`_tuck_skin`).
    inside_depth: np.ndarray | None = None
    # Draped parts: the body vertices inside the cloth as posed at rest (`cloth_pose.skin_inside`; `_with_rest_depths`),
    # lifted or not, whose coming out through the posed cloth the "auto" cloth mode counts (`cloth_pose.skin_out`).
    covered_skin: np.ndarray | None = None

    def __post_init__(self) -> None:
        faces = _ro(self.faces, np.int32)
        uvs = _ro(self.uvs, np.float32)
        bv = _ro(self.body_vertex, np.int64)
        off = _ro(self.offset, np.float32)
        n = len(bv)
        if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= n:
            raise ValueError(f"CharacterPart {self.name}: faces must be (F, 3) indices into {n} vertices")
        if uvs.shape != (n, 2) or uvs.min() < 0.0 or uvs.max() > 1.0:
            raise ValueError(f"CharacterPart {self.name}: uvs must be ({n}, 2) in [0, 1], got {uvs.shape}")
        if off.shape != (n,) or not np.all(np.isfinite(off)) or off.min() < 0.0:
            raise ValueError(f"CharacterPart {self.name}: offset must be ({n},) finite and >= 0")
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "uvs", uvs)
        object.__setattr__(self, "body_vertex", bv)
        object.__setattr__(self, "offset", off)
        if (self.blend_vertices is None) != (self.blend_weights is None):
            raise ValueError(f"CharacterPart {self.name}: blend_vertices and blend_weights go together")
        if self.blend_vertices is not None:
            bvx = _ro(self.blend_vertices, np.int64)
            bw = _ro(self.blend_weights, np.float32)
            if bvx.shape != bw.shape or bvx.ndim != 2 or bvx.shape[0] != n:
                raise ValueError(f"CharacterPart {self.name}: blend arrays must both be ({n}, K)")
            if not np.allclose(bw.sum(1), 1.0, atol=1e-5) or bw.min() < 0:
                raise ValueError(f"CharacterPart {self.name}: blend_weights must be convex (>= 0, rows sum to 1)")
            object.__setattr__(self, "blend_vertices", bvx)
            object.__setattr__(self, "blend_weights", bw)
        if self.skinning is not None:
            sk = self.skinning
            if sk.bind.shape != (n, 3) or sk.bones.shape != sk.weights.shape or sk.bones.shape[0] != n:
                raise ValueError(f"CharacterPart {self.name}: skinning arrays must be ({n}, 3) and ({n}, K)")
            if self.blend_vertices is not None:
                raise ValueError(f"CharacterPart {self.name}: skinning and blend anchors exclude each other")
        if self.body_faces is not None:
            bf = _ro(self.body_faces, np.int64)
            if bf.shape != (len(faces),) or self.blend_vertices is None or bf.min() < 0:
                raise ValueError(f"CharacterPart {self.name}: body_faces must be ({len(faces)},) face indices of a "
                                 "blend-anchored shell")
            object.__setattr__(self, "body_faces", bf)
        for field in ("inside_skin", "covered_skin"):  # body vertex indices of a draped part's skin
            value = getattr(self, field)
            if value is None:
                continue
            idx = _ro(value, np.int64)
            if idx.ndim != 1 or self.skinning is None or (len(idx) and idx.min() < 0):
                raise ValueError(f"CharacterPart {self.name}: {field} must be body vertex indices (N,) of a skinned "
                                 "(draped) part")
            object.__setattr__(self, field, idx)
        if self.inside_depth is not None and (self.inside_skin is None or
                                              np.shape(self.inside_depth) != (len(self.inside_skin),)):
            raise ValueError(f"CharacterPart {self.name}: inside_depth must be one depth per inside_skin vertex")
        if self.inside_depth is not None:
            object.__setattr__(self, "inside_depth", _ro(self.inside_depth, np.float64))


@dataclasses.dataclass(frozen=True)
class CharacterStrands:
    """Hair strands of one fibre: S strands x K control points. radius (S, K) float32 metres; blend_vertices /
    blend_weights (S*K, B) and offset (S*K,): each control point's anchor, as `CharacterPart` blends."""

    name: str
    radius: np.ndarray
    blend_vertices: np.ndarray
    blend_weights: np.ndarray
    offset: np.ndarray
    fibre: HairFibre

    def __post_init__(self) -> None:
        r = _ro(self.radius, np.float32)
        n = r.size
        if r.ndim != 2 or r.shape[1] < 2 or not np.all(r > 0):
            raise ValueError(f"CharacterStrands {self.name}: radius must be (S, K >= 2) and positive")
        bv, bw, off = _ro(self.blend_vertices, np.int32), _ro(self.blend_weights, np.float32), _ro(self.offset,
                                                                                                    np.float32)
        if bv.shape != bw.shape or bv.ndim != 2 or bv.shape[0] != n or off.shape != (n,):
            raise ValueError(f"CharacterStrands {self.name}: blend arrays must be ({n}, B), offset ({n},)")
        if not np.allclose(bw.sum(1), 1.0, atol=1e-5) or bw.min() < 0 or off.min() < 0:
            raise ValueError(f"CharacterStrands {self.name}: blend_weights must be convex, offset >= 0")
        for f, a in (("radius", r), ("blend_vertices", bv), ("blend_weights", bw), ("offset", off)):
            object.__setattr__(self, f, a)


@dataclasses.dataclass(frozen=True)
class Character:
    recipe: CharacterRecipe
    parts: list[CharacterPart]
    phenotype: dict[str, float]
    strands: tuple[CharacterStrands, ...] = ()

    def part(self, name: str) -> CharacterPart:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"character has no part {name!r}; parts: {[p.name for p in self.parts]}")

    @property
    def triangle_count(self) -> int:
        return int(sum(len(p.faces) for p in self.parts))


@dataclasses.dataclass(frozen=True)
class PosedMesh:
    """A posed part in world coordinates: vertices/normals (V, 3) float32 (normals unit), faces (F, 3) int32,
    uvs (V, 2) float32 v-up, and its material."""

    name: str
    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    material: Material


@dataclasses.dataclass(frozen=True)
class PosedStrands:
    """Posed hair strands in world coordinates: points (S, K, 3) float32 control points of cubic B-splines,
    radius (S, K) float32 metres, and their fibre (Mitsuba `hair` BSDF parameters and albedo)."""

    name: str
    points: np.ndarray
    radius: np.ndarray
    fibre: HairFibre

    @property
    def vertices(self) -> np.ndarray:
        """The control points as (S*K, 3), for bounds."""
        return self.points.reshape(-1, 3)


# Skin: a dielectric sheen on a rough surface.
SKIN_ROUGHNESS, SKIN_SPECULAR = 0.5, 0.35
SHOE_SPECULAR = 0.45
FABRIC_SPECULAR = 0.15

# Independent noise streams per texture: np.random.default_rng([seed, stream]).
_STREAM_SKIN, _STREAM_HAIR, _STREAM_SOLE, _STREAM_SKIN_DETAIL, _STREAM_GARMENT0, _STREAM_HEADWEAR0 = 1, 2, 3, 4, 10, 30
_STREAM_EYES = 5
_STREAM_FACE_HAIR = 6  # brows and lashes (face_hair.py)
# The face's hair grown as strands (face_hair.py): the brows. Not the lashes: at the protocol's 4-5 mm a pixel they
# change the image by about the Monte Carlo noise at most (bench/bench_brows.py; docs/SUBJECTS.md, "Eyebrows ...").
FACE_HAIR = ("brows",)
FACE_HAIR_BUILDERS = {"brows": build_brows, "lashes": build_lashes}

# Sheen of each fabric (recipe.FABRICS) for the principled BSDF's sheen lobe: woven cotton and denim have none worth
# the name, a jersey a little, a knit's fibres more, a velvet's pile most (Burley 2012 uses sheen for exactly this).
FABRIC_SHEEN = {"plain": 0.0, "jersey": 0.3, "knit": 0.6, "velvet": 1.0}
# Headwear materials: fabric as garments; glasses frames are polished acetate (a dielectric of IOR ~1.5).
FRAME_SPECULAR = 0.5
# Eyes: a moist base (specular 0.5 ~ IOR 1.5, roughness 0.3) under a full clear coat, the tear film over cornea
# and sclera (IOR 1.34-1.38), nearly mirror-like: the face's sharpest highlight.
EYE_ROUGHNESS, EYE_SPECULAR, EYE_CLEARCOAT, EYE_CLEARCOAT_GLOSS = 0.3, 0.5, 1.0, 0.95

# Shoe soles (linear RGB): white rubber, gum, black rubber; drawn per character, dark uppers favour white soles.
_SOLE_COLOURS = np.array([[0.7, 0.7, 0.66], [0.32, 0.19, 0.09], [0.03, 0.03, 0.03]], dtype=np.float32)
SOLE_HEIGHT = 0.024  # metres above the bottom of the shoe


def _sole_colour(seed: int, upper_srgb: tuple[float, float, float]) -> np.ndarray:
    rng = np.random.default_rng([seed, _STREAM_SOLE])
    light = float(np.mean(upper_srgb)) > 0.55
    p = [0.15, 0.35, 0.5] if light else [0.6, 0.2, 0.2]
    return _SOLE_COLOURS[int(rng.choice(3, p=p))]


def _own_layout_coords(resolution: int, metres_per_uv: float) -> np.ndarray:
    res = int(resolution)
    u = (np.arange(res) + 0.5) / res
    v = 1.0 - (np.arange(res) + 0.5) / res
    uu, vv = np.meshgrid(u, v)
    return (np.stack([uu, vv], axis=-1) * metres_per_uv).astype(np.float32)


def _to_part(geo: PartGeometry, material: Material) -> CharacterPart:
    return CharacterPart(
        name=geo.name,
        faces=geo.faces,
        uvs=geo.uvs,
        body_vertex=geo.body_vertex,
        offset=geo.offset,
        material=material,
        blend_vertices=geo.blend_vertices,
        blend_weights=geo.blend_weights,
        skinning=geo.skinning,
        body_faces=geo.body_faces,
        drape=geo.drape,
        inside_skin=geo.inside_skin,
    )


def build_character(recipe: CharacterRecipe, texture_resolution: int = DEFAULT_TEXTURE_RESOLUTION,
                    drape: str = "full") -> Character:
    """Geometry and textures of a recipe. Deterministic (bit-identical for equal recipes); the last two results are
    cached, keyed by the recipe's canonical JSON. `drape`: how finely draped garments are simulated
    (`drape.DRAPE_LEVELS`; a generated dataset's `RenderSettings.drape`)."""
    if drape not in DRAPE_LEVELS:
        raise ValueError(f"build_character: drape must be one of {DRAPE_LEVELS}, got {drape!r}")
    if not isinstance(recipe, CharacterRecipe):
        raise ValueError(f"build_character: expected a CharacterRecipe, got {type(recipe).__name__}")
    res = int(texture_resolution)
    if not (16 <= res <= 8192):
        raise ValueError(f"build_character: texture_resolution must be in [16, 8192], got {texture_resolution}")
    return _build_cached(recipe.to_json_text(), res, drape)


@functools.lru_cache(maxsize=2)
def _build_cached(recipe_json: str, res: int, drape: str = "full") -> Character:
    recipe = CharacterRecipe.from_json(recipe_json)
    topology = ANNY_TOPOLOGY
    feats = body_features(recipe.phenotype, topology)
    topo = body_topology(topology)
    seed = recipe.seed

    body = split_faces(np.arange(len(topo.faces)), topology)
    positions = texel_positions(feats, res, topology)  # shared by the skin and every body-layout garment
    skin = skin_texture(recipe.skin, recipe.hair.colour, feats, np.random.default_rng([seed, _STREAM_SKIN]), res,
                        topology, positions, detail_rng=np.random.default_rng([seed, _STREAM_SKIN_DETAIL]))
    parts = [
        CharacterPart("body", body.faces, body.uvs, body.body_vertex, np.zeros(len(body.body_vertex), np.float32),
                      Material(skin, SKIN_ROUGHNESS, SKIN_SPECULAR, two_sided=False))
    ]

    under = np.zeros(len(feats.rest_vertices))
    geos = build_garments(recipe.garments, feats, topology, under=under, phenotype=recipe.phenotype, drape=drape)
    body_coords = None
    worn = [g.kind for g in recipe.garments]
    owner = [i for i, g in enumerate(recipe.garments) for _ in garment_parts(g.kind, worn)]  # part -> its garment
    for i, geo in zip(owner, geos):
        g = recipe.garments[i]
        rng = np.random.default_rng([seed, _STREAM_GARMENT0 + i])  # a garment's parts: the same texture draws
        if geo.uv_layout == "body":
            if body_coords is None:
                body_coords = body_layout_coords(feats, res, topology, positions)
            tex = garment_texture(g, rng, res, body_coords)
        else:
            r2 = max(res // 2, 16)
            tex = garment_texture(g, rng, r2, _own_layout_coords(r2, geo.metres_per_uv))
            if g.kind == "shoes":
                tex = shoe_sole(tex, shoe_height_map(geo, feats, r2), SOLE_HEIGHT, _sole_colour(seed, g.colour))
        spec = SHOE_SPECULAR if g.kind == "shoes" else FABRIC_SPECULAR
        parts.append(_to_part(geo, Material(tex, g.roughness, spec, sheen=FABRIC_SHEEN[g.fabric])))

    hats = build_headwear(recipe.headwear, feats, recipe.phenotype, under)
    for i, (h, geo) in enumerate(zip(recipe.headwear, hats)):
        if h.kind == "glasses":
            lin = srgb_decode(np.asarray(h.colour, np.float64))
            mat = Material(np.broadcast_to(lin, (16, 16, 3)).astype(np.float32), h.roughness, FRAME_SPECULAR)
        else:
            r2 = max(res // 4, 16)
            rng = np.random.default_rng([seed, _STREAM_HEADWEAR0 + i])
            mat = Material(garment_texture(h, rng, r2, _own_layout_coords(r2, geo.metres_per_uv)), h.roughness,
                           FABRIC_SPECULAR)
        parts.append(CharacterPart(h.kind, geo.faces, geo.uvs, _nearest_body_vertex(feats, geo.vertices),
                                   np.zeros(len(geo.vertices), np.float32), mat, skinning=geo.skinning))

    eyes = eye_geometry(feats)
    r2 = max(res // 4, 16)
    eye_tex = eye_texture(recipe.eyes.iris, eyes.theta_iris, eyes.theta_pupil,
                          np.random.default_rng([seed, _STREAM_EYES]), r2)
    parts.append(CharacterPart("eyes", eyes.faces, eyes.uvs, _nearest_body_vertex(feats, eyes.vertices),
                               np.zeros(len(eyes.vertices), np.float32),
                               Material(eye_tex, EYE_ROUGHNESS, EYE_SPECULAR, two_sided=False,
                                        clearcoat=EYE_CLEARCOAT, clearcoat_gloss=EYE_CLEARCOAT_GLOSS),
                               skinning=eyes.skinning, collide=False))

    rng = np.random.default_rng([seed, _STREAM_HAIR])
    covers = [g.cover for g in hats if g.cover is not None]
    press = (lambda pts, sc: press_hair(pts, covers, sc)) if covers else None
    hair = build_hair(recipe.hair.style, feats, rng, topology, under=under, press=press)
    fibres = fibres_for_colour(recipe.hair.colour)
    strands = () if hair is None else _split_fibres(hair, fibres, rng)
    # The face's hair (FACE_HAIR) of the scalp hair's fibres, whatever the style or headwear.
    rng = np.random.default_rng([seed, _STREAM_FACE_HAIR])
    for kind in FACE_HAIR:
        strands += _split_fibres(FACE_HAIR_BUILDERS[kind](feats, rng), fibres, rng, kind)
    return _with_rest_depths(Character(recipe=recipe, parts=parts, phenotype=dict(recipe.phenotype),
                                       strands=strands))


def _with_rest_depths(character: Character) -> Character:
    """`character` with each lifted draped part's `inside_depth`: its inside skin's depths under the cloth as
    `pose_character` poses it at rest (after the layers' pushes: a shell top over draped trousers presses their
    waist nearer the skin than the drape lies), which `_tuck_skin` compares a frame's with, so that a rest-pose
    frame tucks nothing; and each draped part's `covered_skin`, the skin inside it as posed at rest (a lifted part's
    `inside_skin`). 0.1 s a character (one rest posing), plus ~0.05 s a draped part that is not lifted."""
    draped = {p.name for p in character.parts if p.skinning is not None and p.name in DRAPED_KINDS}
    if not draped:
        return character
    rest = run_anny(character.phenotype, None)["vertices"]
    normals = vertex_normals(rest, body_topology().faces)
    posed = {m.name: m for m in pose_character(character, None, None)}

    def done(p: CharacterPart) -> CharacterPart:
        if p.name not in draped:
            return p
        cloth = posed[p.name].vertices.astype(np.float64)
        if p.inside_skin is None:
            return dataclasses.replace(p, covered_skin=skin_inside(cloth, p.faces, rest, normals))
        return dataclasses.replace(p, covered_skin=p.inside_skin, inside_depth=layer_depth(
            rest[p.inside_skin], cloth, p.faces, near=INSIDE_NEAR))

    return dataclasses.replace(character, parts=[done(p) for p in character.parts])


def _nearest_body_vertex(feats, points: np.ndarray) -> np.ndarray:
    from scipy.spatial import cKDTree

    return cKDTree(feats.rest_vertices).query(points)[1].astype(np.int64)


def _split_fibres(hair, fibres: tuple[HairFibre, ...], rng: np.random.Generator,
                  name: str = "hair") -> tuple[CharacterStrands, ...]:
    """Deal the strands to the fibres in proportion to their fractions (a random, seeded assignment): one
    `CharacterStrands` per fibre, named `name`, `name`_1, ..."""
    s, k = hair.radius.shape
    order = rng.permutation(s)
    counts = np.round(np.cumsum([f.fraction for f in fibres]) * s).astype(int)
    out, start = [], 0
    for i, (f, end) in enumerate(zip(fibres, counts)):
        idx = np.sort(order[start:end])
        start = end
        if not len(idx):
            continue
        rows = (idx[:, None] * k + np.arange(k)[None, :]).ravel()
        out.append(CharacterStrands(name if i == 0 else f"{name}_{i}", hair.radius[idx], hair.blend_vertices[rows],
                                    hair.blend_weights[rows], hair.offset[rows], f))
    return tuple(out)


def _check_transform(name: str, m: np.ndarray) -> np.ndarray:
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be a finite 4x4 matrix, got shape {m.shape}")
    if not np.allclose(m[3], (0, 0, 0, 1)):
        raise ValueError(f"{name}: last row must be (0, 0, 0, 1)")
    r = m[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-5) or np.linalg.det(r) <= 0:
        raise ValueError(f"{name}: the 3x3 block must be a rotation (rigid transforms only)")
    return m


def _welded_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Normals of a generated part's own surface, averaged across duplicated seam vertices (same position)."""
    inv = unique_rows(np.round(vertices / 1e-6).astype(np.int64))[1]
    welded = vertex_normals(_mean_by(vertices, inv), inv[faces])
    return welded[inv]


def _mean_by(values: np.ndarray, groups: np.ndarray) -> np.ndarray:
    n = groups.max() + 1
    out = np.zeros((n, values.shape[1]))
    np.add.at(out, groups, values)
    return out / np.bincount(groups, minlength=n)[:, None]


def pose_character(
    character: Character,
    bone_deltas: dict[str, np.ndarray] | None = None,
    root_transform: np.ndarray | None = None,
    cloth: str = "skinned",
    cloth_stats: dict | None = None,
    cloth_settings: ClothPoseSettings = ClothPoseSettings(),
    tuck_depth: float = TUCK_DEPTH,
) -> list[PosedMesh | PosedStrands]:
    """Pose every part. `bone_deltas`: bone label -> 4x4 local-ref delta (None or identities = anny's rest A-pose).
    `root_transform`: a rigid world 4x4 applied after skinning (the turntable's rotation about +Z through the
    pelvis). anny's root stays where anny puts it (pelvis at the origin before the pose's root translation).
    `cloth`: how draped garments reach the pose (`cloth_pose.CLOTH_MODES`): "skinned" (linear-blend skinning +
    push_out) or "simulated" (newton's cloth solver while the body moves from the rest pose into this one; its
    penalty contact can leave a vertex pressed a few millimetres into a limb, which push_out then puts back on the
    skin as it does for skinned cloth; `cloth_settings` are its settings) or "auto" (skinned, but simulated where the
    skinned cloth leaves more than `cloth_pose.SIMULATE_ABOVE` skin vertices out through it: `skin_out_count` over the
    parts the simulation poses, `SIMULATED_KINDS`; or where a skinned skirt or dress has more than
    `cloth_pose.STRETCHED_ABOVE` of its edges stretched past `STRETCH_LIMIT`: `cloth_stretch`; the mode taken, the
    count and the share go into `cloth_stats` as "mode", "skin_out" and "stretched"). Either way draped cloth over
    draped cloth (`drape.DRAPED_OVER`: a loose top, an open jacket or coat) is then pushed out over that cloth's posed
    surface (`cloth_pose.push_over_layers`, keeping `drape.LAYER_GAP_DRAPE`). `cloth_stats`, if given, receives the
    simulation's step counts and `depth_before_push_m`: the worst simulated cloth vertex's depth under the skin
    (benches; costs a closest-point query). `tuck_depth`: how far under draped cloth the rendered skin that came
    out through it is put (`cloth_pose.tuck_skin`; 0: not tucked, as bench/skin_seen.py compares). The meshes come
    first, in part order, then one `PosedStrands` per `character.strands`."""
    if cloth == "auto":
        posed = pose_character(character, bone_deltas, root_transform, "skinned", None, cloth_settings, tuck_depth)
        n = skin_out_count(character, posed, SIMULATED_KINDS)
        stretched = cloth_stretch(character, posed, STRETCH_KINDS)
        mode = "simulated" if n > SIMULATE_ABOVE or stretched > STRETCHED_ABOVE else "skinned"
        if cloth_stats is not None:
            cloth_stats.update(mode=mode, skin_out=n, stretched=stretched)
        if mode == "skinned":
            return posed
        return pose_character(character, bone_deltas, root_transform, "simulated", cloth_stats, cloth_settings,
                              tuck_depth)
    topo = body_topology()
    out = run_anny(character.phenotype, bone_deltas)
    verts = out["vertices"]
    normals = vertex_normals(verts, topo.faces)
    if root_transform is not None:
        m = _check_transform("root_transform", root_transform)
        verts = verts @ m[:3, :3].T + m[:3, 3]
        normals = normals @ m[:3, :3].T
    if cloth not in CLOTH_MODES:
        raise ValueError(f"pose_character: cloth must be one of {CLOTH_MODES}, got {cloth!r}")
    if not (np.isfinite(tuck_depth) and tuck_depth >= 0):
        raise ValueError(f"pose_character: tuck_depth must be a depth in metres >= 0, got {tuck_depth!r}")
    simulated = (simulated_parts(character, bone_deltas, cloth_settings, stats=cloth_stats) if cloth == "simulated"
                 else {})
    posed = []
    cloth_under = {}  # draped part name -> (posed vertices, faces): what draped cloth over it is pushed over
    names = [p.name for p in character.parts]
    # A shell top held under an open jacket's or a coat's panels keeps its offset direction when lifted: capped under
    # them at rest and put back under them posed (`_shell_under_panels`), turned it came out through them (seed 0's
    # subject 25, tests/test_shell_under_jacket.py).
    held = {n for k in ("draped_coat", "draped_jacket") if k in names for n in shells_under(k, names)}
    for part in character.parts:
        if part.skinning is not None:
            if part.name in simulated:
                v = simulated[part.name]
            else:
                v = skin_points(part.skinning, out["bone_poses"], out["rest_bone_poses"])
            if root_transform is not None:
                v = v @ m[:3, :3].T + m[:3, 3]
            if part.name in simulated and cloth_stats is not None:
                depth = float(penetration(verts, topo.faces, v).max())
                cloth_stats["depth_before_push_m"] = max(cloth_stats.get("depth_before_push_m", -np.inf), depth)
            if part.collide:
                v = push_out(v, verts, normals, topo.faces, push_clearance(part.name))
                if part.inside_skin is not None:  # skin that came out between the cloth's vertices: lift it over
                    v = lift_over_skin(v, part.faces, part.inside_skin, verts, normals, topo.faces,
                                       push_clearance(part.name))
            inners = [cloth_under[k] for k in DRAPED_OVER.get(part.name, ()) if k in cloth_under]
            if inners:
                v = push_over_layers(v, inners, LAYER_GAP_DRAPE)
            if part.name in DRAPED_KINDS:
                cloth_under[part.name] = (v, part.faces)
            n = _welded_normals(v, part.faces)
        elif part.blend_vertices is None:
            p = verts[part.body_vertex]
            n = normals[part.body_vertex]
            v = p + part.offset[:, None].astype(np.float64) * n
        else:
            v = anchor_points(verts, normals, part.blend_vertices, part.blend_weights, part.offset)
            lifted = None if part.name in held else _lift_weight(part)
            if lifted is not None:
                v = _lifted_shell_points(part, lifted, v, verts, normals)
            if part.body_faces is not None:  # a shell: the body's own (interpolated) normals, as before it was cut
                n = blended_normals(normals, part.blend_vertices, part.blend_weights)
                if lifted is not None and part.name in BRIDGED:  # laid over the bust: its own surface's where lifted
                    n = n + lifted[:, None] * (_welded_normals(v, part.faces) - n)
            else:
                n = _welded_normals(v, part.faces)
        posed.append(
            PosedMesh(
                name=part.name,
                vertices=_ro(v, np.float32),
                normals=_ro(_unit(n), np.float32),
                faces=part.faces,
                uvs=part.uvs,
                material=part.material,
            )
        )
    _tuck_inner_layers(character, posed, cloth_under, verts, normals, topo.faces)
    _shell_under_panels(character, posed, cloth_under, verts, normals, topo.faces)
    _bottoms_under_shell_top(posed, cloth_under, verts, normals, topo.faces)
    if tuck_depth > 0:
        _tuck_skin(character, posed, cloth_under, verts, topo.faces, tuck_depth)
    # Strands are bound, not simulated: an arm swung into hanging hair, or a trunk turned into it, is taken back out
    # of it (`push_out_of_body`).
    below_neck = group_mask(ANNY_TOPOLOGY, *PUSHED_GROUPS)[topo.faces].all(axis=1) if character.strands else None
    for h in character.strands:
        pts = anchor_points(verts, normals, h.blend_vertices, h.blend_weights, h.offset)
        pts = push_out_of_body(pts, verts, normals, topo.faces, below_neck).reshape(*h.radius.shape, 3)
        posed.append(PosedStrands(h.name, _ro(pts, np.float32), h.radius, h.fibre))
    return posed


def skin_out_count(character: Character, posed: list, parts: tuple[str, ...] | None = None) -> int:
    """How many body vertices inside a draped part at rest (its `covered_skin`) lie out through its posed cloth in
    `posed` (`pose_character`'s meshes: the body as rendered, after the tuck; `cloth_pose.skin_out`, a lifted part's
    skin only where farther out than at rest), over the draped parts named in `parts` (None: all). The "auto" cloth
    mode weighs the parts its simulation poses (`cloth_pose.SIMULATED_KINDS`): skin out through a draped sleeve,
    skinned in every mode, would stay out simulated (a forearm pressed into its sleeve by crossed arms)."""
    meshes = {m.name: m for m in posed if isinstance(m, PosedMesh)}
    body = character.part("body")
    # The rendered body's vertices are anny's with the seams split: any copy of a vertex has its position.
    anny = np.zeros((int(body.body_vertex.max()) + 1, 3))
    anny[body.body_vertex] = meshes["body"].vertices
    out = np.zeros(len(anny), bool)
    for part in character.parts:
        if (part.covered_skin is None or not len(part.covered_skin) or part.name not in meshes
                or (parts is not None and part.name not in parts)):
            continue
        out[part.covered_skin] |= skin_out(anny[part.covered_skin], meshes[part.name].vertices, part.faces,
                                           part.inside_depth)
    return int(out.sum())


def cloth_stretch(character: Character, posed: list, parts: tuple[str, ...] | None = None) -> float:
    """The largest share of a draped part's edges stretched past `cloth_pose.STRETCH_LIMIT` in `posed`
    (`pose_character`'s meshes) against its drape (`cloth_pose.overstretched` against the part's skinning bind),
    over the draped parts named in `parts` (None: all); 0 if none is worn. The "auto" cloth mode weighs the skirts
    and dresses (`cloth_pose.STRETCH_KINDS`): skinned, a sitting frame pulls them taut between the thighs."""
    meshes = {m.name: m for m in posed if isinstance(m, PosedMesh)}
    return max((overstretched(p.skinning.bind, meshes[p.name].vertices, p.faces) for p in character.parts
                if p.skinning is not None and p.name in DRAPED_KINDS and p.name in meshes
                and (parts is None or p.name in parts)), default=0.0)


def _tuck_skin(character: Character, posed: list, cloth_under: dict, verts: np.ndarray, faces: np.ndarray,
               depth: float) -> None:
    """In place: the body's render mesh with the skin inside each lifted draped part (`inside_skin`, with its rest
    depths `inside_depth`) tucked back `depth` under its posed cloth where it came out through it
    (`cloth_pose.tuck_skin`), its normals recomputed. Only the rendered body moves: the cloth was posed, and the
    hair and shells anchored, on anny's posed body (`verts`), which the frame's pose and every fit and export keep.
    Where no skin came out farther than at rest (a rest-pose frame), nothing changes."""
    tucked = None
    for part in character.parts:
        if part.inside_depth is None or part.name not in cloth_under:
            continue
        w, moved = tuck_skin((verts if tucked is None else tucked)[part.inside_skin], part.inside_depth,
                             *cloth_under[part.name], depth=depth)
        if len(moved):
            tucked = verts.copy() if tucked is None else tucked
            tucked[part.inside_skin[moved]] = w[moved]
    if tucked is None:
        return
    at, body = next((j, p) for j, p in enumerate(character.parts) if p.name == "body")
    # The body's mesh comes first among the posed meshes, in part order; its vertices are anny's, seams split.
    n = vertex_normals(tucked, faces)
    posed[at] = dataclasses.replace(posed[at], vertices=_ro(tucked[body.body_vertex], np.float32),
                                    normals=_ro(_unit(n[body.body_vertex]), np.float32))


def _lift_weight(part: CharacterPart) -> np.ndarray | None:
    """(V,) how far each shell vertex's offset direction turns to the smoothed normals, and a shell laid over the
    bust (garments.BRIDGED) its shading to its own surface (0..1; garments.lift_turn), or None where none does (not
    a shell, or no vertex lifted)."""
    if part.body_faces is None or part.blend_vertices is None or part.name not in BASE_OFFSET:
        return None
    turn = lift_turn(part.name, part.offset)
    return turn if (turn > 0).any() else None


def _lifted_shell_points(part: CharacterPart, lifted: np.ndarray, points: np.ndarray, verts: np.ndarray,
                         normals: np.ndarray) -> np.ndarray:
    """The shell's posed points (`points`: along the body's own normals) with each lifted vertex's offset direction
    turned by `lifted` to the smoothed normals (garments.LIFT_SMOOTH_ROUNDS)."""
    sel = np.flatnonzero(lifted > 0)
    bv, bw = part.blend_vertices[sel], part.blend_weights[sel]
    even = blended_normals(smoothed_normals(normals, LIFT_SMOOTH_ROUNDS), bv, bw)
    direction = lift_directions(blended_normals(normals, bv, bw), even, lifted[sel])
    out = points.copy()
    out[sel] = (verts[bv] * bw.astype(np.float64)[..., None]).sum(1) + part.offset[sel, None] * direction
    return out


def _unit(n: np.ndarray) -> np.ndarray:
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return n / np.linalg.norm(n, axis=1, keepdims=True)  # second pass: unit length to float32 precision


# Draped layers nothing is tucked under (`_tuck_inner_layers`): the hoodie's hood, a bag laid back whose faces point
# out of the bag, so the sheet lying on the back faces the body's cloth under it. `push_under` takes what lies on a
# layer's outward side within LAYER_REACH for cloth come out through it: on seed 0's subjects 13 and 28 at rest
# (6 December, bench/bench_cloth_layers.py --subjects 13,28 --through) 30-40 of the body's vertices under the hood's
# back sheet, which it moved up to the hood, and the hood's nearest vertex over that cloth came from 12.9 mm to
# 3.2 mm. `push_over_layers` (the hood over the body's cloth, by that cloth's outward normals) keeps the hood on top.
TUCK_UNDER_NOT = ("draped_hoodie",)


def _tuck_inner_layers(character: Character, posed: list, cloth_under: dict, verts, normals, faces) -> None:
    """In place: draped cloth under draped cloth put back under it where it came out through it. `push_over_layers`
    moves only the outer layer's vertices, and the cloth under it can still pass out between them: the wide
    trousers' folds over an open jacket's hem on a sitting lap, a skirt over the jacket where a thigh is raised. For
    each outer layer, outermost first, each cloth it is draped over (`DRAPED_OVER`) goes under it where it lies over
    it (`cloth_pose.push_under`: within reach, not beyond its open edges), LAYER_GAP_DRAPE per layer between them
    (the innermost deepest), then out of the skin where that took it in (the skin wins). Then each outer layer over
    cloth that moved is pushed over it again (`push_over_layers`, innermost first), so that it stays on top where
    the skin won. Outermost first: a tucked cloth is then tucked under the cloth over it in turn. Pool recipe 4 of
    seed 0 bending and sitting: the trousers' vertices a camera sees over its open jacket 31-39 -> 0-2 a frame, for
    about 1 s more posing (1.6-1.9 -> 2.6-3.0 s at load ~1; bench/bench_cloth_layers.py --through, with and without
    --no-tuck; ARCHITECTURE, "Cloth under the top out through it"). `posed` meshes (vertices and normals) and
    `cloth_under` entries are replaced where they moved; where nothing came through, nothing changes."""
    outers = [p for p in character.parts if p.name in cloth_under and p.name not in TUCK_UNDER_NOT and
              any(k in cloth_under for k in DRAPED_OVER.get(p.name, ()))]
    before = {k: v for k, (v, _) in cloth_under.items()}
    for part in reversed(outers):
        names = [k for k in DRAPED_OVER[part.name] if k in cloth_under]
        for i, k in enumerate(names):
            w, moved = push_under(cloth_under[k][0], cloth_under[part.name][0], part.faces,
                                  LAYER_GAP_DRAPE * (len(names) - i))
            if len(moved):
                w[moved] = push_out(w[moved], verts, normals, faces, push_clearance(k))
                cloth_under[k] = (w, cloth_under[k][1])
    for part in outers:
        names = [k for k in DRAPED_OVER[part.name] if k in cloth_under]
        if any(cloth_under[k][0] is not before[k] for k in names):
            cloth_under[part.name] = (push_over_layers(cloth_under[part.name][0], [cloth_under[k] for k in names],
                                                       LAYER_GAP_DRAPE), part.faces)
    for k, (v, f) in cloth_under.items():
        if v is not before[k]:
            at = next(j for j, m in enumerate(posed) if m.name == k)
            posed[at] = dataclasses.replace(posed[at], vertices=_ro(v, np.float32),
                                            normals=_ro(_unit(_welded_normals(v, f)), np.float32))


def _shell_under_panels(character: Character, posed: list, cloth_under: dict, verts, normals, faces) -> None:
    """In place: the coat's (or open jacket's) shell, posed on the skin, put back LAYER_GAP under its draped panels
    where its trunk came out through them (`cloth_pose.push_under`), then out of the skin where that took it in (an
    arm pressing the panel against the trunk leaves no room: the skin wins, the panel hides the rest). Only the
    trunk's vertices (bone group "torso", by each vertex's nearer body vertex): a sleeve beside a panel is outside it
    by right. At rest the trunk lies under the panels already (`garments._under_cover`). Likewise a shell top under
    the open jacket or coat over a draped bottom (`drape.SHELLS_UNDER`; all of it but its sleeves,
    `drape.SLEEVE_GROUPS`), 2 LAYER_GAP under them, so that where it reaches up under the coat's shell it stays under
    that too; it is capped under them at rest the same way."""
    kind = next((k for k in ("draped_coat", "draped_jacket") if k in cloth_under), None)
    if kind is None:
        return
    panels = cloth_under[kind]
    names = [p.name for p in character.parts]
    for name in ("coat",) + shells_under(kind, names):
        at = next((i for i, m in enumerate(posed) if m.name == name), None)
        if at is None:
            continue
        held = (group_mask(ANNY_TOPOLOGY, "torso") if name == "coat" else ~group_mask(ANNY_TOPOLOGY, *SLEEVE_GROUPS))
        _tuck_shell(posed, at, character.part(name), held, panels, LAYER_GAP * (1 if name == "coat" else 2),
                    verts, normals, faces)
    sleeves = cloth_under.get("draped_coat_sleeves")
    if sleeves is not None:
        _top_under_coat_sleeves(character, posed, sleeves, verts, normals, faces)


# The shells whose sleeves lie under the open coat's draped sleeves: the coat's own (its sleeves cut short, ending
# inside the cloth's pinned rings) and a top's worn under it (the loose tops' shells keep their sleeves there:
# garments.SLEEVES_UNDER_NOT).
TOPS_UNDER_COAT_SLEEVES = ("coat",) + SHELL_TOPS + ("tee", "longtop")


def _top_under_coat_sleeves(character: Character, posed: list, sleeves, verts, normals, faces) -> None:
    """In place: the shell sleeves under the open coat's draped sleeves (`TOPS_UNDER_COAT_SLEEVES`: the coat's own
    and the top's under it; their vertices on the arms, `drape.SLEEVE_GROUPS`) put back LAYER_GAP under them
    (`sleeves`: their posed (vertices, faces)) where they came out through them, then out of the skin where that took
    them in (the skin wins). The draped sleeves are skinned to the arm's bones alone and the shells are anchored to
    the skin: at a bent elbow the skin's crease carried the top's sleeve up to 19 mm out through the cloth
    (bench/bench_sleeves.py --kind draped_coat_sleeves), and with a raised arm the coat's 17 mm shell came 12.6 mm
    out by the armpit (tests/test_sleeves.py)."""
    arm = group_mask(ANNY_TOPOLOGY, *SLEEVE_GROUPS)
    for at, m in enumerate(posed):
        if m.name in TOPS_UNDER_COAT_SLEEVES:
            _tuck_shell(posed, at, character.part(m.name), arm, sleeves, LAYER_GAP, verts, normals, faces)


def _tuck_shell(posed: list, at: int, part: CharacterPart, held: np.ndarray, cloth, gap: float, verts, normals,
                faces) -> None:
    """In place: the vertices of `posed[at]` (the shell `part`) whose nearer body vertex is `held` (a mask over the
    body's vertices) put `gap` under `cloth` ((vertices, faces) posed) where they came out through it
    (`cloth_pose.push_under`), then out of the skin where that took them in (the skin wins)."""
    nearer = (part.body_vertex if part.blend_vertices is None else
              part.blend_vertices[np.arange(len(part.blend_vertices)), np.argmax(part.blend_weights, axis=1)])
    sel = np.flatnonzero(held[nearer])
    v = posed[at].vertices.astype(np.float64)
    w, moved = push_under(v[sel], *cloth, gap)
    if not len(moved):
        return
    moved = sel[moved]
    v[sel] = w
    v[moved] = push_out(v[moved], verts, normals, faces)
    posed[at] = dataclasses.replace(posed[at], vertices=_ro(v, np.float32))


def _bottoms_under_shell_top(posed: list, cloth_under: dict, verts, normals, faces) -> None:
    """In place: a draped bottom (`drape.BOTTOMS_UNDER`) put back LAYER_GAP_DRAPE under the shell top worn over it
    (`drape.SHELL_TOPS`) where it came out through the top (`cloth_pose.push_under`: within reach, not beyond the
    top's hem or cuffs), then out of the skin where that took it in (the skin wins). Skipped under a draped jacket or
    coat, which holds the top under its panels (`_shell_under_panels`). Where nothing came through, nothing
    changes."""
    if any(k in cloth_under for k in SHELLS_UNDER):
        return
    tops = [m for m in posed if m.name in SHELL_TOPS]
    for k in (k for k in BOTTOMS_UNDER if k in cloth_under):
        v, f = cloth_under[k]
        for top in tops:
            w, moved = push_under(v, top.vertices, top.faces, LAYER_GAP_DRAPE)
            if len(moved):
                w[moved] = push_out(w[moved], verts, normals, faces, push_clearance(k))
                v = w
        if v is not cloth_under[k][0]:
            cloth_under[k] = (v, f)
            at = next(j for j, m in enumerate(posed) if m.name == k)
            posed[at] = dataclasses.replace(posed[at], vertices=_ro(v, np.float32),
                                            normals=_ro(_unit(_welded_normals(v, f)), np.float32))


def body_bounds(posed_meshes: list[PosedMesh | PosedStrands]) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (min (3,), max (3,)) of all posed parts, float64."""
    if not posed_meshes:
        raise ValueError("body_bounds: no meshes")
    allv = np.concatenate([m.vertices for m in posed_meshes]).astype(np.float64)
    return allv.min(axis=0), allv.max(axis=0)


def mitsuba_texcoords(uvs: np.ndarray) -> np.ndarray:
    """v-up UVs to what Mitsuba's `bitmap` texture expects for an albedo array stored row 0 = top: (u, 1 - v)."""
    uvs = np.asarray(uvs, dtype=np.float32)
    return np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)
