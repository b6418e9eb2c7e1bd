"""Characters: anny bodies with eyeballs, dressed in procedural garments, headwear and strand hair, with
procedural skin, eye and fabric textures.

Public API: recipes (`CharacterRecipe`, `sample_recipe`), `build_character`, `pose_character` (and
`skin_out_count` and `cloth_stretch`, what its "auto" cloth mode weighs), `body_bounds`.
The body model itself is loaded by `rh_common.body_model` (shared with RANA).
"""
from .character import (
    Character,
    CharacterPart,
    CharacterStrands,
    Material,
    PosedMesh,
    PosedStrands,
    body_bounds,
    build_character,
    cloth_stretch,
    mitsuba_texcoords,
    pose_character,
    skin_out_count,
)
from .recipe import (
    FABRICS,
    GARMENT_KINDS,
    HAIR_STYLES,
    HEADWEAR_KINDS,
    PATTERNS,
    POOLS,
    CharacterRecipe,
    EyeSpec,
    Garment,
    HairSpec,
    Headwear,
    SkinTone,
)
from .recipe_draws import derive_seed, recipe_from_seed, sample_recipe

__all__ = [
    "Character",
    "CharacterPart",
    "CharacterStrands",
    "Material",
    "PosedMesh",
    "PosedStrands",
    "body_bounds",
    "build_character",
    "cloth_stretch",
    "mitsuba_texcoords",
    "pose_character",
    "skin_out_count",
    "FABRICS",
    "GARMENT_KINDS",
    "HAIR_STYLES",
    "HEADWEAR_KINDS",
    "PATTERNS",
    "POOLS",
    "CharacterRecipe",
    "EyeSpec",
    "Garment",
    "HairSpec",
    "Headwear",
    "SkinTone",
    "derive_seed",
    "recipe_from_seed",
    "sample_recipe",
]
