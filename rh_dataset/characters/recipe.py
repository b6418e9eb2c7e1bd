"""Character recipes: the small, JSON-serialisable description a character is rebuilt from exactly.

In: a recipe's fields, or its JSON. Out: validated `CharacterRecipe` (phenotype, skin, hair, garments, headwear)
and its JSON. A recipe holds every choice; `build_character` turns it into geometry and textures deterministically,
drawing texture noise from `np.random.default_rng([recipe.seed, stream])`. Where recipes come from (the seeded
distribution of benchmark and pretraining characters): `recipe_draws.py`.
"""
from __future__ import annotations

import dataclasses
import json
from typing import Any, ClassVar

import numpy as np

from rh_common.imageio import dumps_json

from .body import PHENOTYPE_LABELS

__all__ = [
    "POOLS",
    "GARMENT_KINDS",
    "DRESSES",
    "UNDER_COAT",
    "UNDER_LOOSE_TOP",
    "OVER_LOOSE_TOP",
    "JACKET_OVER_LOOSE_TOP",
    "COAT_OVER_DRAPED",
    "OUTERWEAR",
    "LOOSE_TOPS",
    "PATTERNS",
    "FABRICS",
    "HAIR_STYLES",
    "HEADWEAR_KINDS",
    "SkinTone",
    "HairSpec",
    "Garment",
    "Headwear",
    "EyeSpec",
    "DEFAULT_IRIS",
    "CharacterRecipe",
    "skin_albedo_linear",
]

RECIPE_FORMAT = "rh-character/1"  # headwear (optional key) kept the format: older recipes read back unchanged
POOLS = ("benchmark", "pretrain")
# draped_skirt, draped_dress, draped_trousers (wide-leg), draped_straight_trousers (their cut with straight legs),
# draped_shorts (loose, the wide trousers' cut above the knee), draped_coat (open, long), draped_jacket (open, to the
# hips): loose garments draped by newton's cloth solver (drape.py). A dress is worn instead of a top and a bottom; the
# coat or the open jacket is the outermost layer, instead of a (shell) jacket, over close-fitting shell bottoms
# (UNDER_COAT), the open jacket also over a draped bottom (JACKET_OVER_LOOSE_TOP), the coat over the loose shorts or
# straight trousers (COAT_OVER_DRAPED); their drape collides with the body and with the loose top's cloth and the skirt
# under them (a shell top is held under them). draped_hoodie: a top, the longsleeve's shoulders over a body of fleece
# hanging loose from under the arms to the hips and a hood draped over it on the upper back, worn without any of
# OUTERWEAR (its hood collides with the body and its own cloth, not with a jacket), over one of UNDER_LOOSE_TOP as a
# loose top is. draped_tshirt: a top, the t-shirt's shoulders and sleeves over a body of cloth hanging loose from under
# the arms to the hips, worn under nothing or one of OVER_LOOSE_TOP (whose drape collides with it), over one of
# UNDER_LOOSE_TOP (its drape collides with the body and with a draped skirt or wide trousers under it);
# draped_longsleeve likewise, the longsleeve's shoulders and sleeves over that cloth. `recipe_from_seed` draws them
# (recipe_draws.py); the shell `skirt` stays a recipe's choice.
GARMENT_KINDS = ("tshirt", "longsleeve", "jacket", "trousers", "shorts", "skirt", "draped_skirt", "draped_dress",
                 "draped_trousers", "shoes", "draped_coat", "draped_hoodie", "draped_jacket", "draped_tshirt",
                 "draped_longsleeve", "draped_shorts", "draped_straight_trousers")
TOPS = ("tshirt", "longsleeve", "draped_hoodie", "draped_tshirt", "draped_longsleeve")
LOOSE_TOPS = ("draped_tshirt", "draped_longsleeve")  # under OVER_LOOSE_TOP or nothing, over one of UNDER_LOOSE_TOP
BOTTOMS = ("trousers", "shorts", "skirt", "draped_skirt", "draped_trousers", "draped_shorts",
           "draped_straight_trousers")
