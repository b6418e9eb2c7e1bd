"""Character recipes: the small, JSON-serialisable description a character is rebuilt from exactly.

A recipe holds every choice (phenotype, skin, hair, garments); `build_character` turns it into geometry and textures
deterministically, drawing texture noise from `np.random.default_rng([recipe.seed, stream])`.

Benchmark and pretraining characters are disjoint by construction: a recipe's seed is even for the benchmark pool
and odd for the pretraining pool (see `derive_seed`), and everything random in a character is drawn from its seed.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from typing import Any, ClassVar

import numpy as np

from rh_common.imageio import dumps_json

from .body import PHENOTYPE_LABELS, sample_phenotype

__all__ = [
    "POOLS",
    "GARMENT_KINDS",
    "PATTERNS",
    "FABRICS",
    "HAIR_STYLES",
    "HAIR_COLOUR_NAMES",
    "hair_colour_name",
    "HEADWEAR_KINDS",
    "SkinTone",
    "HairSpec",
    "Garment",
    "Headwear",
    "CharacterRecipe",
    "derive_seed",
    "sample_recipe",
    "recipe_from_seed",
    "sample_headwear",
    "skin_albedo_linear",
]

RECIPE_FORMAT = "rh-character/1"  # headwear (optional key) kept the format: older recipes read back unchanged
POOLS = ("benchmark", "pretrain")
# draped_skirt: a loose skirt draped by newton's cloth solver (drape.py); never drawn by `recipe_from_seed` (off by
# default, so generated datasets keep their bytes), chosen by editing a recipe.
GARMENT_KINDS = ("tshirt", "longsleeve", "jacket", "trousers", "shorts", "skirt", "draped_skirt", "shoes")
TOPS = ("tshirt", "longsleeve")
BOTTOMS = ("trousers", "shorts", "skirt", "draped_skirt")
_SAMPLED_BOTTOMS = ("trousers", "shorts", "skirt")  # what recipe_from_seed draws from (its stream unchanged)
PATTERNS = ("solid", "stripes", "checks", "noise")
# Fabric finish (how the renderer's sheen lobe and the knit texture treat a garment; character.FABRIC_SHEEN):
# plain = woven (cotton, denim: threads far below the pixel footprint, no sheen), jersey = fine knit (t-shirts),
# knit = a sweater's visible ribs, velvet = a cut pile (strong sheen).
FABRICS = ("plain", "jersey", "knit", "velvet")
HAIR_STYLES = ("buzz", "short", "bob", "long", "long_wavy", "bun", "ponytail")
# Headwear (headwear.py): at most one covering piece (cap, brimmed_hat, headscarf) plus, independently, glasses.
HEADWEAR_KINDS = ("cap", "brimmed_hat", "headscarf", "glasses")
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
        if self.pattern not in PATTERNS:
            raise ValueError(f"garment.pattern must be one of {PATTERNS}, got {self.pattern!r}")
        _set(self, "colour", _check_rgb("garment.colour", self.colour))
        _set(self, "colour2", _check_rgb("garment.colour2", self.colour2))
        p = self.period_m
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not (0.005 <= float(p) <= 0.5):
            raise ValueError(f"garment.period_m must be in [0.005, 0.5] metres, got {p!r}")
        _set(self, "period_m", float(p))
        _set(self, "duty", _check_unit("garment.duty", self.duty))
        if not isinstance(self.vertical, bool):
            raise ValueError(f"garment.vertical must be a bool, got {self.vertical!r}")
        _set(self, "roughness", _check_unit("garment.roughness", self.roughness))


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
        if self.pattern not in PATTERNS:
            raise ValueError(f"headwear.pattern must be one of {PATTERNS}, got {self.pattern!r}")
        _set(self, "colour", _check_rgb("headwear.colour", self.colour))
        _set(self, "colour2", _check_rgb("headwear.colour2", self.colour2))
        p = self.period_m
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not (0.005 <= float(p) <= 0.5):
            raise ValueError(f"headwear.period_m must be in [0.005, 0.5] metres, got {p!r}")
        _set(self, "period_m", float(p))
        _set(self, "duty", _check_unit("headwear.duty", self.duty))
        if not isinstance(self.vertical, bool):
            raise ValueError(f"headwear.vertical must be a bool, got {self.vertical!r}")
        _set(self, "roughness", _check_unit("headwear.roughness", self.roughness))


# ---------------------------------------------------------------------------------------------------------------
# The recipe
# ---------------------------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class CharacterRecipe:
    """Everything that defines a character. `garments` is ordered from the innermost layer outwards. `headwear`:
    at most one of COVERINGS, then optionally glasses (empty = none; the JSON then has no "headwear" key, so
    recipes written before headwear existed read back unchanged)."""

    seed: int
    pool: str
    index: int
    phenotype: dict[str, float]
    skin: SkinTone
    hair: HairSpec
    garments: tuple[Garment, ...]
    headwear: tuple[Headwear, ...] = ()

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
        if sum(k in TOPS for k in kinds) != 1:
            raise ValueError(f"garments: exactly one of {TOPS} is required, got {kinds}")
        if sum(k in BOTTOMS for k in kinds) != 1:
            raise ValueError(f"garments: exactly one of {BOTTOMS} is required, got {kinds}")
        layered = sorted(kinds, key=_LAYER.index)
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
        if set(d) - {"headwear"} != expected:  # headwear is optional (absent = none)
            raise ValueError(f"recipe keys must be {sorted(expected)} (and optionally headwear), got unknown "
                             f"{sorted(set(d) - expected - {'headwear'})} missing {sorted(expected - set(d))}")
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
        return cls(seed=d["seed"], pool=d["pool"], index=d["index"], phenotype=dict(d["phenotype"]), skin=skin,
                   hair=hair, garments=tuple(garments), headwear=tuple(headwear))

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


# Innermost first: shoes under trouser hems, bottoms under tops (a shirt hangs over the waistband), jacket outside.
_LAYER = ("shoes", "trousers", "shorts", "skirt", "draped_skirt", "tshirt", "longsleeve", "jacket")


def derive_seed(pool: str, index: int, base: int) -> int:
    """A 63-bit seed from (pool, index, base): even for "benchmark", odd for "pretrain", so the two pools' seeds
    (and hence their characters) never coincide whatever the base seeds."""
    if pool not in POOLS:
        raise ValueError(f"pool must be one of {POOLS}, got {pool!r}")
    h = hashlib.sha256(f"rh-character/{pool}/{int(index)}/{int(base)}".encode()).digest()
    return ((int.from_bytes(h[:8], "little") >> 2) << 1) | POOLS.index(pool)


def sample_recipe(rng: np.random.Generator, pool: str, index: int) -> CharacterRecipe:
    """Draw one base seed from `rng`, derive the character's seed from (pool, index, base) and build the recipe
    from that seed alone (so a recipe is reproducible from its seed, pool and index)."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy Generator, got {type(rng).__name__}")
    base = int(rng.integers(0, 2**62))
    return recipe_from_seed(derive_seed(pool, index, base), pool, index)


