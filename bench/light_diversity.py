"""How varied each protocol's test lights are: prints one row per scene and split.

In: scene names (default: a, b, mixed_a, mixed_b) and either `--dataset DIR` (read the frames' `light` blocks) or
nothing (draw the lights exactly as rh-generate would, `rh_dataset.generate.frames.light_for`, for `--subjects`
subjects and `--seed`; nothing is rendered). Out (stdout), per split:
* lights, distinct environments (an HDRI by name; a procedural or sunsky light by its parameters), and the share
  of real maps (`envmap`), procedural maps (studio / window / outdoor) and sunsky;
* dominant direction: the luminance SH band-1 vector (the irradiance gradient) as a unit vector; its spread over
  the sphere as the mean resultant length R (1: every light from the same side; 0: spread evenly), and the share
  of lights lit from above the horizon;
* directional / ambient: |l1| / (√3 l0) of the luminance SH (0: uniform light; 1: one distant point light); its
  median and 10-90% range;
* colour temperature of the ambient term l0 (`rh_common.colourspace.linear_srgb_to_cct`): median and 10-90%.

  python bench/light_diversity.py                      # the four shipped scenes, 1 subject (150 lights each)
  python bench/light_diversity.py --dataset data/rh b  # the lights of a generated dataset
  python bench/light_diversity.py mixed_b --by-kind    # and one row per light kind
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.colourspace import REC709_LUMINANCE, linear_srgb_to_cct
from rh_dataset.generate.frames import light_for, light_spec_json
from rh_dataset.generate.plan import DatasetPlan, light_library
from rh_dataset.lights import PROCEDURAL_KINDS
from rh_dataset.render.scene import RenderSettings
from rh_dataset.spec import load_protocol


def _drawn(scene: str, subjects: int, seed: int) -> dict[str, list[dict]]:
    spec = load_protocol(scene)
    plan = DatasetPlan(out=Path("unused"), spec=spec, settings=RenderSettings(), seed=seed)
    library = light_library(spec)
    out = {}
    for split in spec.splits:
        if split.light != "random":
            continue
        lights = []
        for s in range(min(subjects, spec.subjects)):
            for i in range(split.frames):
                light = light_for(plan, split, s, i, library)
                lights.append({**light_spec_json(light.spec), "sh_world": np.asarray(light.sh_world)})
        out[split.name] = lights
    return out


def _read(dataset: Path, scene: str) -> dict[str, list[dict]]:
    spec = load_protocol(scene)
    out: dict[str, list[dict]] = {}
    for split in spec.splits:
        if split.light != "random":
            continue
        files = sorted(dataset.glob(f"subject_*/{layout.protocol_dir(spec.protocol)}/{split.name}/frame_*.json"))
        out[split.name] = [{**json.loads(f.read_text())["light"]} for f in files]
    return out


def _identity(light: dict) -> str:
    if light["kind"] == "envmap":
        return f"envmap:{light['name']}"
    keep = {k: light[k] for k in ("params", "sun_azimuth_deg", "sun_elevation_deg", "turbidity") if k in light}
    return f"{light['kind']}:{json.dumps(keep, sort_keys=True)}"


def summarise(lights: list[dict]) -> dict:
    n = len(lights)
    kinds = [lt["kind"] for lt in lights]
    lum = np.array([np.asarray(lt["sh_world"], dtype=np.float64) @ REC709_LUMINANCE.astype(np.float64)
                    for lt in lights])  # (n, 9)
    l1 = lum[:, [3, 1, 2]]  # band 1 is (y, z, x) in rh_common.sh order: reorder to (x, y, z)
    norm = np.linalg.norm(l1, axis=1)
    dirs = l1 / np.maximum(norm, 1e-30)[:, None]
    ratio = norm / (math.sqrt(3.0) * lum[:, 0])
    cct = np.array([linear_srgb_to_cct(np.asarray(lt["sh_world"], dtype=np.float64)[0]) for lt in lights])
    pct = lambda a: (float(np.nanmedian(a)), float(np.nanpercentile(a, 10)), float(np.nanpercentile(a, 90)))  # noqa
    return {"lights": n, "distinct": len({_identity(lt) for lt in lights}),
            "real": kinds.count("envmap") / n, "procedural": sum(kinds.count(k) for k in PROCEDURAL_KINDS) / n,
            "sunsky": kinds.count("sunsky") / n, "R": float(np.linalg.norm(dirs.mean(axis=0))),
            "above": float(np.mean(dirs[:, 2] > 0)), "ratio": pct(ratio), "cct": pct(cct)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=["a", "b", "mixed_a", "mixed_b"],
                    help="protocols whose random-light splits are summarised: names as rh-generate --protocol "
                         "takes them or scene JSON paths (default a b mixed_a mixed_b)")
    ap.add_argument("--dataset", type=Path, help="read the lights of this generated dataset instead of drawing")
    ap.add_argument("--subjects", type=int, default=1, help="subjects whose lights are drawn (default 1)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed (rh-generate --seed)")
    ap.add_argument("--by-kind", action="store_true", help="also one row per light kind of each split")
    args = ap.parse_args(argv)
    print(f"{'scene/split':16s} {'lights':>6s} {'distinct':>8s} {'real':>5s} {'proc':>5s} {'sky':>5s} "
          f"{'R':>5s} {'above':>5s}  {'dir/amb median [10-90%]':24s} {'CCT K median [10-90%]':22s}")
    for scene in args.scenes:
        splits = _read(args.dataset, scene) if args.dataset else _drawn(scene, args.subjects, args.seed)
        for split, lights in splits.items():
            if not lights:
                print(f"{scene + '/' + split:16s} no frames")
                continue
            kinds = sorted({lt["kind"] for lt in lights}) if args.by_kind and len({lt["kind"] for lt in lights}) > 1 \
                else []
            for label, subset in [(f"{scene}/{split}", lights)] + [(f"  {k}", [lt for lt in lights if lt["kind"] == k])
                                                                  for k in kinds]:
                s = summarise(subset)
                r, c = s["ratio"], s["cct"]
                print(f"{label:16s} {s['lights']:6d} {s['distinct']:8d} {s['real']:5.2f} "
                      f"{s['procedural']:5.2f} {s['sunsky']:5.2f} {s['R']:5.2f} {s['above']:5.2f}  "
                      f"{r[0]:5.2f} [{r[1]:4.2f}-{r[2]:4.2f}]{'':9s} {c[0]:6.0f} [{c[1]:5.0f}-{c[2]:5.0f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
