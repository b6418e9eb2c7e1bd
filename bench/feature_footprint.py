"""How many pixels the face's fine features cover in the benchmark's frames: should eyebrows and eyelashes be strands?

In: the protocol's scene file (default protocol a) and seed. Out: a printed table: for every subject, the millimetres
one pixel spans at the head (the camera rh-generate builds frames the subject's box, `frame_body` with the
generator's `framing_box` and `CAMERA_FILL`), and what eyebrows and eyelashes measure there in pixels.

The camera is computed from the naked anny body's rest-pose bounds (anny alone, a fraction of a second per subject),
not from the built character's (hair, hats and clothes widen the box by a few centimetres and move the camera back a
little: the real pixels are, if anything, slightly larger than printed). The head is taken at the box's centre
plane (the camera looks along +Y at it; a head turned or leaning moves by ~0.1 m against a camera ~5 m away).

Feature sizes (adult, typical): an eyebrow band 8-12 mm tall and 50 mm long standing 1-2 mm off the skin, its hairs
~0.06 mm thick; eyelashes 8-12 mm long (upper lid), ~0.1 mm thick, ~100 per upper lid, curving ~3 mm off the lid.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FEATURES_MM = {  # name: (size along the image, thickness or relief off the skin)
    "eyebrow band (height, relief)": (10.0, 1.5),
    "eyebrow hair (length, thickness)": (8.0, 0.06),
    "upper eyelash (length, thickness)": (10.0, 0.1),
    "eyelash curl off the lid": (3.0, 3.0),
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene", nargs="?", default=str(ROOT / "rh_dataset/scenes/protocol_a.json"),
                   help="protocol scene file (default: protocol a)")
    p.add_argument("--seed", type=int, default=0, help="dataset seed (rh-generate --seed)")
    p.add_argument("--subjects", type=int, default=None, help="only the first N subjects")
    args = p.parse_args()

    from rh_common.camera import frame_body
    from rh_dataset.characters.body import run_anny
    from rh_dataset.characters.recipe_draws import sample_recipe
    from rh_dataset.generate.subjects import CAMERA_FILL, framing_box
    from rh_dataset.generate.seeding import rng_for
    from rh_dataset.spec import load_protocol

    spec = load_protocol(args.scene)
    n = spec.subjects if args.subjects is None else min(args.subjects, spec.subjects)
    mm_per_px = []
    for s in range(n):
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool=spec.character_pool, index=s)
        v = run_anny(recipe.phenotype)["rest_vertices"]
        lo, hi = framing_box(v.min(axis=0), v.max(axis=0))
        cam = frame_body(lo, hi, spec.width, spec.height, spec.fov_y_deg, fill=CAMERA_FILL)
        dist = float(np.linalg.norm(np.subtract(cam.target, cam.origin)))
        f_px = 0.5 * spec.height / math.tan(math.radians(spec.fov_y_deg) / 2.0)
        mm_per_px.append(1000.0 * dist / f_px)
    mm = np.array(mm_per_px)
    print(f"{Path(args.scene).name}, seed {args.seed}: {n} subjects at {spec.width}x{spec.height}, "
          f"fov {spec.fov_y_deg:g} deg (naked-body framing; see the docstring)")
    print(f"one pixel at the head spans {mm.min():.2f} / {np.median(mm):.2f} / {mm.max():.2f} mm "
          f"(min / median / max over subjects)")
    print(f"{'feature':<36} {'size mm':>8} {'px (median)':>12} {'thick/relief mm':>16} {'px (median)':>12}")
    med = float(np.median(mm))
    for name, (size, thick) in FEATURES_MM.items():
        print(f"{name:<36} {size:>8.2f} {size / med:>12.2f} {thick:>16.2f} {thick / med:>12.3f}")


if __name__ == "__main__":
    main()
