"""`rh-demo`: the whole chain on the small embedded default, as the README's first command runs it.

rh_dataset/scenes/demo.json (protocol a, one subject, 12 turntable + 6 test frames, 128x128, draft) → rh-generate →
rh-verify → a baseline's predictions → rh-eval → rh-leaderboard. Each step is the same entry point a user calls.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rh_common.cli_help import HelpFormatter
from rh_common.interrupt import add_debug_flag, command, on_stop

__all__ = ["main"]


@command("rh-demo")
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rh-demo", description=__doc__.strip().splitlines()[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--out", type=Path, default=Path("demo_out"), help="folder for the dataset, predictions, results")
    p.add_argument("--preset", default="draft", help="render preset (rh_dataset/scenes/presets.json)")
    p.add_argument("--seed", type=int, default=0, help="dataset seed")
    add_debug_flag(p)
    args = p.parse_args(argv)

    from rana import cli as rana_cli
    from rana import oracle
    from rh_dataset import cli as generate_cli
    from rh_dataset import verify
    from rh_eval import cli as eval_cli
    from rh_eval import leaderboard

    data, preds = args.out / "data", args.out / "predictions"
    results, board = args.out / "results", args.out / "leaderboard"
    steps = [
        ("generate", lambda: generate_cli.main(["--protocol", "demo", "--out", str(data), "--preset", args.preset,
                                                "--seed", str(args.seed)])),
        ("verify", lambda: verify.main([str(data), "--no-progress"])),
        ("baseline", lambda: oracle.main(["--dataset", str(data), "--protocol", "a",
                                          "--out", str(preds / "oracle")])),
        ("evaluate oracle", lambda: eval_cli.main([str(preds / "oracle"), "--dataset", str(data), "--protocol", "a",
                                                   "--out", str(results / "oracle.json")])),
        # The SMPL+D baseline of the RANA paper; one torch thread is faster than two on a shared 2-core machine.
        ("baseline smpl+d", lambda: rana_cli.main(["smpld", "--dataset", str(data), "--protocol", "a",
                                                   "--runs", str(args.out / "runs"), "--out", str(preds / "smpld"),
                                                   "--preset", "demo", "--threads", "1", "--no-progress"])),
        ("evaluate smpl+d", lambda: eval_cli.main([str(preds / "smpld"), "--dataset", str(data), "--protocol", "a",
                                                   "--out", str(results / "smpld.json")])),
        ("leaderboard", lambda: leaderboard.main([str(results / "oracle.json"), str(results / "smpld.json"),
                                                  "--out", str(board)])),
    ]
    finished: list[str] = []
    # Each step resumes or redoes its own work, so rerunning rh-demo continues where it stopped.
    on_stop(lambda: f"steps finished: {', '.join(finished) or 'none'}")
    for name, step in steps:
        t = time.perf_counter()
        print(f"== rh-demo: {name}", flush=True)
        rc = step()
        if rc:
            print(f"rh-demo: step {name!r} failed (exit {rc})", file=sys.stderr)
            return rc
        print(f"== rh-demo: {name} done in {time.perf_counter() - t:.1f} s", flush=True)
        finished.append(name)
    print("rh-demo: done. Look at:")
    from rh_common.layout import CONTACT_SHEET

    for sheet in sorted(data.glob(f"subject_*/protocol_*/*/{CONTACT_SHEET}")):
        print(f"  {sheet}")
    print(f"  {board / 'leaderboard.md'}\n  {board / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
