"""The seam across a loose top's or a dress's chest: where its shell ("tee", "longtop", "hoodie", the dress's
"bodice") meets its draped body's pinned ring, for the generator's own subjects, with the bust bridged
(`drape.BRIDGE_BAND`, `garments.BRIDGED`) and, with --before, without.

    python bench/bench_bust_seam.py                          # seed 0's loose-top and dress wearers: the ring
    python bench/bench_bust_seam.py --subjects 28,12,42 --poses 2 --before
    python bench/bench_bust_seam.py --subjects 28,12,3 --figure docs/bust_seam.png --before

Subjects are rh-generate's (`sample_recipe(rng_for(seed, "character", s))`, benchmark pool). Per subject, from the
A-pose body the cloth is draped on (nothing built): the bust's apex over the ring under the arms (`drape._bust_apex`:
the front-most trunk point within 12 cm of the middle, from 4 cm under that ring to 12 cm over it), how far the ring
is raised over the bust (`drape._bust_height`; not under an open jacket or a coat, `drape.piece_settings`), and how
far the trunk's hull stands out over the ring's radius, front middle, below it (the belly, within
`drape.BRIDGE_BELOW`) and above it (the bust, within 15 cm).

With --poses N (or --figure) each subject is built as rh-generate builds it (the user's drape cache; a cold one drapes
each top, ~30-60 s), then in the rest pose and its first N test poses (`sample_pose(rng_for(seed, "pose", s, "test",
j))`), skinned and, with N > 0, simulated (`pose_character`'s cloth modes):
- the slot: each pinned ring vertex's height over the shell (`cloth_pose.layer_depth` against the shell, within
  2 cm): median and largest over the front (within 60 degrees of the middle); seen from above, a wide slot is a dark
  line across the chest;
- the shell through the cloth: the shell's trunk vertices under the ring in the rest pose, and how many of them lie
  outside the draped body (`layer_depth` < 0), the worst by how much;
- the shell's triangles turned over (`bench_shell_folds.folded`: geometric normal against the shading normals);
- the shell's largest offset off the skin.
--before: each figure also for the build before the bridge (the ring under the arms at the trunk's hull, the shell on
the skin, its hem at one bind-space height: `bridge`); the subject's drape is then another (the ring moved), so a
cold cache drapes it twice.
--figure PATH: each subject's chest in the rest pose and its first test pose (rh-generate's standard preset for the
test split, 64 spp, Blender's studio light, the body framed at FIGURE_PX), cropped round the ring: a row per subject;
with --before, each pose bridged then before.
"""
from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

FIGURE_PX = 1024  # the figure's renders (the whole body framed), cropped round the ring
# The garments whose cloth hangs from a pinned ring under a shell over the chest: garment kind -> (shell, cloth part).
TOPS = {"draped_tshirt": ("tee", "draped_tshirt"), "draped_longsleeve": ("longtop", "draped_longsleeve"),
        "draped_hoodie": ("hoodie", "draped_hoodie_body"), "draped_dress": ("bodice", "draped_dress")}


@contextlib.contextmanager
def bridge(on: bool):
    """The bridge as it is (`on`), or switched off for a build: the ring under the arms (`DrapeProfile.top` "chest"),
    `drape.BRIDGE_BAND` and `garments.BRIDGED` emptied (the character cache cleared either side)."""
    import dataclasses

    import rh_dataset.characters.character as character_module
    import rh_dataset.characters.drape as drape_module
    import rh_dataset.characters.garments as garments_module

    saved = drape_module.BRIDGE_BAND, garments_module.BRIDGED, dict(drape_module.PROFILES)
    if not on:
        drape_module.BRIDGE_BAND, garments_module.BRIDGED = {}, {}
        for kind in saved[0]:
            drape_module.PROFILES[kind] = dataclasses.replace(drape_module.PROFILES[kind], top="chest")
    character_module._build_cached.cache_clear()
    try:
        yield
    finally:
        drape_module.BRIDGE_BAND, garments_module.BRIDGED = saved[:2]
        drape_module.PROFILES.update(saved[2])
        character_module._build_cached.cache_clear()


