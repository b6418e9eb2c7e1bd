"""One process or several on this machine's cores: `rh-generate --workers N`'s wall time for the same frames, and
whether the files are the same.

    python bench/bench_workers.py                                # 4 subjects, 10 frames a split, a and b, 1 and 2
    python bench/bench_workers.py --subjects 2 --frames 4 --resolution 128 --preset draft     # a quick look

In: the generator's own command line (`python -m rh_dataset.cli`, this checkout's code), run once per --workers
count and protocol into a fresh folder under --out (kept with --keep), the counts in turn. Out: one line per
(workers, protocol) and one per workers count in all:
  frames / simulated  frames written, and of those posed by newton's simulation ("auto" cloth: render.cloth_posed
                      in each frame's JSON), which runs its CPU kernels on one core;
  wall s              the command, from start to its last file (start-up, character builds, frames, contact sheets);
  cpu s               the command's processes' CPU seconds (user + system, `resource.RUSAGE_CHILDREN`), and the
                      cores it kept busy on average (cpu / wall);
  load                the 1-minute load average before and after: the machine may be shared;
and, at the end, each count's wall time against the first's, and whether every file of the datasets (their
manifests' sha256, the run logs aside) is the same. One worker renders with all cores' threads; N workers render N
subjects at once, each with cores / N threads, at least 2 (`rh_dataset.backends.local`). A subject's character is
built once per process and protocol, so small runs weigh the builds more than the full benchmark does (550 frames a
subject).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def load() -> float:
    return os.getloadavg()[0]


def simulated_frames(out: Path, protocol: str) -> tuple[int, int]:
    """(frames, frames whose cloth newton simulated) of one protocol in a dataset folder."""
    frames = sim = 0
    for path in out.glob(f"subject_*/protocol_{protocol}/*/frame_*.json"):
        frames += 1
        sim += json.loads(path.read_text()).get("render", {}).get("cloth_posed") == "simulated"
    return frames, sim


def manifest_files(out: Path) -> dict:
    files = json.loads((out / "manifest.json").read_text())["files"]
    return {k: v["sha256"] for k, v in files.items() if not k.startswith("logs/")}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--subjects", type=int, default=4, help="subjects 0..N-1 of each protocol (default 4)")
    ap.add_argument("--frames", type=int, default=10, help="frames per split (rh-generate --frames; default 10)")
    ap.add_argument("--protocols", nargs="+", default=["a", "b"], choices=["a", "b", "c"],
                    help="protocols generated, in turn, into one folder per workers count (default a b)")
    ap.add_argument("--workers", nargs="+", type=int, default=[1, 2],
                    help="--workers counts compared, the first the reference (default 1 2)")
    ap.add_argument("--resolution", default="512", help="rh-generate --resolution (default 512)")
    ap.add_argument("--preset", default="standard", help="rh-generate --preset (default standard)")
    ap.add_argument("--out", type=Path, default=None,
                    help="folder for the datasets (default: a temporary one, removed at the end)")
    ap.add_argument("--keep", action="store_true", help="keep the datasets (with --out)")
    args = ap.parse_args(argv)
    if any(w < 1 for w in args.workers):
        ap.error("--workers counts must be >= 1")

    base = args.out or Path(tempfile.mkdtemp(prefix="bench_workers_"))
    base.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    print(f"# {args.subjects} subjects, {args.frames} frames a split, protocols {' '.join(args.protocols)}, "
          f"{args.resolution} px, preset {args.preset}; {os.cpu_count()} cores; load {load():.2f} at the start")
    print("| workers | protocol | frames | simulated | wall s | cpu s | cores busy | load before / after |")
    print("|---:|---|---:|---:|---:|---:|---:|---|")
    totals: dict[int, tuple[float, float, int, int]] = {}
    try:
        for w in args.workers:
            out = base / f"workers_{w}"
            if out.exists():
                shutil.rmtree(out)
            wall_all = cpu_all = 0.0
            frames_all = sim_all = 0
            for protocol in args.protocols:
                cmd = [sys.executable, "-m", "rh_dataset.cli", "--protocol", protocol, "--out", str(out),
                       "--subjects", str(args.subjects), "--frames", str(args.frames), "--resolution",
                       args.resolution, "--preset", args.preset, "--workers", str(w), "--no-progress"]
                l0, c0, t0 = load(), cpu_seconds(), time.perf_counter()
                proc = subprocess.run(cmd, env=env, cwd=base, capture_output=True, text=True)
                wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
                if proc.returncode != 0:
                    tail = (proc.stderr or proc.stdout).strip().splitlines()[-5:]
                    print(f"rh-generate --workers {w} --protocol {protocol} failed ({proc.returncode}):\n  "
                          + "\n  ".join(tail), file=sys.stderr)
                    return 1
                frames, sim = simulated_frames(out, protocol)
                print(f"| {w} | {protocol} | {frames} | {sim} | {wall:.1f} | {cpu:.1f} | {cpu / wall:.2f} | "
                      f"{l0:.2f} / {load():.2f} |", flush=True)
                wall_all, cpu_all, frames_all, sim_all = wall_all + wall, cpu_all + cpu, frames_all + frames, \
                    sim_all + sim
            totals[w] = (wall_all, cpu_all, frames_all, sim_all)
            print(f"| {w} | all | {frames_all} | {sim_all} | **{wall_all:.1f}** | {cpu_all:.1f} | "
                  f"{cpu_all / wall_all:.2f} | |", flush=True)
        ref = args.workers[0]
        files = {w: manifest_files(base / f"workers_{w}") for w in args.workers}
        print()
        for w in args.workers[1:]:
            differ = sorted(k for k in files[ref].keys() | files[w].keys() if files[ref].get(k) != files[w].get(k))
            same = "every file the same" if not differ else f"{len(differ)} of {len(files[ref])} files differ " \
                f"(first: {differ[0]})"
            print(f"--workers {w} against {ref}: wall {totals[w][0] / totals[ref][0]:.3f}x "
                  f"({totals[w][0]:.1f} s against {totals[ref][0]:.1f} s); {same}")
        print(f"# load {load():.2f} at the end")
    finally:
        if not (args.keep and args.out):
            shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
