"""The seeded distribution of character recipes: who the benchmark's and the pretraining pool's subjects are.

In: a seed (or a generator to draw one from), a pool ("benchmark" or "pretrain") and an index. Out: a
`CharacterRecipe` (recipe.py). Benchmark and pretraining characters are disjoint by construction: a recipe's seed
is even for the benchmark pool and odd for the pretraining pool (`derive_seed`), and everything random in a
character is drawn from its seed. Later fields (skin and cloth detail, headwear) draw from streams of their own, so
adding one leaves the earlier draws of every seed unchanged.
"""
from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

from .body import sample_phenotype
from .recipe import (BOTTOMS, COVERINGS, GARMENT_LAYERS, HAIR_STYLES, JACKET_OVER_LOOSE_TOP, OUTERWEAR,
                     OVER_LOOSE_TOP, PATTERNS, POOLS, TOPS, UNDER_COAT, UNDER_LOOSE_TOP, CharacterRecipe, EyeSpec,
                     Garment, HairSpec, Headwear, SkinTone)

__all__ = ["derive_seed", "sample_recipe", "recipe_from_seed", "sample_headwear", "HAIR_COLOUR_NAMES",
           "hair_colour_name", "HEADWEAR_P", "GLASSES_P", "HEADWEAR_STREAM", "sample_eyes", "IRIS_COLOUR_NAMES",
           "iris_colour_name", "iris_weights", "EYES_STREAM", "DRESS_P", "DRESS_STREAM", "WIDE_TROUSERS_P",
           "WIDE_TROUSERS_STREAM", "COAT_P", "COAT_STREAM", "HOODIE_P", "HOODIE_STREAM", "HOODIE_HAIR", "JACKET_P",
           "JACKET_STREAM", "JACKET_BOTTOMS", "TSHIRT_P", "TSHIRT_STREAM",
           "LONGSLEEVE_P", "LONGSLEEVE_STREAM", "SHORTS_P", "SHORTS_STREAM", "STRAIGHT_TROUSERS_P",
           "STRAIGHT_TROUSERS_STREAM"]

