"""The render stage alone, saved on one machine and rendered on another: seconds per frame per preset on a GPU
(Mitsuba's cuda_ad_rgb), and how far its layers lie from llvm_ad_rgb's for the very same scenes.

    python bench/bench_render_stage.py save --out DIR [--presets draft standard reference] [--frames 0 1]
    python bench/bench_render_stage.py render DIR --layers-out DIR/llvm [--variant llvm_ad_rgb] [--repeats 3]
    python bench/bench_render_stage.py render DIR --layers-out DIR/llvm_s1 --seed-offset 1   # the noise yardstick
    python bench/bench_render_stage.py compare DIR/cuda DIR/llvm [DIR/llvm_s1 DIR/llvm]

save: the `FrameScene` of each of subject 0's test frames (`--frames`) of protocol a for each preset
(`rh_dataset.generate.frame_scenes`: the pose, cloth, light, culling and seed rh-generate renders that frame with),
pickled (xz) into DIR/scenes.pkl.xz with each frame's JSON record as rh-generate writes it. Needs the whole
environment (anny, the cloth drape, the HDRIs).

render: each saved scene rendered on the chosen variant (default: cuda_ad_rgb where a GPU works, else llvm_ad_rgb),
one untimed warm-up (kernel compilation), then --repeats timed renders. Prints the median seconds of scene load,
beauty and AOV passes and of the writer (`rh_dataset.writer.write_frame`, EXR + PNG as in a dataset; beside it the
same frame written with one encoding thread), and writes the last render as a dataset-shaped folder (split =
preset). Needs only Mitsuba, drjit, numpy, scipy, OpenEXR, Pillow, colour-science and this repository: what a GPU
machine with no package index can be given (tools/device_bundle.sh, tools/device_render_stage.sh).

compare: `rh_common.layout.compare` between two such folders (rh-verify --against's per-layer figures); further
pairs put the figures beside the noise between two sample streams of one variant.

What this leaves out: posing, cloth and light (the "pose" and "light" columns of bench_generate.py) run on the CPU
before the render stage whatever the variant, so they are not measured here.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import lzma
import os
import pickle
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout, also where it is not installed

FORMAT = "rh-render-stage/1"


def _machine() -> str:
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"
    return f"{platform.machine()}, {os.cpu_count()} cores, load average {load}"


def save(args) -> None:
    from rh_common.imageio import read_json
    from rh_dataset.cli import render_settings
    from rh_dataset.generate import (DatasetPlan, frame_scenes, render_frame_to_disk, resolve_plan,
                                     subject_source)
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import select_variant

    variant = select_variant("llvm_ad_rgb")
    spec = load_protocol("a").with_overrides(subjects=1, resolution=(args.resolution, args.resolution))
    split = spec.split("test")
    entries = []
    with tempfile.TemporaryDirectory(prefix="bench_render_stage_") as tmp:
        for preset in args.presets:
            plan = resolve_plan(DatasetPlan(out=Path(tmp) / preset, spec=spec, settings=render_settings(preset),
                                            seed=args.seed))
            source = subject_source(plan)
            subject = source.subject(0)
            for k in args.frames:
                t = time.perf_counter()
                [scene] = frame_scenes(plan, source, subject, split, k)
                # The frame's JSON record as rh-generate writes it (its render.scene_model included): the template
                # of the frames `render` writes, so that they are dataset frames rh-verify's comparison reads.
                result = render_frame_to_disk(plan, source, subject, split, k)
                record = read_json(result.json_path)
                for key in ("files", "index", "format"):
                    record.pop(key, None)
                entries.append({"preset": preset, "frame": k, "scene": scene, "record": record})
                print(f"saved {preset} frame {k}: {sum(len(m.faces) for m in scene.meshes if hasattr(m, 'faces'))} "
                      f"triangles, {time.perf_counter() - t:.1f} s on {variant}", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    payload = {"format": FORMAT, "made_on": _machine(), "resolution": args.resolution,
               "entries": _share_arrays(entries, {})}
    tmp_path, path = out / "scenes.pkl.xz.part", out / "scenes.pkl.xz"
    with lzma.open(tmp_path, "wb", preset=6) as f:
        pickle.dump(payload, f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp_path, path)
    print(f"{path}: {path.stat().st_size / 2**20:.1f} MiB, {len(entries)} scenes")


def _share_arrays(obj, seen: dict):
    """`obj` with equal large arrays made one object, so that pickle stores each once: every preset's character
    has the same textures and light map, built anew for each plan."""
    if isinstance(obj, np.ndarray):
        if obj.nbytes < 65536:
            return obj
        key = (obj.dtype.str, obj.shape, hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest())
        return seen.setdefault(key, obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        changes = {f.name: _share_arrays(getattr(obj, f.name), seen) for f in dataclasses.fields(obj) if f.init}
        return dataclasses.replace(obj, **changes)
    if isinstance(obj, (list, tuple)):
        return type(obj)(_share_arrays(x, seen) for x in obj)
    if isinstance(obj, dict):
        return {k: _share_arrays(v, seen) for k, v in obj.items()}
    return obj


def render(args) -> None:
    from rh_dataset.generate import render_scene
    from rh_dataset.variant import select_variant
    from rh_dataset.writer import write_frame

    path = Path(args.scenes)
    path = path / "scenes.pkl.xz" if path.is_dir() else path
    with lzma.open(path, "rb") as f:  # a file this script wrote (pickle runs code: never load one from elsewhere)
        payload = pickle.load(f)
    if payload.get("format") != FORMAT:
        sys.exit(f"bench_render_stage: {path} is not a {FORMAT} file; make it with `save`")
    variant = select_variant(args.variant)
    print(f"machine: {_machine()}; Mitsuba variant {variant}; scenes made on {payload['made_on']}; "
          f"{payload['resolution']}x{payload['resolution']}, seed offset {args.seed_offset}")
    gpu = _gpu_name() if variant.startswith("cuda") else None
    if gpu:
        print(f"GPU: {gpu}")
    print("\n| preset | frame | spp | max depth | scene load s | beauty s | aov s | render s | write s | "
          "write s, 1 thread | s / frame | first render s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    out = Path(args.layers_out)
    for e in payload["entries"]:
        if args.presets and e["preset"] not in args.presets:
            continue
        scene = dataclasses.replace(e["scene"], seed=e["scene"].seed + args.seed_offset)
        t = time.perf_counter()
        render_scene(scene)  # warm-up: compiles the kernels (or reads them from drjit's cache)
        first = time.perf_counter() - t
        runs, writes, writes_one = [], [], []
        for _ in range(args.repeats):
            result = render_scene(scene)
            runs.append(result.seconds)
            folder = out / "subject_000" / "protocol_a" / e["preset"]
            record = {**e["record"], "render": {**e["record"]["render"], "scene_model": result.info,
                                                "variant": variant, "seed": scene.seed}}
            t = time.perf_counter()
            write_frame(folder, e["frame"], result.layers, record)
            writes.append(time.perf_counter() - t)
            # The same frame written with one thread (the writer before it encoded the layers side by side), into
            # a throwaway folder: the thread pool's gain on this machine, within one run.
            with tempfile.TemporaryDirectory(prefix="bench_render_stage_") as scratch:
                t = time.perf_counter()
                write_frame(scratch, e["frame"], result.layers, record, workers=1)
                writes_one.append(time.perf_counter() - t)
        med = {k: float(np.median([r.get(k, 0.0) for r in runs])) for k in ("load", "beauty", "aov")}
        total = float(np.median([sum(r.values()) for r in runs]))
        write, write_one = float(np.median(writes)), float(np.median(writes_one))
        print(f"| {e['preset']} | {e['frame']} | {scene.settings.spp} | {scene.settings.max_depth} | "
              f"{med['load']:.3f} | {med['beauty']:.3f} | {med['aov']:.3f} | {total:.3f} | {write:.3f} | "
              f"{write_one:.3f} | {total + write:.3f} | {first:.2f} |", flush=True)
    print(f"\nframes written under {out} (split = preset)")


def _gpu_name() -> str | None:
    try:
        import subprocess

        return subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                              capture_output=True, text=True, timeout=30).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def compare(args) -> None:
    from rh_common.layout.compare import compare_datasets

    if len(args.folders) % 2:
        sys.exit("bench_render_stage compare: give folders in pairs (A B [C D])")
    pairs = list(zip(args.folders[::2], args.folders[1::2]))
    print("| layer | " + " | ".join(f"{a} vs {b}: min PSNR dB / max abs" for a, b in pairs) + " |")
    print("|---|" + "---|" * len(pairs))
    tables = []
    for a, b in pairs:
        cmp = compare_datasets(a, b, tier="noise")
        if cmp.mismatches:
            print(f"{a} vs {b}: {'; '.join(cmp.mismatches[:5])}")
        tables.append(cmp.layers)
    for key in sorted(set().union(*tables)):
        cells = []
        for t in tables:
            d = t.get(key)
            cells.append("-" if d is None else ("identical" if d.frames_differing == 0 else
                                                f"{d.min_psnr_db:.1f} / {d.max_abs:.3g}"))
        print(f"| {key} | " + " | ".join(cells) + " |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("save", help="pickle the render stage's input of some test frames, one per preset")
    s.add_argument("--out", required=True, help="folder for scenes.pkl.xz")
    s.add_argument("--presets", nargs="+", default=["draft", "standard", "reference"],
                   help="render presets whose scenes are saved (default all three)")
    s.add_argument("--frames", nargs="+", type=int, default=[0], help="test-frame indices of subject 0 (protocol a)")
    s.add_argument("--resolution", type=int, default=512,
                   help="frame width and height in pixels, in place of protocol a's (default 512)")
    s.add_argument("--seed", type=int, default=0, help="dataset seed")
    r = sub.add_parser("render", help="render saved scenes on this machine's variant, timed, and write the frames")
    r.add_argument("scenes", help="scenes.pkl.xz or the folder holding it")
    r.add_argument("--layers-out", required=True, help="folder for the rendered frames (dataset-shaped)")
    r.add_argument("--variant", default=None, help="Mitsuba variant (default: cuda_ad_rgb where a GPU works)")
    r.add_argument("--repeats", type=int, default=3, help="timed renders per scene, after one warm-up")
    r.add_argument("--presets", nargs="*", default=None, help="only the saved scenes of these presets")
    r.add_argument("--seed-offset", type=int, default=0,
                   help="add this to each scene's sampler seed (1: another sample stream, the noise yardstick)")
    c = sub.add_parser("compare", help="per-layer differences between rendered folders, in pairs")
    c.add_argument("folders", nargs="+",
                   help="folders that render --layers-out wrote, in pairs A B [C D ...]: each pair is compared")
    args = p.parse_args()
    {"save": save, "render": render, "compare": compare}[args.command](args)


if __name__ == "__main__":
    main()
