"""How soon `rh-generate` stops after Ctrl-C: seconds from SIGINT to the process's exit, at a real frame size.

In: a resolution, a preset and how long after the first frame to send the signal. Out (printed): the exit code, the
seconds until exit, the stop line, any temporary file left (there should be none), and the load average.

    python bench/bench_stop.py --resolution 512 --preset standard --delay 1

A signal is handled when the renderer returns to Python, so the wait is at most the render pass under way (the
beauty pass is most of a frame: README, "Cost per 512x512 frame").
"""
from __future__ import annotations

import argparse
import glob
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument("--resolution", default="512", help="image size N or WxH, passed to rh-generate --resolution "
                   "(default 512)")
    p.add_argument("--preset", default="standard",
                   help="render preset passed to rh-generate --preset: draft, standard or reference "
                        "(default standard)")
    p.add_argument("--delay", type=float, default=1.0, help="seconds after the first frame's JSON to send SIGINT")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="rh_stop_") as work:
        out = Path(work) / "ds"
        cmd = [sys.executable, "-m", "rh_dataset.cli", "--protocol", "a", "--out", str(out), "--subjects", "1",
               "--frames", "3", "--resolution", args.resolution, "--preset", args.preset, "--no-progress"]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                start_new_session=True, env={**os.environ, "PYTHONPATH": str(REPO)})
        while not glob.glob(f"{out}/subject_*/protocol_a/train/frame_000000.json") and proc.poll() is None:
            time.sleep(0.02)
        time.sleep(args.delay)
        os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C: the whole process group
        t = time.perf_counter()
        _, err = proc.communicate()
        seconds = time.perf_counter() - t
        print(f"exit code {proc.returncode}, {seconds:.2f} s after SIGINT ({args.resolution} px, {args.preset}); "
              f"load average {Path('/proc/loadavg').read_text().split()[:3]}")
        print("\n".join(line for line in err.splitlines() if line.startswith("rh-generate")))
        print(f"temporary files left: {glob.glob(f'{out}/**/.*.tmp', recursive=True)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