# Garment colour palette, sRGB 8-bit: common clothing colours picked by us (navy, black, white, heather grey, denim,
# olive, khaki, burgundy, red, mustard, teal, pink, cream, brown, forest green, sky blue).
_GARMENT_PALETTE = np.array(
    [
        [31, 40, 72], [25, 25, 28], [232, 232, 228], [150, 150, 152], [62, 84, 120], [90, 96, 58], [190, 170, 130],
        [110, 28, 40], [178, 34, 40], [214, 160, 40], [20, 110, 118], [226, 150, 170], [236, 226, 200],
        [100, 66, 40], [30, 80, 50], [130, 175, 215],
    ],
    dtype=np.float64,
) / 255.0
_BOTTOM_PALETTE = np.array(
    [[45, 62, 96], [70, 92, 128], [28, 28, 30], [70, 70, 72], [180, 160, 120], [90, 78, 60], [40, 50, 40]],
    dtype=np.float64,
) / 255.0  # denim dark/mid, black, charcoal, khaki, brown, dark olive
_SHOE_PALETTE = np.array(
    [[20, 20, 20], [235, 235, 235], [90, 55, 30], [60, 60, 64], [150, 40, 40], [40, 50, 90]], dtype=np.float64
) / 255.0
# Hair colours, sRGB 8-bit, picked by us: black, dark brown, brown, light brown, dark blonde, blonde, auburn, grey.
_HAIR_PALETTE = np.array(
    [[20, 16, 14], [45, 30, 22], [80, 54, 36], [120, 86, 56], [160, 124, 80], [205, 170, 110], [130, 60, 32],
     [170, 168, 165]],
    dtype=np.float64,
) / 255.0


HAIR_COLOUR_NAMES = ("black", "dark brown", "brown", "light brown", "dark blonde", "blonde", "auburn", "grey")


