"""The coat's shell (worn under an open jacket's or a coat's panels) against those panels, for the generator's own
subjects at rest: does any of its vertices under the panels' pinned ring stand outside them?

    python bench/bench_coat_shell.py                                 # seed 0's jackets and coats over loose tops
    python bench/bench_coat_shell.py --subjects 7,19,25,30          # ... over shell tops
    python bench/bench_coat_shell.py --drape coarse --subjects 14,26

Subjects are rh-generate's (`sample_recipe(rng_for(seed, "character", s))`, benchmark pool), built as the generator
builds them (the user's drape cache: a cold one simulates each drape, minutes at `full`). Per subject: the shell's
trunk vertices under the pinned ring in anny's rest A-pose, but for the open front's 4 cm either side of the middle
(`bench_cloth.coat_overlap`); how many of them lie outside the panels (`cloth_pose.layer_depth` < 0); the least
depth under the panels (negative: the worst poke out); the shell's largest offset off the skin. Over a loose top the
shell is lifted over the top's cloth (`garments._shell`'s `under`) and, before `garments._under_cover`, came out
through the panels under their ring.
Then the slot: how far the panels' pinned ring stands off the shell under it (each ring vertex's height over the
shell, `layer_depth` against the shell, within 3 cm): its median and largest. Seen from above (a bending pose) a wide
slot shows as a dark line across the chest; the loose t-shirt's ring was brought to 2.5 mm over its shell for that
(docs/ARCHITECTURE.md, "The loose t-shirt"); the coat's shell is lifted to the ring for it (`garments.RING_LIFT`).
--poses N: the same overlap and slot measures posed, in the rest pose and the subject's first N test poses
(`sample_pose(rng_for(seed, "pose", s, "test", j))`, as rh-generate draws them), skinned and simulated
(`pose_character`'s cloth modes).
--without-lift: also build each subject with the shell tucked to TUCK["coat"] up to the ring, as before the lift
(`garments.RING_LIFT` emptied for that build), and print its figures beside (the draped panels are the same).
--figure PATH: the first subject in its first test pose (rh-generate's standard preset for the test split, 64 spp,
Blender's studio light, full body framed at 512 px), its chest cropped around the panels' ring at 2x: with the lift,
and left of it without (with --without-lift).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def measure(ch, kind: str, g, low: np.ndarray, bones: dict, mode: str) -> str:
    """One line of figures for a built character posed by `bones` in cloth mode `mode` (module docstring)."""
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.cloth_pose import layer_depth

    posed = {m.name: m for m in pose_character(ch, bones, None, mode)}
    shell_v, shell_f = posed["coat"].vertices.astype(np.float64), posed["coat"].faces
    d = layer_depth(shell_v[low], posed[kind].vertices.astype(np.float64), posed[kind].faces)
    slot = -layer_depth(posed[kind].vertices[g.pinned].astype(np.float64), shell_v, shell_f)
    return (f"{int((d < 0).sum())} of {int(low.sum())} outside the panels (worst "
            f"{1e3 * max(0.0, -float(np.nanmin(d, initial=0.0))):.2f} mm out), the least "
            f"{1e3 * float(np.nanmin(d)):.2f} mm under them; ring over the shell "
            f"{1e3 * float(np.nanmedian(slot)):.1f} mm (median), {1e3 * float(np.nanmax(slot)):.1f} mm at most "
            f"({int(np.isfinite(slot).sum())} of {int(g.pinned.sum())} ring vertices over it)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="2,14,21,26,40,41,45,48",
                    help="comma-separated benchmark subjects (rh-generate's, at --seed) wearing an open jacket or a "
                         "coat")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes come from")
    ap.add_argument("--drape", default="full", choices=("full", "coarse"), help="drape level (RenderSettings.drape)")
    ap.add_argument("--poses", type=int, default=0, help="also measure posed: rest and this many test poses, "
                                                         "skinned and simulated (about a minute a pose)")
    ap.add_argument("--without-lift", action="store_true",
                    help="also measure the shell as it was before garments.RING_LIFT (tucked up to the ring)")
    ap.add_argument("--figure", type=Path, default=None, help="write the first subject's chest, posed, here (PNG)")
    args = ap.parse_args(argv)

    from bench_cloth import coat_overlap
    import rh_dataset.characters.character as character_module
    import rh_dataset.characters.garments as garments_module
    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, sample_recipe
    from rh_dataset.characters.character import DEFAULT_TEXTURE_RESOLUTION
    from rh_dataset.characters.drape import drape_layers
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    def build(recipe, lift: bool, res: int = 64):
        """The character as rh-generate builds it (textures at `res` px), or with the shell before the lift (a build
        of its own)."""
        saved = garments_module.RING_LIFT
        garments_module.RING_LIFT = saved if lift else ()
        character_module._build_cached.cache_clear()  # the build cache keys on the recipe alone
        try:
            return build_character(recipe, res, drape=args.drape)
        finally:
            garments_module.RING_LIFT = saved
            character_module._build_cached.cache_clear()

    variants = ("lift", "before") if args.without_lift else ("lift",)
    print(f"load average at start: {' '.join(open('/proc/loadavg').read().split()[:3])}; drape {args.drape}")
    subjects = [int(x) for x in args.subjects.split(",")]
    for s in subjects:
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s)
        kinds = [g.kind for g in recipe.garments]
        kind = next((k for k in kinds if k in ("draped_jacket", "draped_coat")), None)
        if kind is None:
            ap.error(f"benchmark subject {s} wears no open jacket or coat: {kinds}")
        t0 = time.perf_counter()
        chars = {v: build(recipe, v == "lift") for v in variants}
        g = drape_layers(kinds, recipe.phenotype, args.drape)[kind]  # as the build drapes it (cached by it)
        z_ring = float(g.vertices[g.pinned, 2].mean())
        low = {v: coat_overlap(ch, z_ring) for v, ch in chars.items()}
        print(f"subject {s:2d} {', '.join(kinds)}: shell offset up to "
              f"{1e3 * float(chars['lift'].part('coat').offset.max()):.1f} mm; shell vertices under the ring:")
        poses = [("rest", {})] + [(f"test {j} ({p.label})", dict(p.bones)) for j, p in enumerate(
            sample_pose(rng_for(args.seed, "pose", s, "test", j), load_anny()) for j in range(args.poses))]
        for label, bones in poses:
            for mode in ("skinned", "simulated") if args.poses else ("skinned",):
                for v, ch in chars.items():
                    print(f"  {label:16s} {mode:9s} {v:6s} {measure(ch, kind, g, low[v], bones, mode)}", flush=True)
        print(f"  ({time.perf_counter() - t0:.0f} s, load {open('/proc/loadavg').read().split()[0]})", flush=True)
        if args.figure and s == subjects[0]:
            first = ({v: build(recipe, v == "lift", DEFAULT_TEXTURE_RESOLUTION) for v in reversed(variants)}, kind, g)
    if args.figure:
        figure(args.figure, subjects[0], args.seed, *first)
    return 0


def figure(out: Path, s: int, seed: int, chars: dict, kind: str, g) -> None:
    """`--figure`: each character of `chars` (one subject's builds) in rh-generate's first test pose of subject `s`,
    its chest (the box of the pinned ring of its panels `kind`, drape `g`, widened) cut out at 2x, side by side."""
    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, pose_character
    from rh_dataset.cli import render_settings
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant
    from rh_common.body_model import load_anny
    from subjects_gallery import studio_environment

    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings("standard", spp=64, aov_spp=4).for_split(test)
    bones = dict(sample_pose(rng_for(seed, "pose", s, "test", 0), load_anny()).bones)
    tiles = []
    for ch in chars.values():
        posed = pose_character(ch, bones)
        lo, hi = body_bounds(posed)
        cam = frame_body(lo, hi, 512, 512, 30.0, fill=0.94)
        img = render_frame(posed, env, cam, settings, ["image"], seed=s).layers["image"]
        ring = cam.project(next(m for m in posed if m.name == kind).vertices[g.pinned].astype(np.float64))
        (x0, y0), (x1, y1) = ring.min(0), ring.max(0)
        cx, cy, w, h = 0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.3 * (x1 - x0), 1.3 * (x1 - x0) * 0.75
        crop = img[int(cy - 0.5 * h):int(cy + 0.5 * h), int(cx - 0.5 * w):int(cx + 0.5 * w)]
        tiles.append(np.repeat(np.repeat(quantize8(srgb_encode(np.clip(crop * 1.3, 0.0, None))), 2, 0), 2, 1))
    h = min(t.shape[0] for t in tiles)
    w = min(t.shape[1] for t in tiles)
    write_png(out, np.concatenate([t[:h, :w] for t in tiles], 1))
    print(f"wrote {out}")


if __name__ == "__main__":
    raise SystemExit(main())