_SAMPLED_BOTTOMS = ("trousers", "shorts", "skirt")  # what recipe_from_seed draws from (its stream unchanged)
# Loose clothing (issue 17): the published dataset's subjects wear "long hair, loose clothing, jackets, hats, head
# scarves", so loose garments belong in the benchmark. Every skirt drawn is the draped one (a shell skirt hugging the
# thighs is not a skirt anyone wears), and DRESS_P of the women wear a draped dress instead of top and bottom
# (and then no jacket). Our choice, not a census figure: with the skirt's 35 % that is about half the women (a
# quarter of all subjects) in something loose. The dress is drawn from its own stream, so every other draw of a
# seed is the one it was; its colours are the drawn top's.
_LOOSE = {"skirt": "draped_skirt"}
DRESS_STREAM = 1717
DRESS_P = 0.25
# Wide-leg trousers (palazzo, culottes: `draped_trousers`, draped like the skirt) instead of the drawn trousers, for
# this share of the trousers wearers (women, men): our choice, not a census figure. Drawn from a stream of their own
# (one draw for everyone), in the trousers' colours, pattern and fabric, so every other draw of a seed is unchanged.
WIDE_TROUSERS_STREAM = 1718
WIDE_TROUSERS_P = (0.35, 0.1)
# An open long coat (`draped_coat`: a jacket's shoulders and sleeves over panels draped from the chest to below the
# knee) instead of the drawn jacket, for this share of the jacket wearers whose bottom is one the coat may be worn
# over (`recipe.UNDER_COAT`: shell trousers or shorts, after the wide-trousers draw). Our choice, not a census
# figure. Its own stream (one draw for everyone), the jacket's colours, pattern and fabric: no other draw changes.
COAT_STREAM = 1719
COAT_P = 0.5
# A hoodie (`draped_hoodie`: the longsleeve's shell and a hood draped down the upper back) instead of the drawn
# longsleeve, for this share of the longsleeve wearers with nothing over it (none of recipe.OUTERWEAR: the hood collides
# with the body, not with a jacket), hair that stays off the upper back (HOODIE_HAIR: long hair and a ponytail would
# lie through the hood) and no headscarf (it covers the neck the hood is sewn to). Our choice, not a census figure:
# a few of the benchmark's subjects. Its own stream (one draw for everyone, made after the headwear), the
# longsleeve's colours, pattern and fabric: no other draw of any seed changes.
HOODIE_STREAM = 1720
HOODIE_P = 0.5
HOODIE_HAIR = ("buzz", "short", "bob", "bun")
# An open jacket (`draped_jacket`: the coat's shoulders and sleeves over panels draped from the chest to the hips)
# instead of every drawn jacket the coat draw left a jacket, where the bottom is one of JACKET_BOTTOMS. Our choice,
# not a census figure: the shell jacket is a second skin from the collar to the hips, with no hem standing off the
# body and no folds, which no jacket looks like, so wherever the draped one can be worn it is. Its own stream (one
# draw for everyone, after the coat's), the jacket's colours, pattern and fabric: no other draw of any seed changes,
# and a share below 1 can be chosen later without moving any other draw.
# The bottoms the open jacket's draw drapes a jacket over, whatever the top: the coat's (recipe.UNDER_COAT) and, since
# 5 December afternoon, the wide trousers, a shell top under it held under the panels (drape.SHELLS_UNDER; before,
# a jacket over them was draped only where the loose top's draw put a loose top under it). Not the draped skirt: over
# a shell top, seated, the skirt's lap came out through the panels' hem (benchmark pool recipe 29's `sit`, skinned:
# 93 skirt vertices over the jacket, 15 seen, against 49 and 3 for the wide trousers of pool recipe 173, sitting;
# docs/ARCHITECTURE.md, "Every jacket over wide trousers draped"), so a jacket over a skirt is still draped only with
# a loose top under it (`_loose_top`). Seed 0's 49 benchmark subjects and first 40 pretraining characters wear no
# shell jacket over wide trousers either way.
JACKET_BOTTOMS = UNDER_COAT + ("draped_trousers",)
JACKET_STREAM = 1721
JACKET_P = 1.0
# A loose t-shirt (`draped_tshirt`: the t-shirt's shoulders and sleeves over cloth hanging from under the arms to the
# hips) instead of the drawn t-shirt, for this share of the t-shirt wearers with nothing over it (none of
# recipe.OUTERWEAR) and one of recipe.UNDER_LOOSE_TOP under it (shell trousers or shorts, and since 3 December a
# draped skirt or wide trousers, whose cloth its drape collides with; not the shell skirt). Our choice, not a census
# figure: about half the t-shirts stay close-fitting shells (fitted tees exist), the rest hang loose. Its own stream
# (one draw for everyone, after the jacket's), the t-shirt's colours, pattern and fabric: no other draw of any seed
# changes.
TSHIRT_STREAM = 1722
TSHIRT_P = 0.5
# A loose long sleeve (`draped_longsleeve`: the longsleeve's shoulders and sleeves over the loose t-shirt's cloth)
# instead of the drawn longsleeve, for this share of the longsleeve wearers the hoodie draw left, with nothing over it
# and one of UNDER_LOOSE_TOP under it (as the loose t-shirt). Our choice, not a census figure (a sweater hangs off
# the body; a fitted long sleeve does not). Its own stream (one draw for everyone, after the hoodie's), the
# longsleeve's colours, pattern and fabric: no other draw of any seed changes.
LONGSLEEVE_STREAM = 1723
LONGSLEEVE_P = 0.5
# Loose shorts (`draped_shorts`: the wide trousers' pattern cut above the knee) instead of the drawn (shell) shorts,
# for this share of the shorts wearers, whatever is worn over them: the open jacket's and the coat's drapes collide
# with their cloth (recipe.JACKET_OVER_LOOSE_TOP, recipe.COAT_OVER_DRAPED; over a shell top since 5 December, which
# is then held under the panels, drape.SHELLS_UNDER; under the coat since that afternoon). Our choice, not a census
# figure: a shell is a cycling short, and most shorts worn in the street hang loose; half stay close-fitting. Drawn
# last, from a stream of their own (one draw for everyone), the shorts' colours, pattern and fabric: no other draw
# of any seed changes, and no other garment of any subject.
SHORTS_STREAM = 1724
SHORTS_P = 0.5
# Straight-leg draped trousers (`draped_straight_trousers`: the wide trousers' pattern with straight, narrower legs)
# instead of the (shell) trousers left after the wide-trousers draw, for this share of their wearers, under the same
# rule as the loose shorts. Our choice: the shell is a legging or skinny jeans, most trousers hang loose
# on the thigh and straight past the knee; half stay close-fitting. Drawn
# after the shorts, from a stream of their own: no other draw of any seed changes, and no other garment.
STRAIGHT_TROUSERS_STREAM = 1725
STRAIGHT_TROUSERS_P = 0.5


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
    kinds = {"shoes", top, _LOOSE.get(str(bottom), str(bottom))}
    if rng.random() < 0.3:
        kinds.add("jacket")
    garments = tuple(_sample_garment(rng, k) for k in sorted(kinds, key=GARMENT_LAYERS.index))
    garments = _dress(np.random.default_rng([int(seed), DRESS_STREAM]), female, garments)
    garments = _wide_trousers(np.random.default_rng([int(seed), WIDE_TROUSERS_STREAM]), female, garments)
    garments = _open_jacket(np.random.default_rng([int(seed), COAT_STREAM]), garments, "draped_coat", COAT_P,
                            UNDER_COAT)
    garments = _open_jacket(np.random.default_rng([int(seed), JACKET_STREAM]), garments, "draped_jacket", JACKET_P,
                            JACKET_BOTTOMS)
    garments = _loose_top(np.random.default_rng([int(seed), TSHIRT_STREAM]), garments, "tshirt", TSHIRT_P)
    skin, garments = _surface_detail(seed, skin, hair, garments)
    headwear = sample_headwear(np.random.default_rng([int(seed), HEADWEAR_STREAM]), female, phenotype["age"])
    eyes = sample_eyes(np.random.default_rng([int(seed), EYES_STREAM]), skin.melanin)
    garments = _hoodie(np.random.default_rng([int(seed), HOODIE_STREAM]), garments, hair, headwear)
    garments = _loose_top(np.random.default_rng([int(seed), LONGSLEEVE_STREAM]), garments, "longsleeve",
                          LONGSLEEVE_P)
    garments = _loose_bottom(np.random.default_rng([int(seed), SHORTS_STREAM]), garments, "shorts",
                             "draped_shorts", SHORTS_P)
    garments = _loose_bottom(np.random.default_rng([int(seed), STRAIGHT_TROUSERS_STREAM]), garments, "trousers",
                             "draped_straight_trousers", STRAIGHT_TROUSERS_P)
    return CharacterRecipe(seed=int(seed), pool=pool, index=int(index), phenotype=phenotype, skin=skin, hair=hair,
                           garments=garments, headwear=headwear, eyes=eyes)


