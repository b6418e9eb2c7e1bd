"""The dataset manifest: `manifest.json` = {"format": "rh-manifest/1", "files": {relative path: {"sha256", "bytes"}}}.

In: a dataset root. Out: the manifest written last by a writer (every file but itself and temporaries), read
back, and each listed file checked against it (what `rh-verify` reports, before it decodes any image).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from rh_common.imageio import read_json, sha256_file, write_json

from .paths import MANIFEST_JSON

__all__ = ["MANIFEST_FORMAT", "ManifestEntry", "write_manifest", "read_manifest", "unlisted_files", "check_entry"]

MANIFEST_FORMAT = "rh-manifest/1"


@dataclass(frozen=True)
class ManifestEntry:
    sha256: str
    bytes: int


def _is_listed(p: Path) -> bool:
    return p.is_file() and p.name != MANIFEST_JSON and not p.name.endswith(".tmp")


def write_manifest(root: str | os.PathLike) -> Path:
    """sha256 and size of every file under `root` but the manifest itself and temporaries, sorted by path."""
    root = Path(root)
    entries = {}
    for p in sorted(root.rglob("*")):
        if _is_listed(p):
            entries[p.relative_to(root).as_posix()] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
    out = root / MANIFEST_JSON
    write_json(out, {"format": MANIFEST_FORMAT, "files": entries})
    return out


def read_manifest(root: str | os.PathLike) -> dict[str, ManifestEntry]:
    """The manifest's entries by relative path. FileNotFoundError if there is none (an unfinished run); ValueError
    if it is not a manifest of this format."""
    path = Path(root) / MANIFEST_JSON
    data = read_json(path)
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or not isinstance(data.get("files"), dict):
        raise ValueError(f"{path}: not an {MANIFEST_FORMAT} manifest (expected {{'format', 'files'}})")
    try:
        return {rel: ManifestEntry(str(e["sha256"]), int(e["bytes"])) for rel, e in data["files"].items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: malformed entry ({exc!r})") from exc


def unlisted_files(root: str | os.PathLike, listed: dict[str, ManifestEntry]) -> list[str]:
    """Files on disk the manifest does not list (temporaries included: a finished dataset has none), sorted."""
    root = Path(root)
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file() and p.name != MANIFEST_JSON}
    return sorted(on_disk - set(listed))


def check_entry(root: str | os.PathLike, rel: str, entry: ManifestEntry) -> str | None:
    """What is wrong with one listed file (missing, truncated, altered), or None if it matches."""
    p = Path(root) / rel
    if not p.is_file():
        return "missing"
    size = p.stat().st_size
    if size != entry.bytes:
        kind = "truncated" if size < entry.bytes else "altered"
        return f"{kind}: {size} bytes, manifest says {entry.bytes}"
    if sha256_file(p) != entry.sha256:
        return "altered: sha256 differs from the manifest"
    return None