def profile(phenotype: dict, kind: str, worn: list[str]) -> str:
    """The ring against the bust and the belly in the A-pose (module docstring), one line; `worn`: the recipe's
    garment kinds (under an open jacket or a coat the top is not hung over the bust: `drape.piece_settings`)."""
    from rh_dataset.characters import drape as D
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.body_features import body_features

    feats, run = body_features(phenotype), run_anny(phenotype)
    body = run["vertices"]
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    centre = np.asarray(heads["root"], np.float64)
    gap = D._ring_gap(D.PROFILES[kind], D.drape_settings(kind))
    chest = D._under_the_arms(feats, body, heads, centre, gap)
    apex = D._bust_apex(feats, body, centre, chest)
    st = D.piece_settings(kind, "full", worn)
    z = D.ring_height(kind, phenotype, st)

    def hull(h: float) -> float:
        return float(D._hull_radii(feats, body, float(h), centre, np.zeros(1))[0])

    at = hull(z)
    above = max(hull(h) for h in np.arange(z, z + 0.15, 0.005)) - at
    below = max(hull(h) for h in np.arange(z - D.BRIDGE_BELOW, z, 0.005)) - at
    return (f"bust's apex {100 * (apex - chest):+5.1f} cm over the chest ring, "
            f"ring raised {100 * (z - chest):3.1f} cm{'' if st.over_bust else ' (under a jacket or coat)'}; "
            f"the trunk's hull over the ring's, front middle: {1e3 * above:5.1f} mm above it, {1e3 * below:5.1f} mm "
            f"below it")


def measure(ch, shell: str, cloth: str, ring: np.ndarray, low: np.ndarray, centre: np.ndarray, bones: dict,
            mode: str) -> str:
    """One line of figures for a built character posed by `bones` in cloth mode `mode` (module docstring)."""
    from bench_shell_folds import folded

    from rh_dataset.characters import pose_character
    from rh_dataset.characters.cloth_pose import layer_depth

    posed = {m.name: m for m in pose_character(ch, bones, None, mode)}
    sv, sf = posed[shell].vertices.astype(np.float64), posed[shell].faces
    cv, cf = posed[cloth].vertices.astype(np.float64), posed[cloth].faces
    if len(cv) != len(ring):  # the render mesh repeats the tube's first column (geometry.seamed_grid): row 0
        ring = np.arange(int(ring.sum()) + 1)
    d = layer_depth(sv[low], cv, cf)
    slot = -layer_depth(cv[ring], sv, sf)
    front = np.abs(np.arctan2(cv[ring, 0] - centre[0], -(cv[ring, 1] - centre[1]))) < np.radians(60.0)
    s = slot[front & np.isfinite(slot)]
    out = int((d < 0).sum())
    return (f"slot (front) {1e3 * float(np.median(s)) if len(s) else np.nan:4.1f} mm median, "
            f"{1e3 * float(s.max()) if len(s) else np.nan:5.1f} max ({len(s)} of {int(front.sum())} over the shell); "
            f"shell out through the cloth: {out} of {int(low.sum())}"
            + (f" (worst {1e3 * float(-np.nanmin(d)):.1f} mm)" if out else "")
            + f"; shell triangles turned over: {int(folded(posed[shell]).sum())}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default=None,
                    help="comma-separated benchmark subjects (rh-generate's, at --seed) wearing a loose t-shirt, "
                         "long sleeve, hoodie or dress (default: all of them at --seed)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes and poses come from")
    ap.add_argument("--drape", default="full", choices=("full", "coarse"), help="drape level (RenderSettings.drape)")
    ap.add_argument("--poses", type=int, default=-1,
                    help="build each subject and measure the seam in the rest pose and this many test poses "
                         "(0: rest only, skinned; default: no build, the A-pose profile only)")
    ap.add_argument("--before", action="store_true", help="also measure each build without the bridge")
    ap.add_argument("--figure", type=Path, default=None, help="write the subjects' chests here (PNG)")
    args = ap.parse_args(argv)

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character, sample_recipe
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.drape import drape_layers
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    print(f"load average at start: {' '.join(open('/proc/loadavg').read().split()[:3])}; drape {args.drape}")
    recipes = {}
    for s in ([int(x) for x in args.subjects.split(",")] if args.subjects else range(49)):
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s)
        top = next((g.kind for g in recipe.garments if g.kind in TOPS), None)
        if top is None:
            if args.subjects:
                ap.error(f"benchmark subject {s} wears no loose top or dress: {[g.kind for g in recipe.garments]}")
            continue
        recipes[s] = (recipe, top)
    variants = (True, False) if args.before else (True,)
    figures = []
    for s, (recipe, top) in recipes.items():
        shell, cloth = TOPS[top]
        ph = recipe.phenotype
        print(f"subject {s:2d} {top:18s} {profile(ph, cloth, [g.kind for g in recipe.garments])}", flush=True)
        if args.poses < 0 and args.figure is None:
            continue
        t0 = time.perf_counter()
        run = run_anny(ph)
        centre = run["bone_poses"][body_topology().bone_labels.index("root"), :2, 3].astype(np.float64)
        poses = [("rest", {})] + [(f"test {j} ({p.label})", dict(p.bones)) for j, p in enumerate(
            sample_pose(rng_for(args.seed, "pose", s, "test", j), load_anny()) for j in range(max(args.poses, 1)))]
        for on in variants:
            with bridge(on):
                ch = build_character(recipe, 64, drape=args.drape)
                g = drape_layers([gm.kind for gm in recipe.garments], ph, args.drape)[cloth]
                z_ring = float(g.vertices[g.pinned, 2].mean())
                rest = {m.name: m for m in pose_character(ch, {})}[shell].vertices
                low = (rest[:, 2] < z_ring) & body_features(ph).in_groups("torso")[ch.part(shell).body_vertex]
                label = "bridged" if on else "before"
                print(f"  {label}: shell offset up to {1e3 * float(ch.part(shell).offset.max()):.1f} mm", flush=True)
                for name, bones in poses[:args.poses + 1]:
                    for mode in ("skinned", "simulated") if args.poses > 0 else ("skinned",):
                        print(f"    {name:22s} {mode:9s} "
                              f"{measure(ch, shell, cloth, g.pinned, low, centre, bones, mode)}", flush=True)
                if args.figure is not None:
                    figures.append((s, on, recipe, g, cloth, poses[1][1]))
        print(f"  ({time.perf_counter() - t0:.0f} s, load {open('/proc/loadavg').read().split()[0]})", flush=True)
    if args.figure is not None:
        figure(args.figure, figures, len(variants))
    return 0