def _dress(rng: np.random.Generator, female: bool, garments: tuple[Garment, ...]) -> tuple[Garment, ...]:
    """With probability DRESS_P for a woman: the garments with top, bottom and jacket replaced by a draped dress in
    the top's colours and pattern (rng: the dress stream; one draw for everyone, so the stream's use is fixed)."""
    wears = rng.random() < DRESS_P
    if not (female and wears):
        return garments
    top = next(g for g in garments if g.kind in TOPS)
    dress = dataclasses.replace(top, kind="draped_dress")
    kept = [g for g in garments if g.kind not in TOPS + BOTTOMS + ("jacket",)]
    return tuple(sorted(kept + [dress], key=lambda g: GARMENT_LAYERS.index(g.kind)))


def _wide_trousers(rng: np.random.Generator, female: bool, garments: tuple[Garment, ...]) -> tuple[Garment, ...]:
    """The drawn trousers made wide-leg draped ones with probability WIDE_TROUSERS_P (rng: their stream; one draw
    for everyone, so the stream's use is fixed)."""
    wide = rng.random() < WIDE_TROUSERS_P[0 if female else 1]
    if not wide:
        return garments
    return tuple(dataclasses.replace(g, kind="draped_trousers") if g.kind == "trousers" else g for g in garments)


