"""`rh-verify DIR`: find every missing, truncated, altered or extra file and every NaN/Inf in a dataset."""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rh_common.imageio import ImageFileError, read_exr, read_json, read_png, sha256_file

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
    manifest_path = root / "manifest.json"
    if not manifest_path.is_file():
        rep.problems.append(Problem(str(manifest_path), "missing: not a finished dataset (rerun rh-generate)"))
        return rep
    try:
        listed = read_json(manifest_path)["files"]
    except (ValueError, KeyError) as exc:
        rep.problems.append(Problem(str(manifest_path), f"unreadable manifest ({exc})"))
        return rep
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file() and p.name != "manifest.json"}
    for rel in sorted(on_disk - set(listed)):
        what = "leftover temporary file from an interrupted write" if rel.endswith(".tmp") else "not in the manifest"
        rep.problems.append(Problem(rel, what))
    from tqdm import tqdm

    for rel, info in tqdm(sorted(listed.items()), disable=not progress, unit="file", desc="verify"):
        p = root / rel
        rep.files_checked += 1
        if not p.is_file():
            rep.problems.append(Problem(rel, "missing"))
            continue
        size = p.stat().st_size
        if size != info["bytes"]:
            kind = "truncated" if size < info["bytes"] else "altered"
            rep.problems.append(Problem(rel, f"{kind}: {size} bytes, manifest says {info['bytes']}"))
            continue
        if sha256_file(p) != info["sha256"]:
            rep.problems.append(Problem(rel, "altered: sha256 differs from the manifest"))
            continue
        if check_content:
            msg = _check_content(p)
            if msg:
                rep.problems.append(Problem(rel, msg))
    # Frame JSONs list their own layer files: a frame must be whole even if the manifest was rebuilt around a hole.
    for fj in sorted(root.glob("subject_*/protocol_*/*/frame_*.json")):
        rep.frames_checked += 1
        try:
            files = read_json(fj)["files"]
        except (ValueError, KeyError):
            continue  # already reported as unreadable above
        for name in files:
            if not (fj.parent / name).is_file():
                rep.problems.append(Problem((fj.parent / name).relative_to(root).as_posix(),
                                            f"missing, listed by {fj.name}"))
    return rep


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rh-verify",
                                description="Check a dataset against its manifest: every file present, with the "
                                            "recorded size and sha256, readable, and free of NaN/Inf; no extra or "
                                            "temporary files. Exit status 0 if clean, 1 if any problem.")
    p.add_argument("root", type=Path, help="dataset folder (the one holding manifest.json)")
    p.add_argument("--no-content", action="store_true", help="checksums only; skip decoding images for NaN/Inf")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    rep = verify(args.root, check_content=not args.no_content, progress=not args.no_progress)
    for prob in rep.problems:
        print(prob)
    status = "OK" if not rep.problems else f"{len(rep.problems)} problem(s)"
    print(f"rh-verify: {rep.files_checked} files, {rep.frames_checked} frames checked: {status}")
    return 0 if not rep.problems else 1


if __name__ == "__main__":
    sys.exit(main())
