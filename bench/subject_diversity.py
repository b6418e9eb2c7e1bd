"""Who the benchmark subjects are: counts of sex, body, hair, garments, fabrics, any other recipe field, and skin tone.

In: a scene (default protocol_a: 49 benchmark subjects) and the dataset seed (rh-generate --seed, default 0). The
recipes are drawn exactly as rh-generate draws them (`sample_recipe(rng_for(seed, "character", s), ...)`); nothing
is built or rendered, so it runs in seconds. Out (stdout):
* sex (anny's gender > 0.5 is female, as the recipe draws hair from it) and body (anny phenotype quartiles);
* hair styles and colours (`recipe_draws.hair_colour_name`: the palette colour each was drawn from), iris colours
  (`recipe_draws.iris_colour_name`);
* garments: how many subjects wear each kind, how many wear any draped kind (and who wears shells only), and the
  patterns and fabrics;
* every other top-level recipe field (headwear, ...), counted generically by its `kind`/`style`/`type` or value;
* skin: the Individual Typology Angle of each subject's mean skin albedo (`rh_common.colourspace.ita_degrees` of
  `recipe.skin_albedo_linear`), its range and the count per ITA category; freckles, blush and veins.

  python bench/subject_diversity.py                 # protocol_a's 49 subjects, seed 0
  python bench/subject_diversity.py b --seed 3
"""
from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from rh_common.colourspace import ITA_CATEGORIES, ita_category, ita_degrees
from rh_dataset.characters import sample_recipe
from rh_dataset.characters.recipe import skin_albedo_linear
from rh_dataset.characters.recipe_draws import hair_colour_name, iris_colour_name
from rh_dataset.generate.seeding import rng_for
from rh_dataset.spec import load_protocol

_READ = {"format", "seed", "pool", "index", "phenotype", "skin", "hair", "garments", "eyes"}  # read by name below


def benchmark_recipes(scene: str, seed: int) -> list:
    spec = load_protocol(scene)
    return [sample_recipe(rng_for(seed, "character", s), pool=spec.character_pool, index=s)
            for s in range(spec.subjects)]


def _label(value) -> list[str]:
    """What a generic recipe field counts as: None -> "none"; a dict -> its kind/style/type/name; a list -> each."""
    if value is None:
        return ["none"]
    if isinstance(value, (list, tuple)):
        return [x for v in value for x in _label(v)] or ["none"]
    if isinstance(value, dict):
        for key in ("kind", "style", "type", "name"):
            if key in value:
                return [str(value[key])]
        return [",".join(f"{k}={value[k]}" for k in sorted(value))]
    return [str(value)]


def _counts(c: Counter, total: int | None = None) -> str:
    items = sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))
    return ", ".join(f"{k} {v}" for k, v in items) + (f"  (of {total})" if total is not None else "")


def summarise(recipes: list) -> list[str]:
    n = len(recipes)
    dicts = [r.to_json() for r in recipes]
    lines = []
    female = sum(r.phenotype["gender"] > 0.5 for r in recipes)
    lines.append(f"subjects        {n}: {n - female} male / {female} female (anny gender > 0.5 = female)")
    for k in ("age", "height", "weight", "muscle"):
        q = np.quantile([r.phenotype[k] for r in recipes], [0.0, 0.25, 0.5, 0.75, 1.0])
        lines.append(f"  {k:13s} anny {k} min {q[0]:.2f}  quartiles {q[1]:.2f} {q[2]:.2f} {q[3]:.2f}  max {q[4]:.2f}")
    lines.append(f"hair styles     {_counts(Counter(r.hair.style for r in recipes))}")
    lines.append(f"hair colours    {_counts(Counter(hair_colour_name(r.hair.colour) for r in recipes))}")
    lines.append(f"iris colours    {_counts(Counter(iris_colour_name(r.eyes.iris) for r in recipes))}")
    lines.append(f"garments        {_counts(Counter(g.kind for r in recipes for g in r.garments))}  (subjects wearing)")
    draped = [r.index for r in recipes if any(g.kind.startswith("draped_") for g in r.garments)]
    lines.append(f"  draped        {len(draped)} of {len(recipes)} subjects wear draped cloth; in shells only: "
                 f"{', '.join(str(r.index) for r in recipes if r.index not in draped) or 'none'}")
    lines.append(f"  patterns      {_counts(Counter(g.pattern for r in recipes for g in r.garments if g.kind != 'shoes'))}")
    lines.append(f"  fabrics       {_counts(Counter(g.fabric for r in recipes for g in r.garments if g.kind != 'shoes'))}")
    for key in sorted({k for d in dicts for k in d} - _READ):
        lines.append(f"{key:15s} {_counts(Counter(x for d in dicts for x in _label(d.get(key))))}")
    ita = np.array([float(ita_degrees(skin_albedo_linear(r.skin))) for r in recipes])
    cats = Counter(ita_category(a) for a in ita)
    lines.append(f"skin ITA (deg)  min {ita.min():.1f}  median {np.median(ita):.1f}  max {ita.max():.1f}")
    lines.append("  categories    " + ", ".join(f"{name} {cats.get(name, 0)}" for name, _ in ITA_CATEGORIES)
                 + "  (very light > 55 > light > 41 > intermediate > 28 > tan > 10 > brown > -30 > dark)")
    freckled = sum(r.skin.freckles > 0 for r in recipes)
    lines.append(f"skin detail     freckles {freckled} of {n}; blush median {np.median([r.skin.blush for r in recipes]):.2f}; "
                 f"veins median {np.median([r.skin.veins for r in recipes]):.2f}")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="protocol_a",
                    help="protocol whose subjects are drawn: a name as rh-generate --protocol takes it or a scene "
                         "JSON path (default protocol_a)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed (rh-generate --seed)")
    args = ap.parse_args(argv)
    recipes = benchmark_recipes(args.scene, args.seed)
    print(f"{args.scene}, seed {args.seed}: {len(recipes)} subjects from the {recipes[0].pool} pool")
    print("\n".join(summarise(recipes)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
