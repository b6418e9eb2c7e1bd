"""`rh-verify DIR`: find every missing, truncated, altered or extra file and every NaN/Inf in a dataset.

In: a dataset root, read through `rh_common.layout` (its manifest and frame records). Out: a `Report` listing each
problem with the file it concerns; exit status 1 if there is any.
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
    return rep


@command("rh-verify")
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rh-verify",
                                description="Check a dataset against its manifest: every file present, with the "
                                            "recorded size and sha256, readable, and free of NaN/Inf; no extra or "
                                            "temporary files. Exit status 0 if clean, 1 if any problem.")
    p.add_argument("root", type=Path, help="dataset folder (the one holding manifest.json)")
    p.add_argument("--no-content", action="store_true", help="checksums only; skip decoding images for NaN/Inf")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_debug_flag(p)
    args = p.parse_args(argv)
    on_stop(lambda: "rh-verify only reads, the dataset is unchanged")
    rep = verify(args.root, check_content=not args.no_content, progress=not args.no_progress)
    for prob in rep.problems:
        print(prob)
    status = "OK" if not rep.problems else f"{len(rep.problems)} problem(s)"
    print(f"rh-verify: {rep.files_checked} files, {rep.frames_checked} frames checked: {status}")
    return 0 if not rep.problems else 1


if __name__ == "__main__":
    sys.exit(main())
