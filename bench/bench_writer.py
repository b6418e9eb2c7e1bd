"""What writing one frame costs, part by part, and what the lossless encoder settings would save.

    python bench/bench_writer.py [--resolution 512] [--preset standard] [--repeats 5]

Renders frame 0 of subject 0's test split of protocol a (every layer) with `rh_dataset.generate.render_frame_to_disk`
into a temporary folder, then times on those layers (median of `--repeats`): the whole writer (`rh_dataset.writer.
write_frame`: firefly count, EXRs, PNG previews, checksums, JSON, each file fsynced), its parts, and each PNG preview
at three zlib levels (bytes per pixel beside; lossless, so every reader reads the same pixels). The EXRs' own options
are bench/bench_exr.py's. Prints Markdown tables.
"""
from __future__ import annotations

import argparse
import io
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def _ms(fn, repeats: int) -> float:
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1000 * statistics.median(ts)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, default=512, help="frame width and height in pixels (default 512)")
    p.add_argument("--preset", default="standard",
                   help="render preset of the frame written: draft, standard or reference (default standard)")
    p.add_argument("--repeats", type=int, default=5,
                   help="timed runs of each part; the tables give medians (default 5)")
    args = p.parse_args()

    from PIL import Image

    from rh_common.colourspace import quantize8, srgb_encode, to_display
    from rh_common.imageio import read_exr, read_json, read_png, sha256_file, write_exr, write_png
    from rh_dataset.cli import render_settings
    from rh_dataset.generate import DatasetPlan, render_frame_to_disk, resolve_plan, subject_source
    from rh_dataset.render.passes import count_fireflies
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import select_variant
    from rh_dataset.writer import write_frame

    select_variant(None)
    n = args.resolution
    spec = load_protocol("a").with_overrides(subjects=1, resolution=(n, n))
    split = spec.split("test")
    with tempfile.TemporaryDirectory(prefix="bench_writer_") as tmp:
        plan = resolve_plan(DatasetPlan(out=Path(tmp) / "d", spec=spec, settings=render_settings(args.preset), seed=0))
        source = subject_source(plan)
        res = render_frame_to_disk(plan, source, source.subject(0), split, 0)
        d = res.json_path.parent
        meta = read_json(res.json_path)
        stem = res.json_path.stem
        layers = {"image": read_exr(d / f"{stem}_image.exr"), "mask": read_png(d / f"{stem}_mask.png") / 255.0,
                  "albedo": read_exr(d / f"{stem}_albedo.exr"), "normal": read_exr(d / f"{stem}_normal.exr"),
                  "depth": read_exr(d / f"{stem}_depth.exr")[..., 0]}
        layers["mask"] = layers["mask"].astype(np.float32)
        for k in ("files", "format", "index"):
            meta.pop(k, None)
        out = Path(tmp) / "w"
        out.mkdir()
        exposure = float(meta["exposure"])
        pngs = {"image": quantize8(to_display(layers["image"], exposure)), "mask": quantize8(layers["mask"]),
                "albedo": quantize8(srgb_encode(layers["albedo"])),
                "normal": np.where(np.any(layers["normal"] != 0, -1, keepdims=True),
                                   quantize8((layers["normal"] + 1) * 0.5), 0).astype(np.uint8)}
        px = n * n
        load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
        print(f"{n}x{n}, preset {args.preset}, median of {args.repeats}; load average {load}\n")
        total = _ms(lambda: write_frame(out, 0, layers, meta), args.repeats)
        files = sorted(out.iterdir())
        print("| part | ms |\n|---|---|")
        print(f"| whole writer (write_frame, {len(files)} files) | {total:.0f} |")
        print(f"| EXR layers (write_exr, ZIP) | {_ms(lambda: [write_exr(out / f'x_{k}.exr', layers[k]) for k in ('image', 'albedo', 'normal', 'depth')], args.repeats):.0f} |")
        print(f"| PNG previews (write_png) | {_ms(lambda: [write_png(out / f'x_{k}.png', a) for k, a in pngs.items()], args.repeats):.0f} |")
        print(f"| firefly count (5x5 median) | {_ms(lambda: count_fireflies(layers['image']), args.repeats):.0f} |")
        print(f"| sha256 of every file | {_ms(lambda: [sha256_file(f) for f in files], args.repeats):.0f} |")
        print(f"| display transforms + 8-bit quantisation of the previews | "
              f"{_ms(lambda: (quantize8(to_display(layers['image'], exposure)), quantize8(srgb_encode(layers['albedo']))), args.repeats):.0f} |")

        print("\n| PNG preview | zlib level | ms | bytes / px |\n|---|---|---|---|")
        for name, arr in pngs.items():
            for level in (1, 3, 6):
                buf = io.BytesIO()

                def enc(arr=arr, level=level, buf=buf):
                    buf.seek(0)
                    buf.truncate()
                    Image.fromarray(arr).save(buf, format="PNG", compress_level=level)
                ms = _ms(enc, args.repeats)
                print(f"| {name} | {level} | {ms:.1f} | {len(buf.getvalue()) / px:.2f} |")


if __name__ == "__main__":
    main()