DRESSES = ("draped_dress",)
UNDER_COAT = ("trousers", "shorts")  # the bottoms a draped coat or jacket may be worn over
# The bottoms a loose top may be worn over: the close-fitting shells, and the draped skirt, trousers and loose
# shorts, whose cloth its drape collides with (drape.DRAPED_OVER); not the shell skirt, whose flare its drape would
# hang through.
UNDER_LOOSE_TOP = UNDER_COAT + ("draped_skirt", "draped_trousers", "draped_shorts", "draped_straight_trousers")
# The outerwear a loose top may be worn under: the draped open jacket and coat, whose drape collides with the top's
# cloth (drape.DRAPED_OVER); not the shell jacket, a second skin the top's cloth would hang through.
OVER_LOOSE_TOP = ("draped_jacket", "draped_coat")
# The draped bottoms the open jacket may be worn over (its drape collides with their cloth and a loose top's,
# drape.DRAPED_OVER; a shell top, lifted over the bottom's waistband, showed through the panels until 5 December, and
# is now held under them: drape.SHELLS_UNDER, docs/ARCHITECTURE.md). The open jacket's draw puts it over the wide
# trousers whatever the top (since 5 December afternoon: recipe_draws.JACKET_BOTTOMS), the loose top's over a skirt
# with a loose top under it (`recipe_draws._loose_top`), and the loose bottoms' draws put the shorts and straight
# trousers under it; a shell jacket over a skirt with a shell top stays a shell.
JACKET_OVER_LOOSE_TOP = ("draped_skirt", "draped_trousers", "draped_shorts", "draped_straight_trousers")
# The draped bottoms the coat may be worn over: the loose shorts and straight trousers the draws make of shell ones
# under it (`recipe_draws._loose_bottom`, since 5 December; its drape collides with their cloth, drape.DRAPED_OVER,
# and a shell top is held under its panels, drape.SHELLS_UNDER). Not the skirt or the wide trousers: no draw puts
# the coat over them, and a long coat's hem over their flare is not measured.
COAT_OVER_DRAPED = ("draped_shorts", "draped_straight_trousers")
OUTERWEAR = ("jacket", "draped_jacket", "draped_coat")  # the outermost layers: at most one of them
PATTERNS = ("solid", "stripes", "checks", "noise")
# Fabric finish (how the renderer's sheen lobe and the knit texture treat a garment; character.FABRIC_SHEEN):
# plain = woven (cotton, denim: threads far below the pixel footprint, no sheen), jersey = fine knit (t-shirts),
# knit = a sweater's visible ribs, velvet = a cut pile (strong sheen).
FABRICS = ("plain", "jersey", "knit", "velvet")
HAIR_STYLES = ("buzz", "short", "bob", "long", "long_wavy", "bun", "ponytail")
# Headwear (headwear.py): at most one covering piece (cap, brimmed_hat, headscarf) plus, independently, glasses.
HEADWEAR_KINDS = ("cap", "brimmed_hat", "headscarf", "glasses")
# Innermost first: shoes under trouser hems, bottoms under tops (a shirt hangs over the waistband), jacket outside.
GARMENT_LAYERS = ("shoes", "trousers", "shorts", "skirt", "draped_skirt", "draped_trousers", "draped_shorts",
                  "draped_straight_trousers", "draped_dress", "tshirt", "draped_tshirt", "longsleeve",
                  "draped_longsleeve", "draped_hoodie", "jacket", "draped_jacket", "draped_coat")
COVERINGS = ("cap", "brimmed_hat", "headscarf")


def _check_unit(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number in [0, 1], got {value!r}")
    v = float(value)
    if not (0.0 <= v <= 1.0):
        raise ValueError(f"{name} must be in [0, 1], got {v}")
    return v


def _check_rgb(name: str, value: Any) -> tuple[float, float, float]:
    if not isinstance(value, (tuple, list)) or len(value) != 3:
        raise ValueError(f"{name} must be 3 sRGB values in [0, 1], got {value!r}")
    return tuple(_check_unit(f"{name}[{i}]", c) for i, c in enumerate(value))  # type: ignore[return-value]


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)  # normalising inside a frozen dataclass's __post_init__