def _open_jacket(rng: np.random.Generator, garments: tuple[Garment, ...], kind: str, p: float,
                 bottoms: tuple[str, ...]) -> tuple[Garment, ...]:
    """The drawn (shell) jacket made the draped `kind` (the coat, the open jacket) with probability `p` where the
    bottom is one of `bottoms` (rng: the kind's stream; one draw for everyone, so the stream's use is fixed)."""
    wears = rng.random() < p
    kinds = {g.kind for g in garments}
    if not (wears and "jacket" in kinds and kinds & set(bottoms)):
        return garments
    return tuple(dataclasses.replace(g, kind=kind) if g.kind == "jacket" else g for g in garments)


def _loose_top(rng: np.random.Generator, garments: tuple[Garment, ...], top: str, p: float) -> tuple[Garment, ...]:
    """The drawn `top` ("tshirt" or "longsleeve") made its draped kind with probability `p` where nothing but one of
    OVER_LOOSE_TOP is worn over it and the bottom is one of UNDER_LOOSE_TOP (rng: the kind's stream; one draw for
    everyone, so the stream's use is fixed)."""
    loose = rng.random() < p
    kinds = {g.kind for g in garments}
    # A shell jacket is left only over a draped skirt (the open jacket's draw took the others, JACKET_BOTTOMS); over
    # a loose top it is draped too (recipe.JACKET_OVER_LOOSE_TOP), as every jacket that can be is (JACKET_P = 1).
    jacket = ("jacket" in kinds and bool(kinds & (set(JACKET_OVER_LOOSE_TOP) - set(JACKET_BOTTOMS)))
              and JACKET_P == 1.0)
    if not (loose and top in kinds and (jacket or not kinds & (set(OUTERWEAR) - set(OVER_LOOSE_TOP)))
            and kinds & set(UNDER_LOOSE_TOP)):
        return garments
    kind = {top: f"draped_{top}", "jacket": "draped_jacket" if jacket else "jacket"}
    return tuple(dataclasses.replace(g, kind=kind.get(g.kind, g.kind)) for g in garments)


def _loose_bottom(rng: np.random.Generator, garments: tuple[Garment, ...], shell: str, draped: str,
                  p: float) -> tuple[Garment, ...]:
    """The drawn `shell` bottom made the `draped` one with probability `p` under any outerwear (a shell jacket, an
    open jacket or a coat) or none (rng: that draw's stream; one draw for everyone, so its use is fixed). Until
    5 December the open jacket only over a loose top: a shell top lifted over the draped bottom's waistband showed
    through its panels, until the shell top was held under them (drape.SHELLS_UNDER); the coat, whose drape did not
    collide with a draped bottom, not at all until the afternoon of 5 December (recipe.COAT_OVER_DRAPED)."""
    loose = rng.random() < p
    if not (loose and any(g.kind == shell for g in garments)):
        return garments
    return tuple(dataclasses.replace(g, kind=draped) if g.kind == shell else g for g in garments)


def _hoodie(rng: np.random.Generator, garments: tuple[Garment, ...], hair: HairSpec,
            headwear: tuple[Headwear, ...]) -> tuple[Garment, ...]:
    """The drawn longsleeve made a draped hoodie with probability HOODIE_P where nothing is worn over it, the hair is
    one of HOODIE_HAIR and there is no headscarf (rng: the hoodie's stream; one draw for everyone, so the stream's
    use is fixed)."""
    hoodie = rng.random() < HOODIE_P
    kinds = {g.kind for g in garments}
    if not (hoodie and "longsleeve" in kinds and not kinds & set(OUTERWEAR) and hair.style in HOODIE_HAIR
            and not any(h.kind == "headscarf" for h in headwear)):
        return garments
    return tuple(dataclasses.replace(g, kind="draped_hoodie") if g.kind == "longsleeve" else g for g in garments)


