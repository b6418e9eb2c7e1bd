"""EXR storage options for each layer of a dataset: bytes, write and read time, and whether the round trip is exact.

In: a dataset folder (rh-generate output) and a frame count. Out (printed): for each EXR layer (image, albedo, normal,
depth) and each OpenEXR compression this OpenEXR offers, the mean bytes per pixel, the median write and read
milliseconds, and the largest error of the round trip (0 = bit-exact); then, for the beauty image, ZIP after
dropping low mantissa bits (lossy: the relative error it adds, against the image's own path-tracing noise), and
half floats for the other layers (their largest error in the layer's units).

    python bench/bench_exr.py --dataset D --frames 2 --repeats 3

Only the compression and the pixel type change; the channels, the header and the reader are `rh_common.imageio`'s.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import OpenEXR

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rh_common.imageio import read_exr  # noqa: E402

COMPRESSIONS = [n[:-len("_COMPRESSION")] for n in dir(OpenEXR)
                if n.endswith("_COMPRESSION") and n != "NUM_COMPRESSION_METHODS"]


def write(path: Path, arr: np.ndarray, compression: str, dtype=np.float32) -> None:
    names = ("Y",) if arr.shape[2] == 1 else ("R", "G", "B")
    channels = {n: np.ascontiguousarray(arr[..., i].astype(dtype)) for i, n in enumerate(names)}
    header = {"compression": getattr(OpenEXR, f"{compression}_COMPRESSION"), "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def drop_mantissa(a: np.ndarray, keep: int) -> np.ndarray:
    """float32 with only the top `keep` of its 23 mantissa bits (rounded to nearest)."""
    bits = a.astype(np.float32).view(np.uint32)
    drop = 23 - keep
    rounded = (bits + np.uint32(1 << (drop - 1))) & np.uint32(~((1 << drop) - 1) & 0xFFFFFFFF)
    return rounded.view(np.float32)


def measure(arrays: list[np.ndarray], compression: str, repeats: int, work: Path, dtype=np.float32,
            prep=None) -> dict:
    sizes, w_ms, r_ms, err = [], [], [], 0.0
    for k, a in enumerate(arrays):
        src = prep(a) if prep else a
        path = work / f"{compression}_{k}.exr"
        for _ in range(repeats):
            t = time.perf_counter()
            write(path, src, compression, dtype)
            w_ms.append((time.perf_counter() - t) * 1e3)
        for _ in range(repeats):
            t = time.perf_counter()
            back = read_exr(path)
            r_ms.append((time.perf_counter() - t) * 1e3)
        sizes.append(path.stat().st_size / (a.shape[0] * a.shape[1]))
        err = max(err, float(np.max(np.abs(back.astype(np.float64) - a.astype(np.float64)))))
        os.unlink(path)
    return {"bpp": statistics.mean(sizes), "write_ms": statistics.median(w_ms), "read_ms": statistics.median(r_ms),
            "err": err}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("--dataset", required=True, type=Path,
                   help="dataset folder (rh-generate output); the frames are those of its first "
                        "subject_*/protocol_*/test folder")
    p.add_argument("--frames", type=int, default=2, help="test frames used per layer")
    p.add_argument("--repeats", type=int, default=3,
                   help="writes and reads of each frame per compression; the times are medians (default 3)")
    args = p.parse_args(argv)
    print(f"OpenEXR {OpenEXR.__version__}; load average before: {Path('/proc/loadavg').read_text().split()[:3]}")
    test = sorted(args.dataset.glob("subject_*/protocol_*/test"))[0]
    with tempfile.TemporaryDirectory(prefix="rh_exr_") as work:
        work = Path(work)
        for layer in ("image", "albedo", "normal", "depth"):
            files = sorted(test.glob(f"frame_*_{layer}.exr"))[: args.frames]
            arrays = [read_exr(f) for f in files]
            h, w = arrays[0].shape[:2]
            print(f"\n{layer} ({len(arrays)} frames of {w}x{h}, {arrays[0].shape[2]} channel(s), float32)")
            print(f"  {'compression':12s} {'B/px':>7s} {'write ms':>9s} {'read ms':>8s} {'max |error|':>12s}")
            for c in COMPRESSIONS:
                try:
                    r = measure(arrays, c, args.repeats, work)
                except Exception as exc:  # an option this build cannot write for float32
                    print(f"  {c:12s} not available for float32 ({str(exc)[:60]})")
                    continue
                print(f"  {c:12s} {r['bpp']:7.3f} {r['write_ms']:9.1f} {r['read_ms']:8.1f} {r['err']:12.3g}")
            if layer == "image":
                inside = [a > 0 for a in arrays]
                for keep in (16, 12, 10):
                    r = measure(arrays, "ZIP", args.repeats, work, prep=lambda a, k=keep: drop_mantissa(a, k))
                    rel = max(float(np.max(np.abs(drop_mantissa(a, keep) - a)[m] / a[m]))
                              for a, m in zip(arrays, inside))
                    print(f"  ZIP, {keep:2d}-bit mantissa {r['bpp']:7.3f} {r['write_ms']:9.1f} {r['read_ms']:8.1f} "
                          f"relative error <= {rel:.2g} (lossy)")
            else:
                for c in ("ZIP", "PIZ"):
                    r = measure(arrays, c, args.repeats, work, dtype=np.float16)
                    print(f"  {c + ', half':12s} {r['bpp']:7.3f} {r['write_ms']:9.1f} {r['read_ms']:8.1f} "
                          f"{r['err']:12.3g} (lossy)")
    print(f"\nload average after: {Path('/proc/loadavg').read_text().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