# ---------------------------------------------------------------------------------------------------------------
# Skin
# ---------------------------------------------------------------------------------------------------------------
# Anchor swatches of skin reflectance along a melanin axis, sRGB 8-bit (D65). The two middle anchors are measured
# human skin: the "light skin" (194, 150, 130) and "dark skin" (115, 82, 68) patches of the X-Rite/Macbeth
# ColorChecker Classic (McCamy, Marcus & Davidson 1976; sRGB values as tabulated by BabelColor / D. Pascale,
# "RGB coordinates of the Macbeth ColorChecker", 2006). The two end anchors are our own extrapolations along the same
# hue line, chosen so the range spans very light to very dark skin (Fitzpatrick I-VI-like) while staying within
# measured skin albedos (~0.6 linear red at most, a few percent in blue at the darkest).
_SKIN_ANCHORS_T = np.array([0.0, 0.3, 0.7, 1.0])
_SKIN_ANCHORS_SRGB8 = np.array(
    [
        [214, 172, 150],  # our extrapolation: very light
        [194, 150, 130],  # ColorChecker "light skin"
        [115, 82, 68],  # ColorChecker "dark skin"
        [70, 50, 43],  # our extrapolation: very dark
    ],
    dtype=np.float64,
)


@dataclasses.dataclass(frozen=True)
class SkinTone:
    """Skin colour as two pigment-like parameters.

    melanin: 0 = very light, 1 = very dark (interpolates the anchor swatches above in log-linear space).
    redness: haemoglobin-like tint, 0 = sallow/olive, 1 = ruddy; 0.5 leaves the anchor hue unchanged.
    freckles, blush, veins: strength in [0, 1] of the skin detail `textures.skin_detail` paints (freckles on the
    face, shoulders and arms; redder cheeks and nose; the bluish venous network of wrists, forearms, hands and
    temples). 0 paints none, so recipes written before these fields existed keep their textures bit for bit.
    """

    melanin: float
    redness: float = 0.5
    freckles: float = 0.0
    blush: float = 0.0
    veins: float = 0.0

    def __post_init__(self) -> None:
        for name in ("melanin", "redness", "freckles", "blush", "veins"):
            _set(self, name, _check_unit(f"skin.{name}", getattr(self, name)))


def skin_albedo_linear(skin: SkinTone) -> np.ndarray:
    """Mean linear-RGB diffuse albedo of a skin tone (float32 (3,))."""
    from rh_common.colourspace import srgb_decode

    anchors = np.log(np.maximum(srgb_decode(_SKIN_ANCHORS_SRGB8 / 255.0).astype(np.float64), 1e-4))
    log_rgb = np.array([np.interp(skin.melanin, _SKIN_ANCHORS_T, anchors[:, c]) for c in range(3)])
    rgb = np.exp(log_rgb)
    r = skin.redness - 0.5  # haemoglobin absorbs green/blue: a ruddier skin is relatively lower there
    rgb = rgb * np.array([1.0 + 0.10 * r, 1.0 - 0.10 * r, 1.0 - 0.06 * r])
    return np.clip(rgb, 0.01, 0.75).astype(np.float32)


# ---------------------------------------------------------------------------------------------------------------
# Hair and garments
# ---------------------------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class HairSpec:
    """style: buzz (bald-ish stubble), short, bob (chin length), long (straight, past the shoulders), long_wavy, bun,
    ponytail (strands grown by `hair.py`).
    colour: sRGB in [0, 1] (display-referred, as a colour picker gives it)."""

    style: str
    colour: tuple[float, float, float]

    def __post_init__(self) -> None:
        if self.style not in HAIR_STYLES:
            raise ValueError(f"hair.style must be one of {HAIR_STYLES}, got {self.style!r}")
        _set(self, "colour", _check_rgb("hair.colour", self.colour))


def _check_fabric_fields(obj: Any, who: str) -> None:
    """Validate and normalise the fabric-texture fields a Garment and a Headwear share (pattern, colour, colour2,
    period_m, duty, vertical, roughness); `who` names the object in the errors."""
    if obj.pattern not in PATTERNS:
        raise ValueError(f"{who}.pattern must be one of {PATTERNS}, got {obj.pattern!r}")
    _set(obj, "colour", _check_rgb(f"{who}.colour", obj.colour))
    _set(obj, "colour2", _check_rgb(f"{who}.colour2", obj.colour2))
    p = obj.period_m
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not (0.005 <= float(p) <= 0.5):
        raise ValueError(f"{who}.period_m must be in [0.005, 0.5] metres, got {p!r}")
    _set(obj, "period_m", float(p))
    _set(obj, "duty", _check_unit(f"{who}.duty", obj.duty))
    if not isinstance(obj.vertical, bool):
        raise ValueError(f"{who}.vertical must be a bool, got {obj.vertical!r}")
    _set(obj, "roughness", _check_unit(f"{who}.roughness", obj.roughness))