# ---------------------------------------------------------------------------------------------------------------
# Skin and cloth detail (issue 17, part 4): drawn from their own stream after everything else, so the draws above
# (and any later field's own stream) are untouched by it.
# ---------------------------------------------------------------------------------------------------------------
_STREAM_SURFACE_DETAIL = 1704
# Which fabrics a garment kind is made of, with probabilities (shoes and everything unlisted: plain).
_JACKET_FABRICS = (("plain", "knit", "velvet"), (0.75, 0.15, 0.10))
_FABRIC_CHOICES = {
    "tshirt": (("jersey", "plain"), (0.85, 0.15)),
    "draped_tshirt": (("jersey", "plain"), (0.85, 0.15)),  # the t-shirt's (so the drawn fabric stays)
    "longsleeve": (("jersey", "knit", "plain", "velvet"), (0.45, 0.35, 0.15, 0.05)),
    "jacket": _JACKET_FABRICS,
    "draped_coat": _JACKET_FABRICS,  # the jacket's (so the drawn fabric stays)
    "draped_jacket": _JACKET_FABRICS,
    "draped_hoodie": (("jersey", "knit", "plain", "velvet"), (0.45, 0.35, 0.15, 0.05)),  # the longsleeve's
    "draped_longsleeve": (("jersey", "knit", "plain", "velvet"), (0.45, 0.35, 0.15, 0.05)),  # the longsleeve's
    "trousers": (("plain", "velvet"), (0.92, 0.08)),  # denim / twill; velvet stands for corduroy and velour
    "draped_trousers": (("plain", "velvet"), (0.92, 0.08)),  # the trousers' (so a drawn fabric stays the same)
    # (shorts and draped_shorts: plain; the loose shorts and straight trousers are drawn after the fabrics, so keep
    # the shorts' and the trousers')
    "skirt": (("plain", "jersey", "velvet"), (0.6, 0.25, 0.15)),
    "draped_skirt": (("plain", "jersey", "velvet"), (0.6, 0.25, 0.15)),
    "draped_dress": (("plain", "jersey", "velvet"), (0.6, 0.3, 0.1)),
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


# ---------------------------------------------------------------------------------------------------------------
# Eyes (issue 17): the iris colour, from its own stream np.random.default_rng([seed, EYES_STREAM]), drawn after
# everything else so every other field of every seed is what it was before eyes existed.
# ---------------------------------------------------------------------------------------------------------------
EYES_STREAM = 1705
IRIS_COLOUR_NAMES = ("dark brown", "brown", "amber", "hazel", "green", "blue", "grey")
# Mean iris colours, sRGB 8-bit, picked by us from photographs of each class (the texture adds fibres, a darker
# limbal ring and a pupillary zone around the mean).
_IRIS_PALETTE = np.array([[52, 32, 20], [99, 60, 32], [140, 96, 44], [118, 100, 56], [92, 116, 70],
                          [88, 126, 164], [126, 136, 142]], dtype=np.float64) / 255.0
# Class weights at the two ends of the skin-melanin axis. Iris and skin pigment come from the same melanocyte
# pigmentation genes (OCA2/HERC2 among them), so light irises (blue, grey, green) are almost confined to light skin;
# brown is the commonest colour worldwide (~70-80 %). Our choice, guided by those prevalences, not a census.
_IRIS_W_LIGHT = np.array([0.08, 0.22, 0.05, 0.15, 0.12, 0.32, 0.06])
_IRIS_W_DARK = np.array([0.72, 0.25, 0.03, 0.0, 0.0, 0.0, 0.0])


def iris_weights(melanin: float) -> np.ndarray:
    """P(iris class) (IRIS_COLOUR_NAMES order) for a skin melanin in [0, 1]: the light-skin weights fade with
    (1 - melanin)^2 (melanin 0.3, ColorChecker "light skin": ~49 % of them; 0.7, "dark skin": 9 %)."""
    s = (1.0 - float(melanin)) ** 2
    w = s * _IRIS_W_LIGHT + (1.0 - s) * _IRIS_W_DARK
    return w / w.sum()


def iris_colour_name(rgb: tuple[float, float, float]) -> str:
    """The class (IRIS_COLOUR_NAMES) whose palette colour is nearest in sRGB (as `hair_colour_name`; a large
    jitter can move a brown to the neighbouring amber or hazel)."""
    d = np.linalg.norm(_IRIS_PALETTE - np.asarray(rgb, dtype=np.float64), axis=1)
    return IRIS_COLOUR_NAMES[int(np.argmin(d))]


def sample_eyes(rng: np.random.Generator, melanin: float) -> EyeSpec:
    """An iris colour: a class by `iris_weights`, its palette colour jittered (mostly in brightness)."""
    k = int(rng.choice(len(_IRIS_PALETTE), p=iris_weights(melanin)))
    return EyeSpec(iris=_jitter(rng, _IRIS_PALETTE[k], 0.1))
