"""What posing a character costs per frame, and a fingerprint of what it makes, to compare two checkouts.

    python bench/bench_posing.py                         # seed 0's subjects 2 and 14 (open jackets over loose tops)
    python bench/bench_posing.py --subjects 0,1 --poses 3 --repeats 5
    python bench/bench_posing.py --save /tmp/old.npz           # in a checkout of the old commit (this script copied in)
    python bench/bench_posing.py --against /tmp/old.npz        # here: where the posed meshes differ, and by how much

In: the dataset seed, the subjects (rh-generate's protocol a subjects, built as at the `standard` preset: full
drapes from the user's drape cache, skinned cloth), how many of the test split's poses besides the rest pose, and
how many times each frame is posed.
Out, printed per subject and in all: `pose_character`'s seconds per frame (the median of --repeats over each frame,
summed over the frames), and the sha256 of every posed part's vertices and normals over those frames (float32
bytes, in part order): two checkouts whose posing code differs only in speed print the same hash. To time another
commit, copy this script into a checkout of it (with bench_cloth_pose.py, for its subjects and poses) and run it
there, in turn with this one (sys.path takes the script's own checkout); compare the ratios within one sitting,
since a shared machine's load moves the seconds. The load average is printed. `--save` writes every posed mesh's
vertices and every posed strands' control points (float32) to an .npz; `--against` reads one back and prints, per
frame, each part whose points differ: the largest displacement and how many points moved more than 1 um and 0.1 mm.
"""
from __future__ import annotations

import argparse
import hashlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def fingerprint(posed, digest) -> None:
    """Feed every posed part's vertices and normals (strands: their points) into `digest`."""
    for m in posed:
        for name in ("vertices", "normals", "points"):
            x = getattr(m, name, None)
            if x is not None:
                digest.update(np.ascontiguousarray(x, np.float32).tobytes())


def compare(meshes: dict[str, np.ndarray], old: dict[str, np.ndarray]) -> list[str]:
    """Per posed mesh or strands (their control points), how it differs from the same in `old`: nothing where the
    bits agree."""
    out = []
    for key, v in meshes.items():
        if key not in old or old[key].shape != v.shape:
            out.append(f"{key.split('/')[-1]} not comparable")
            continue
        d = np.linalg.norm(v.astype(np.float64) - old[key], axis=1)
        if d.max() > 0:
            out.append(f"{key.split('/')[-1]} {1e3 * d.max():.3f} mm at most, {(d > 1e-6).sum()} vertices > 1 um, "
                       f"{(d > 1e-4).sum()} > 0.1 mm of {len(d)}")
    return out or ["the same bits"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose subjects are posed")
    ap.add_argument("--subjects", default="2,14", help="comma-separated protocol a subject indices")
    ap.add_argument("--poses", type=int, default=2, help="test poses per subject besides the rest pose")
    ap.add_argument("--repeats", type=int, default=3, help="posings of each frame whose median is taken")
    ap.add_argument("--save", type=Path, help="write the posed meshes' vertices and strands' points to this .npz")
    ap.add_argument("--against", type=Path, help="compare the posed meshes and strands with this .npz (from --save)")
    args = ap.parse_args(argv)
    try:
        subjects = [int(x) for x in args.subjects.split(",") if x]
    except ValueError:
        ap.error(f"--subjects: comma-separated integers, got {args.subjects!r}")
    if not subjects or args.poses < 0 or args.repeats < 1:
        ap.error("--subjects must name a subject, --poses be >= 0 and --repeats >= 1")
    if args.against is not None and not args.against.is_file():
        ap.error(f"--against: no such file {args.against}")
    saved, old = {}, (dict(np.load(args.against)) if args.against is not None else None)

    from bench_cloth_pose import rest_and_test_poses, test_source
    from rh_dataset.characters import pose_character

    source, test = test_source(args.seed)
    everything = hashlib.sha256()
    total = 0.0
    print(f"{'subject':>7s} {'frames':>6s} {'s / frame':>10s}  sha256 (posed vertices and normals)   (load {load()})")
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        frames = rest_and_test_poses(source, subject, test, args.poses)
        pose_character(ch, frames[0][1], frames[0][2])  # first call: imports, kernels
        digest = hashlib.sha256()
        secs = 0.0
        for i, (_, bones, root) in enumerate(frames):
            times = []
            for r in range(args.repeats):
                t = time.perf_counter()
                posed = pose_character(ch, bones, root)
                times.append(time.perf_counter() - t)
            secs += statistics.median(times)
            fingerprint(posed, digest)
            fingerprint(posed, everything)
            meshes = {f"{s}/{i}/{m.name}": np.asarray(m.vertices if hasattr(m, "faces") else m.points,
                                                      np.float32).reshape(-1, 3) for m in posed}
            saved.update(meshes)
            if old is not None:
                print(f"  subject {s} frame {i}: " + "; ".join(compare(meshes, old)))
        total += secs
        print(f"{s:7d} {len(frames):6d} {secs / len(frames):10.3f}  {digest.hexdigest()[:32]}   (load {load()})",
              flush=True)
    if args.save is not None:
        np.savez(args.save, **saved)
    print(f"{'all':>7s} {len(subjects) * (args.poses + 1):6d} {total / (len(subjects) * (args.poses + 1)):10.3f}  "
          f"{everything.hexdigest()[:32]}   (load {load()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