@dataclasses.dataclass(frozen=True)
class Garment:
    """One garment.

    kind: one of GARMENT_KINDS. colour / colour2: sRGB in [0, 1] (colour2 is the second colour of stripes, checks
    and printed noise). pattern: one of PATTERNS. period_m: pattern repeat in metres. duty: fraction of a period in
    colour2 (stripes/checks) or coverage of the print (noise). vertical: stripes run vertically instead of around the
    body. roughness: microfacet roughness in [0, 1] used by the renderer. fabric: one of FABRICS (sheen, knit ribs).
    """

    kind: str
    colour: tuple[float, float, float]
    colour2: tuple[float, float, float] = (1.0, 1.0, 1.0)
    pattern: str = "solid"
    period_m: float = 0.04
    duty: float = 0.5
    vertical: bool = False
    roughness: float = 0.8
    fabric: str = "plain"

    def __post_init__(self) -> None:
        if self.fabric not in FABRICS:
            raise ValueError(f"garment.fabric must be one of {FABRICS}, got {self.fabric!r}")
        if self.kind not in GARMENT_KINDS:
            raise ValueError(f"garment.kind must be one of {GARMENT_KINDS}, got {self.kind!r}")
        _check_fabric_fields(self, "garment")


@dataclasses.dataclass(frozen=True)
class Headwear:
    """One piece of headwear. kind: one of HEADWEAR_KINDS. colour / colour2, pattern, period_m, duty, vertical:
    as `Garment`'s (the fabric texture is drawn the same way; glasses frames are a solid colour). roughness:
    microfacet roughness in [0, 1] (fabric ~0.6-0.9, acetate frames ~0.2-0.35)."""

    kind: str
    colour: tuple[float, float, float]
    colour2: tuple[float, float, float] = (1.0, 1.0, 1.0)
    pattern: str = "solid"
    period_m: float = 0.04
    duty: float = 0.5
    vertical: bool = False
    roughness: float = 0.8
    # Headwear fabric is woven (no sheen, no resolved knit): not drawn, so the headwear stream stays as it was.
    fabric: ClassVar[str] = "plain"

    def __post_init__(self) -> None:
        if self.kind not in HEADWEAR_KINDS:
            raise ValueError(f"headwear.kind must be one of {HEADWEAR_KINDS}, got {self.kind!r}")
        _check_fabric_fields(self, "headwear")


# Eyes (eyes.py): the iris colour. Recipes written before eyes existed have no "eyes" key and read back with
# DEFAULT_IRIS, a medium brown (the commonest iris colour worldwide).
DEFAULT_IRIS = (99 / 255, 60 / 255, 32 / 255)


@dataclasses.dataclass(frozen=True)
class EyeSpec:
    """iris: the iris's colour, sRGB in [0, 1] (its mean; `textures.eye_texture` paints fibres and a darker limbal
    ring around it). Sclera and pupil are drawn by the texture's own stream, not stored."""

    iris: tuple[float, float, float] = DEFAULT_IRIS

    def __post_init__(self) -> None:
        _set(self, "iris", _check_rgb("eyes.iris", self.iris))