def figure(out: Path, items: list, n_variants: int) -> None:
    """`--figure`: per subject (a row), per variant, its chest in the rest pose and its first test pose, cropped round
    its cloth's pinned ring at 2x."""
    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, build_character, pose_character
    from rh_dataset.characters.character import DEFAULT_TEXTURE_RESOLUTION
    from rh_dataset.cli import render_settings
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant
    from subjects_gallery import studio_environment

    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings("standard", spp=64, aov_spp=4).for_split(test)
    tiles = []
    for s, on, recipe, g, cloth, bones in items:
        with bridge(on):
            ch = build_character(recipe, DEFAULT_TEXTURE_RESOLUTION)
            for b in ({}, bones):
                posed = pose_character(ch, b)
                lo, hi = body_bounds(posed)
                cam = frame_body(lo, hi, FIGURE_PX, FIGURE_PX, 30.0, fill=0.94)
                img = render_frame(posed, env, cam, settings, ["image"], seed=s).layers["image"]
                cv = next(m for m in posed if m.name == cloth).vertices.astype(np.float64)
                ring = cam.project(cv[g.pinned] if len(cv) == len(g.pinned) else cv[:int(g.pinned.sum())])
                (x0, y0), (x1, y1) = ring.min(0), ring.max(0)
                cx, cy, w = 0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.5 * (x1 - x0)
                crop = img[max(int(cy - 0.55 * w), 0):int(cy + 0.3 * w), max(int(cx - 0.5 * w), 0):int(cx + 0.5 * w)]
                tiles.append(quantize8(srgb_encode(np.clip(crop * 1.3, 0.0, None))))
    h = min(t.shape[0] for t in tiles)
    w = min(t.shape[1] for t in tiles)
    per_row = 2 * n_variants
    rows = []
    for i in range(0, len(tiles), per_row):
        row = tiles[i:i + per_row]
        if n_variants > 1:  # bridged rest, before rest, bridged pose, before pose
            row = [row[0], row[2], row[1], row[3]]
        rows.append(np.concatenate([t[:h, :w] for t in row], 1))
    write_png(out, np.concatenate(rows, 0))
    print(f"wrote {out}: rows = subjects; columns = rest"
          + (" bridged | before, first test pose bridged | before" if n_variants > 1 else ", first test pose"))


if __name__ == "__main__":
    raise SystemExit(main())