def hair_colour_name(rgb: tuple[float, float, float]) -> str:
    """The palette colour (HAIR_COLOUR_NAMES) a hair colour was drawn from: the nearest in sRGB (the jitter is
    mostly a brightness change of a few percent, smaller than the palette's steps)."""
    d = np.linalg.norm(_HAIR_PALETTE - np.asarray(rgb, dtype=np.float64), axis=1)
    return HAIR_COLOUR_NAMES[int(np.argmin(d))]


def _jitter(rng: np.random.Generator, rgb: np.ndarray, amount: float) -> tuple[float, float, float]:
    """Mostly a brightness change, a little hue change: independent per-channel jitter turns khaki into pink."""
    factor = (1.0 + rng.normal(0.0, amount)) * (1.0 + rng.normal(0.0, 0.25 * amount, 3))
    return tuple(float(c) for c in np.clip(rgb * factor, 0.0, 1.0))


def _sample_garment(rng: np.random.Generator, kind: str) -> Garment:
    if kind == "shoes":
        return Garment(kind, _jitter(rng, _SHOE_PALETTE[rng.integers(len(_SHOE_PALETTE))], 0.05),
                       roughness=float(rng.uniform(0.35, 0.7)))
    palette = _BOTTOM_PALETTE if kind in ("trousers", "shorts") else _GARMENT_PALETTE
    c1 = palette[rng.integers(len(palette))]
    c2 = _GARMENT_PALETTE[rng.integers(len(_GARMENT_PALETTE))]
    if kind in ("trousers", "shorts"):
        pattern = rng.choice(["solid", "noise", "checks"], p=[0.75, 0.17, 0.08])
    elif kind == "jacket":
        pattern = rng.choice(["solid", "noise", "checks"], p=[0.75, 0.1, 0.15])
    else:
        pattern = rng.choice(list(PATTERNS), p=[0.4, 0.3, 0.15, 0.15])
    period = {"solid": 0.05, "stripes": rng.uniform(0.015, 0.08), "checks": rng.uniform(0.02, 0.09),
              "noise": rng.uniform(0.03, 0.15)}[str(pattern)]
    return Garment(
        kind=kind,
        colour=_jitter(rng, c1, 0.08),
        colour2=_jitter(rng, c2, 0.08),
        pattern=str(pattern),
        period_m=float(period),
        duty=float(rng.uniform(0.25, 0.55)),
        vertical=bool(rng.random() < 0.2),
        roughness=float(rng.uniform(0.55, 0.95) if kind != "jacket" else rng.uniform(0.4, 0.85)),
    )


def recipe_from_seed(seed: int, pool: str, index: int) -> CharacterRecipe:
    """The recipe a seed stands for (deterministic)."""
    rng = np.random.default_rng(int(seed))
    phenotype = sample_phenotype(rng)
    female = phenotype["gender"] > 0.5
    skin = SkinTone(melanin=float(rng.uniform(0.0, 1.0)), redness=float(rng.uniform(0.2, 0.8)))

    if female:
        style = rng.choice(HAIR_STYLES, p=[0.02, 0.16, 0.2, 0.2, 0.12, 0.15, 0.15])
    else:
        style = rng.choice(HAIR_STYLES, p=[0.22, 0.58, 0.06, 0.04, 0.04, 0.02, 0.04])
    # Darker skin makes dark hair more likely; older adults may be grey (anny age 0.82 ~ 55 years).
    w = np.array([1.0, 1.5, 1.2, 0.8, 0.5, 0.4, 0.3, 0.0])
    w[:2] += 3.0 * skin.melanin
    w[4:6] *= 1.0 - skin.melanin
    if phenotype["age"] > 0.82:
        w[7] = 2.0
    hair_rgb = _HAIR_PALETTE[rng.choice(len(w), p=w / w.sum())]
    hair = HairSpec(style=str(style), colour=_jitter(rng, hair_rgb, 0.08))

    top = "tshirt" if rng.random() < 0.5 else "longsleeve"
    bottom = rng.choice(_SAMPLED_BOTTOMS, p=[0.45, 0.2, 0.35] if female else [0.72, 0.28, 0.0])
    kinds = {"shoes", top, str(bottom)}
    if rng.random() < 0.3:
        kinds.add("jacket")
    garments = tuple(_sample_garment(rng, k) for k in sorted(kinds, key=_LAYER.index))
    skin, garments = _surface_detail(seed, skin, hair, garments)
    headwear = sample_headwear(np.random.default_rng([int(seed), HEADWEAR_STREAM]), female, phenotype["age"])
    return CharacterRecipe(seed=int(seed), pool=pool, index=int(index), phenotype=phenotype, skin=skin, hair=hair,
                           garments=garments, headwear=headwear)