# ---------------------------------------------------------------------------------------------------------------
# The recipe
# ---------------------------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class CharacterRecipe:
    """Everything that defines a character. `garments` is ordered from the innermost layer outwards. `headwear`:
    at most one of COVERINGS, then optionally glasses (empty = none; the JSON then has no "headwear" key, so
    recipes written before headwear existed read back unchanged). `eyes`: the iris colour (recipes without it read
    with `EyeSpec()`)."""

    seed: int
    pool: str
    index: int
    phenotype: dict[str, float]
    skin: SkinTone
    hair: HairSpec
    garments: tuple[Garment, ...]
    headwear: tuple[Headwear, ...] = ()
    eyes: EyeSpec = EyeSpec()

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not (0 <= self.seed < 2**63):
            raise ValueError(f"seed must be an int in [0, 2**63), got {self.seed!r}")
        _set(self, "seed", int(self.seed))
        if self.pool not in POOLS:
            raise ValueError(f"pool must be one of {POOLS}, got {self.pool!r}")
        if self.seed % 2 != POOLS.index(self.pool):
            raise ValueError(f"seed {self.seed} does not belong to pool {self.pool!r} (benchmark seeds are even)")
        if isinstance(self.index, bool) or not isinstance(self.index, (int, np.integer)) or self.index < 0:
            raise ValueError(f"index must be a non-negative int, got {self.index!r}")
        _set(self, "index", int(self.index))
        if not isinstance(self.phenotype, dict) or set(self.phenotype) != set(PHENOTYPE_LABELS):
            got = sorted(self.phenotype) if isinstance(self.phenotype, dict) else self.phenotype
            raise ValueError(f"phenotype must have exactly the keys {list(PHENOTYPE_LABELS)}, got {got!r}")
        _set(self, "phenotype", {k: _check_unit(f"phenotype.{k}", self.phenotype[k]) for k in PHENOTYPE_LABELS})
        if not isinstance(self.skin, SkinTone):
            raise ValueError(f"skin must be a SkinTone, got {type(self.skin).__name__}")
        if not isinstance(self.hair, HairSpec):
            raise ValueError(f"hair must be a HairSpec, got {type(self.hair).__name__}")
        garments = tuple(self.garments)
        if not all(isinstance(g, Garment) for g in garments):
            raise ValueError("garments must be Garment instances")
        kinds = [g.kind for g in garments]
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"garments: each kind at most once, got {kinds}")
        dresses = sum(k in DRESSES for k in kinds)
        if dresses > 1 or (dresses and any(k in TOPS + BOTTOMS for k in kinds)):
            raise ValueError(f"garments: a dress ({DRESSES}) is worn alone, without a top or bottom, got {kinds}")
        if not dresses and sum(k in TOPS for k in kinds) != 1:
            raise ValueError(f"garments: exactly one of {TOPS} (or a dress, {DRESSES}) is required, got {kinds}")
        if not dresses and sum(k in BOTTOMS for k in kinds) != 1:
            raise ValueError(f"garments: exactly one of {BOTTOMS} (or a dress, {DRESSES}) is required, got {kinds}")
        outer = [k for k in kinds if k in OUTERWEAR]
        over_draped = ((outer == ["draped_jacket"] and any(k in JACKET_OVER_LOOSE_TOP for k in kinds))
                       or (outer == ["draped_coat"] and any(k in COAT_OVER_DRAPED for k in kinds)))
        if len(outer) > 1 or (outer and outer != ["jacket"] and not any(k in UNDER_COAT for k in kinds)
                              and not over_draped):
            raise ValueError(f"garments: at most one of {OUTERWEAR}, a draped_coat or draped_jacket only over one of "
                             f"{UNDER_COAT} (a draped_jacket also over one of {JACKET_OVER_LOOSE_TOP}, a draped_coat "
                             f"over one of {COAT_OVER_DRAPED}), got {kinds}")
        if "draped_hoodie" in kinds and (outer or not any(k in UNDER_LOOSE_TOP for k in kinds)):
            raise ValueError(f"garments: a draped_hoodie is worn without any of {OUTERWEAR}, over one of "
                             f"{UNDER_LOOSE_TOP}, got {kinds}")
        if any(k in LOOSE_TOPS for k in kinds) and (set(outer) - set(OVER_LOOSE_TOP)
                                                    or not any(k in UNDER_LOOSE_TOP for k in kinds)):
            raise ValueError(f"garments: a loose top {LOOSE_TOPS} is worn under none of {OUTERWEAR} but "
                             f"{OVER_LOOSE_TOP}, over one of {UNDER_LOOSE_TOP}, got {kinds}")
        layered = sorted(kinds, key=GARMENT_LAYERS.index)
        if kinds != layered:
            raise ValueError(f"garments must be listed innermost first, i.e. {layered}, got {kinds}")
        _set(self, "garments", garments)
        headwear = tuple(self.headwear)
        if not all(isinstance(h, Headwear) for h in headwear):
            raise ValueError("headwear must be Headwear instances")
        hk = [h.kind for h in headwear]
        ordered = sorted(hk, key=HEADWEAR_KINDS.index)
        if len(set(hk)) != len(hk) or sum(k in COVERINGS for k in hk) > 1 or hk != ordered:
            raise ValueError(f"headwear: at most one of {COVERINGS}, then optionally glasses, got {hk}")
        _set(self, "headwear", headwear)
        if not isinstance(self.eyes, EyeSpec):
            raise ValueError(f"eyes must be an EyeSpec, got {type(self.eyes).__name__}")

    # JSON -------------------------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        d = {
            "format": RECIPE_FORMAT,
            "seed": self.seed,
            "pool": self.pool,
            "index": self.index,
            "phenotype": dict(self.phenotype),
            "skin": dataclasses.asdict(self.skin),
            "hair": {"style": self.hair.style, "colour": list(self.hair.colour)},
            "garments": [
                {**dataclasses.asdict(g), "colour": list(g.colour), "colour2": list(g.colour2)} for g in self.garments
            ],
        }
        d["eyes"] = {"iris": list(self.eyes.iris)}
        if self.headwear:
            d["headwear"] = [{**dataclasses.asdict(h), "colour": list(h.colour), "colour2": list(h.colour2)}
                             for h in self.headwear]
        return d

    def to_json(self) -> dict[str, Any]:
        """The recipe as a JSON-ready object (what `character.json` holds; `rh_common.imageio.write_json` writes it
        canonically). Floats are kept at full precision, so `from_json` round-trips exactly."""
        return self.to_dict()

    def to_json_text(self) -> str:
        """Canonical JSON text (sorted keys) of `to_json()`."""
        return dumps_json(self.to_dict())

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "CharacterRecipe":
        if not isinstance(d, dict):
            raise ValueError(f"recipe must be a JSON object, got {type(d).__name__}")
        if d.get("format") != RECIPE_FORMAT:
            raise ValueError(f"format must be {RECIPE_FORMAT!r}, got {d.get('format')!r}")
        expected = {"format", "seed", "pool", "index", "phenotype", "skin", "hair", "garments"}
        optional = {"headwear", "eyes"}  # absent = no headwear, EyeSpec()
        if set(d) - optional != expected:
            raise ValueError(f"recipe keys must be {sorted(expected)} (and optionally {sorted(optional)}), got unknown "
                             f"{sorted(set(d) - expected - optional)} missing {sorted(expected - set(d))}")
        try:
            skin = SkinTone(**d["skin"])
        except TypeError as exc:
            raise ValueError(f"skin: {exc}") from exc
        try:
            hair = HairSpec(style=d["hair"]["style"], colour=tuple(d["hair"]["colour"]))
        except (TypeError, KeyError) as exc:
            raise ValueError(f"hair: {exc}") from exc
        garments = []
        for i, g in enumerate(d["garments"]):
            try:
                g = dict(g)
                g["colour"] = tuple(g["colour"])
                g["colour2"] = tuple(g["colour2"])
                garments.append(Garment(**g))
            except (TypeError, KeyError) as exc:
                raise ValueError(f"garments[{i}]: {exc}") from exc
        headwear = []
        for i, h in enumerate(d.get("headwear", [])):
            try:
                h = dict(h)
                h["colour"] = tuple(h["colour"])
                h["colour2"] = tuple(h["colour2"])
                headwear.append(Headwear(**h))
            except (TypeError, KeyError) as exc:
                raise ValueError(f"headwear[{i}]: {exc}") from exc
        eyes = EyeSpec()
        if "eyes" in d:
            try:
                e = dict(d["eyes"])
                e["iris"] = tuple(e["iris"])
                eyes = EyeSpec(**e)
            except (TypeError, KeyError, ValueError) as exc:
                raise ValueError(f"eyes: {exc} (expected {{\"iris\": [r, g, b]}}, sRGB in [0, 1])") from exc
        return cls(seed=d["seed"], pool=d["pool"], index=d["index"], phenotype=dict(d["phenotype"]), skin=skin,
                   hair=hair, garments=tuple(garments), headwear=tuple(headwear), eyes=eyes)

    @classmethod
    def from_json(cls, data: str | dict[str, Any]) -> "CharacterRecipe":
        """Inverse of `to_json` (an object) or of `to_json_text` (a string)."""
        if isinstance(data, str):
            try:
                data = json.loads(data)
            except json.JSONDecodeError as exc:
                raise ValueError(f"recipe: not valid JSON ({exc})") from exc
        return cls.from_dict(data)

    def garment(self, kind: str) -> Garment | None:
        return next((g for g in self.garments if g.kind == kind), None)
