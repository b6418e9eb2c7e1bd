"""`rh-verify DIR`: find every missing, truncated, altered or extra file and every NaN/Inf in a dataset, and check
its content identity; `rh-verify DIR --against OTHER`: is OTHER the same benchmark?

In: a dataset root, read through `rh_common.layout` (its manifest and frame records); optionally a second one.
Out: a `Report` listing each problem with the file it concerns, and the content identity; with --against, the
per-layer differences (`rh_common.layout.compare`) and the verdict. Exit status 1 if there is any problem or the
datasets are not the same benchmark within the documented tolerance.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rh_common import layout
from rh_common.imageio import ImageFileError, read_exr, read_json, read_png
from rh_common.interrupt import add_debug_flag, command, on_stop

__all__ = ["Problem", "verify", "main"]


@dataclass
class Problem:
    path: str
    what: str

    def __str__(self) -> str:
        return f"{self.path}: {self.what}"


@dataclass
class Report:
    files_checked: int = 0
    frames_checked: int = 0
    problems: list[Problem] = field(default_factory=list)
    identity: dict | None = None  # the manifest's content identity (None: a format-1 manifest)


def _check_content(path: Path) -> str | None:
    try:
        if path.suffix == ".exr":
            a = read_exr(path)
            bad = int(np.sum(~np.isfinite(a)))
            return f"{bad} NaN/Inf values" if bad else None
        if path.suffix == ".png":
            read_png(path)
        elif path.suffix == ".json":
            read_json(path)
    except (ImageFileError, ValueError) as exc:
        return f"unreadable ({exc})"
    return None


def verify(root: str | Path, *, check_content: bool = True, progress: bool = False) -> Report:
    root = Path(root)
    rep = Report()
    manifest_path = root / layout.MANIFEST_JSON
    if not manifest_path.is_file():
        rep.problems.append(Problem(str(manifest_path), "missing: not a finished dataset (rerun rh-generate)"))
        return rep
    try:
        listed = layout.read_manifest(root)
    except ValueError as exc:
        rep.problems.append(Problem(str(manifest_path), f"unreadable manifest ({exc})"))
        return rep
    for rel in layout.unlisted_files(root, listed):
        what = "leftover temporary file from an interrupted write" if rel.endswith(".tmp") else "not in the manifest"
        rep.problems.append(Problem(rel, what))
    from tqdm import tqdm

    for rel, entry in tqdm(sorted(listed.items()), disable=not progress, unit="file", desc="verify"):
        rep.files_checked += 1
        msg = layout.check_entry(root, rel, entry)
        if msg is None and check_content:
            msg = _check_content(root / rel)
        if msg:
            rep.problems.append(Problem(rel, msg))
    # Frame JSONs list their own layer files: a frame must be whole even if the manifest was rebuilt around a hole.
    for fj in layout.iter_frame_jsons(root):
        rep.frames_checked += 1
        try:
            record = layout.read_frame_record(fj)
        except ValueError as exc:
            if not any(p.path == fj.relative_to(root).as_posix() for p in rep.problems):  # else reported above
                rep.problems.append(Problem(fj.relative_to(root).as_posix(), f"not a frame record ({exc})"))
            continue
        for name in record.files:
            if not (fj.parent / name).is_file():
                rep.problems.append(Problem((fj.parent / name).relative_to(root).as_posix(),
                                            f"missing, listed by {fj.name}"))
    rep.identity = layout.read_identity(root)
    if rep.identity is None:
        rep.problems.append(Problem(str(manifest_path), "format-1 manifest: no content identity (rerun rh-generate "
                                                         "on the folder to rewrite it; no frame is rendered again)"))
    elif check_content and not rep.problems:  # else a listed file is missing or altered: reported above
        recomputed = layout.content_identity(root)
        for rel in sorted(set(recomputed["frames"]) | set(rep.identity.get("frames", {}))):
            if recomputed["frames"].get(rel) != rep.identity.get("frames", {}).get(rel):
                rep.problems.append(Problem(rel, "content identity differs from the manifest's"))
        if recomputed["dataset"] != rep.identity.get("dataset") and not rep.problems:
            rep.problems.append(Problem(str(manifest_path), "dataset content identity differs from its frames'"))
    return rep


def _print_comparison(cmp: layout.Comparison, shown: int = 20) -> None:
    print(f"{'split/layer':<32} {'max |A-B|':>12} {'min PSNR dB':>12} {'frames differing':>17} "
          f"{'pixels diverged':>16}")
    for key, d in sorted(cmp.layers.items()):
        psnr = "inf" if d.min_psnr_db == float("inf") else f"{d.min_psnr_db:.1f}"
        flag = ("" if d.within("rounding") else "  within sampling noise" if d.within(cmp.tier)
                else "  outside tolerance")
        div = f"{100 * d.max_diverged_fraction:.2f} %" if d.pixels_diverged else "-"
        print(f"{key:<32} {d.max_abs:>12.4g} {psnr:>12} {d.frames_differing:>8} of {d.frames:<6} {div:>16}{flag}")
    print("(pixels diverged: the largest share of one frame's pixels that differ beyond rounding)")
    if cmp.metadata_frames_differing:
        print(f"cameras, poses, lights: {cmp.metadata_frames_differing} frame(s) differ within rounding (the largest "
              f"float difference {cmp.metadata_max:.2g} of the tolerance: relative "
              f"{layout.TOLERANCE['metadata_rel']:g}, absolute {layout.TOLERANCE['metadata_abs']:g})")
    for line in cmp.mismatches[:shown]:
        print(line)
    for rel in cmp.frames_differing[:shown]:
        print(f"differs: {rel}")
    more = len(cmp.mismatches[shown:]) + len(cmp.frames_differing[shown:])
    if more:
        print(f"... and {more} more (all of them: --record FILE)")


@command("rh-verify")
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rh-verify",
                                description="Check a dataset against its manifest: every file present, with the "
                                            "recorded size and sha256, readable, and free of NaN/Inf; no extra or "
                                            "temporary files. Exit status 0 if clean, 1 if any problem.")
    p.add_argument("root", type=Path, help="dataset folder (the one holding manifest.json)")
    p.add_argument("--no-content", action="store_true", help="checksums only; skip decoding images for NaN/Inf")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--against", type=Path, metavar="OTHER",
                   help="also compare with the dataset OTHER frame by frame and layer by layer: max absolute "
                        "difference and lowest PSNR per layer, the frames that differ, and whether the two are the "
                        "same benchmark within the tolerance of docs/ARCHITECTURE.md ('Content identity'); OTHER "
                        "is verified too")
    p.add_argument("--tolerance", choices=layout.TIERS, default="noise",
                   help="with --against: what counts as the same benchmark. 'noise' (default): every file within "
                        "rounding except up to 2 %% of its pixels whose paths took another course (another CPU "
                        "vector width, strand hair); 'rounding': every file within rounding (>= 100 dB, 8-bit "
                        "within 1 level; both tiers take the cameras, poses and lights' floats within 1e-6 "
                        "relative), the check for a change of the generator on one machine")
    p.add_argument("--record", type=Path, metavar="FILE",
                   help="with --against: write the comparison as JSON (rh-comparison/1), every differing frame "
                        "listed; rh-leaderboard --comparison FILE reads it to rank results of both datasets together")
    add_debug_flag(p)
    args = p.parse_args(argv)
    on_stop(lambda: "rh-verify only reads, the datasets are unchanged")
    if args.record and not args.against:
        p.error("--record needs --against OTHER")
    bad = False
    reports = {}
    for root in [args.root] + ([args.against] if args.against else []):
        rep = reports[root] = verify(root, check_content=not args.no_content, progress=not args.no_progress)
        for prob in rep.problems:
            print(prob)
        status = "OK" if not rep.problems else f"{len(rep.problems)} problem(s)"
        print(f"rh-verify {root}: {rep.files_checked} files, {rep.frames_checked} frames checked: {status}")
        if rep.identity:
            print(f"  content identity {rep.identity['dataset']}")
            for key, sp in rep.identity["splits"].items():
                print(f"    {key:<24} {sp['digest']}  ({sp['frames']} frames)")
        bad |= bool(rep.problems)
    if args.against and not any(pr.path.endswith(layout.MANIFEST_JSON) and "missing" in pr.what
                                for r in reports.values() for pr in r.problems):
        cmp = layout.compare_datasets(args.root, args.against, reports[args.root].identity,
                                      reports[args.against].identity, progress=not args.no_progress,
                                      tier=args.tolerance)
        _print_comparison(cmp)
        print(f"rh-verify --against: {cmp.verdict}")
        if args.record:
            cmp.write(args.record)
            print(f"comparison written to {args.record}")
        bad |= not cmp.within_tolerance
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