# ---------------------------------------------------------------------------------------------------------------
# Skin and cloth detail (issue 17, part 4): drawn from their own stream after everything else, so the draws above
# (and any later field's own stream) are untouched by it.
# ---------------------------------------------------------------------------------------------------------------
_STREAM_SURFACE_DETAIL = 1704
# Which fabrics a garment kind is made of, with probabilities (shoes and everything unlisted: plain).
_FABRIC_CHOICES = {
    "tshirt": (("jersey", "plain"), (0.85, 0.15)),
    "longsleeve": (("jersey", "knit", "plain", "velvet"), (0.45, 0.35, 0.15, 0.05)),
    "jacket": (("plain", "knit", "velvet"), (0.75, 0.15, 0.10)),
    "trousers": (("plain", "velvet"), (0.92, 0.08)),  # denim / twill; velvet stands for corduroy and velour
    "skirt": (("plain", "jersey", "velvet"), (0.6, 0.25, 0.15)),
    "draped_skirt": (("plain", "jersey", "velvet"), (0.6, 0.25, 0.15)),
}


def _surface_detail(seed: int, skin: SkinTone, hair: HairSpec, garments: tuple[Garment, ...]
                    ) -> tuple[SkinTone, tuple[Garment, ...]]:
    """Freckles, blush and veins of the skin and each garment's fabric. Freckles are common on light skin and with
    red hair, rare on dark skin; veins show through light skin only."""
    rng = np.random.default_rng([int(seed), _STREAM_SURFACE_DETAIL])
    r, g, b = hair.colour
    red_hair = r > 0.3 and r > 1.8 * b and r > 1.3 * g
    p_freckles = (0.6 if red_hair else 0.3) * (1.0 - skin.melanin) ** 2
    freckles = float(rng.uniform(0.3, 1.0)) if rng.random() < p_freckles else 0.0
    blush = float(rng.uniform(0.0, 1.0))
    veins = float(rng.uniform(0.2, 1.0)) * (1.0 - skin.melanin)
    skin = dataclasses.replace(skin, freckles=freckles, blush=blush, veins=veins)
    out = []
    for gm in garments:
        names, p = _FABRIC_CHOICES.get(gm.kind, (("plain",), (1.0,)))
        out.append(dataclasses.replace(gm, fabric=str(names[int(rng.choice(len(names), p=p))])))
    return skin, tuple(out)


# Headwear is drawn from its own stream, np.random.default_rng([seed, HEADWEAR_STREAM]), after everything else: the
# main stream's draws (phenotype, skin, hair, garments) are those of recipes made before headwear existed.
HEADWEAR_STREAM = 1000
# P(covering) by gender: (none, cap, brimmed_hat, headscarf). Glasses, independently: 0.2, 0.4 from anny age 0.82 on
# (~55 years). Our choice, not census figures: about a third of the subjects wear something on the head.
HEADWEAR_P = {"female": (0.70, 0.07, 0.10, 0.13), "male": (0.76, 0.16, 0.08, 0.0)}
GLASSES_P = (0.2, 0.4)
# Acetate frame colours, sRGB 8-bit, picked by us: black, dark tortoise brown, honey, navy, dark grey, burgundy.
_FRAME_PALETTE = np.array([[18, 18, 20], [70, 40, 24], [150, 100, 50], [30, 40, 80], [70, 70, 74], [100, 30, 40]],
                          dtype=np.float64) / 255.0


def sample_headwear(rng: np.random.Generator, female: bool, age: float) -> tuple[Headwear, ...]:
    """The headwear distribution (HEADWEAR_P, GLASSES_P); fabric colours and patterns as a top's."""
    p = HEADWEAR_P["female" if female else "male"]
    covering = (None,) + COVERINGS
    kind = covering[int(rng.choice(len(covering), p=p))]
    out = []
    if kind is not None:
        g = _sample_garment(rng, "tshirt" if kind == "headscarf" else "jacket")
        rough = float(rng.uniform(0.6, 0.9))
        out.append(Headwear(kind, g.colour, g.colour2, g.pattern if kind == "headscarf" else "solid", g.period_m,
                            g.duty, g.vertical, rough))
    if rng.random() < GLASSES_P[int(age > 0.82)]:
        c = _jitter(rng, _FRAME_PALETTE[rng.integers(len(_FRAME_PALETTE))], 0.05)
        out.append(Headwear("glasses", c, roughness=float(rng.uniform(0.2, 0.35))))
    return tuple(out)
