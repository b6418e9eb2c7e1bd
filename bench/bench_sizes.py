"""Bytes each layer file of a frame takes on disk, per pixel: the figures `rh_dataset.space` estimates a run from.

In: a preset, resolutions and a frame count. Out (printed): for each resolution and split, the mean and largest bytes
per pixel of every layer file (image.exr, image.png, mask.png, ...), the frame JSON's bytes and the contact sheet's,
then the largest per-pixel figure of each file over all runs, as the `BYTES_PER_PIXEL` table of rh_dataset/space.py.

    python bench/bench_sizes.py --preset draft --resolutions 128 256 512 --frames 3

It renders protocol a (subject 0, train and test) through rh-generate's own stages, so the files are exactly a
dataset's. Sizes depend on content (the HDRI behind the person, path-tracing noise), not on the machine.
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rh_common import layout  # noqa: E402

_FILE_RE = re.compile(r"frame_\d{6}(?:_(?P<name>\w+)\.(?P<ext>exr|png)|\.json)$")


def measure(preset: str, resolution: int, frames: int, protocol: str, work: Path) -> dict:
    from rh_dataset.cli import build_parser, options_from_args
    from rh_dataset.generate import generate

    out = work / f"{protocol}_{preset}_{resolution}"
    args = build_parser().parse_args(["--protocol", protocol, "--out", str(out), "--subjects", "1", "--frames",
                                      str(frames), "--resolution", str(resolution), "--preset", preset,
                                      "--no-progress"])
    plan, backend = options_from_args(args)
    generate(plan, backend, progress=False)
    px = resolution * resolution
    per: dict[tuple[str, str], list[int]] = defaultdict(list)
    for split in plan.spec.splits:
        d = plan.split_dir(0, split.name)
        for f in sorted(d.iterdir()):
            m = _FILE_RE.match(f.name)
            if f.name == layout.CONTACT_SHEET:
                per[(split.name, "contact_sheet")].append(f.stat().st_size)
            elif m:
                key = f"{m['name']}.{m['ext']}" if m["name"] else "json"
                per[(split.name, key)].append(f.stat().st_size)
    return {"pixels": px, "sizes": per}


def full_benchmark(r: dict, resolution: int) -> None:
    """The full benchmark's size (protocols a and b at their own subjects, frames and resolution): from the mean
    frame measured at the largest resolution run, and as rh_dataset.space estimates it before a run."""
    from rh_dataset.cli import build_parser, options_from_args
    from rh_dataset import space

    mean = {split: sum(sum(v) / len(v) for (sp, k), v in r["sizes"].items() if sp == split and k != "contact_sheet")
            for split in ("train", "test")}
    print(f"\nmean frame at {resolution}x{resolution}: train {mean['train'] / 1e6:.3f} MB, test "
          f"{mean['test'] / 1e6:.3f} MB")
    total_measured = total_estimate = 0.0
    for protocol in ("a", "b"):
        plan, _ = options_from_args(build_parser().parse_args(["--protocol", protocol, "--out",
                                                               "/nonexistent/rh_sizes"]))
        frames = {split.name: split.frames * plan.spec.subjects for split in plan.spec.splits}
        measured = sum(mean[name] * n for name, n in frames.items()) if resolution == plan.spec.width else None
        estimate = space.remaining_bytes(plan)
        total_estimate += estimate
        total_measured += measured or 0.0
        print(f"protocol {protocol}: {plan.spec.subjects} subjects, frames {frames} at {plan.spec.width}x"
              f"{plan.spec.height}: estimate {estimate / 1e9:.1f} GB"
              + (f", from the measured mean frame {measured / 1e9:.1f} GB" if measured else ""))
    print(f"full benchmark (a + b): estimate {total_estimate / 1e9:.1f} GB"
          + (f", from the measured mean frame {total_measured / 1e9:.1f} GB" if total_measured else ""))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("--preset", default="draft", help="render preset: draft, standard or reference (default draft)")
    p.add_argument("--protocol", default="a",
                   help="protocol rendered, as rh-generate --protocol takes it (subject 0; default a)")
    p.add_argument("--resolutions", type=int, nargs="+", default=[128, 256, 512],
                   help="frame sizes in pixels, a run each; the last run's mean frame also sizes the full "
                        "benchmark")
    p.add_argument("--frames", type=int, default=3, help="frames per split")
    args = p.parse_args(argv)
    print(f"load average before: {Path('/proc/loadavg').read_text().split()[:3]}")
    table: dict[str, float] = {}
    fixed: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="rh_sizes_") as work:
        for res in args.resolutions:
            r = measure(args.preset, res, args.frames, args.protocol, Path(work))
            print(f"\n{args.protocol} preset={args.preset} {res}x{res}, {args.frames} frames per split")
            print(f"  {'split':6s} {'file':14s} {'mean bytes':>11s} {'max bytes':>10s} {'max B/px':>9s}")
            for (split, key), sizes in sorted(r["sizes"].items()):
                mean, top = sum(sizes) / len(sizes), max(sizes)
                print(f"  {split:6s} {key:14s} {mean:11.0f} {top:10d} {top / r['pixels']:9.4f}")
                if key in ("json", "contact_sheet"):
                    fixed[key] = max(fixed.get(key, 0), top)
                else:
                    table[key] = max(table.get(key, 0.0), top / r["pixels"])
        full_benchmark(r, args.resolutions[-1])
    print(f"\nload average after: {Path('/proc/loadavg').read_text().split()[:3]}")
    print("\nBYTES_PER_PIXEL = {  # the largest over the runs above")
    for key, v in sorted(table.items()):
        print(f"    {key!r}: {v:.3f},")
    print("}")
    print(f"FIXED_BYTES = {fixed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
