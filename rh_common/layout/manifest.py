"""The dataset manifest: `manifest.json` = {"format": "rh-manifest/2", "files": {relative path: {"sha256", "bytes"}},
"identity": {content identity}}.

In: a dataset root. Out: the manifest written last by a writer (every file but itself and temporaries, and the
content identity of its frames: `rh_common.identity`), read back, and each listed file checked against it (what
`rh-verify` reports, before it decodes any image). Manifests of format 1 (no identity) are still read; their
identity is None until the manifest is written again.

"identity" = {"format": "rh-content/1", "dataset": digest, "splits": {"protocol_a/test": {"digest", "frames"}},
"frames": {frame JSON path: digest}}: a split is one protocol's split over every subject (what rh-eval scores);
the dataset digest combines the splits'.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from rh_common import identity as content
from rh_common.imageio import read_json, sha256_file, write_json

from .paths import LOG_DIR, MANIFEST_JSON, frame_key, iter_frame_jsons, protocol_dir

__all__ = ["MANIFEST_FORMAT", "ManifestEntry", "write_manifest", "read_manifest", "read_identity", "content_identity",
           "split_key", "split_identity", "unlisted_files", "check_entry"]

MANIFEST_FORMAT = "rh-manifest/2"
_READABLE = ("rh-manifest/1", MANIFEST_FORMAT)


@dataclass(frozen=True)
class ManifestEntry:
    sha256: str
    bytes: int


def _is_log(root: Path, p: Path) -> bool:
    return p.relative_to(root).parts[0] == LOG_DIR


def _is_listed(root: Path, p: Path) -> bool:
    return p.is_file() and p.name != MANIFEST_JSON and not p.name.endswith(".tmp") and not _is_log(root, p)


def split_key(protocol: str, split: str) -> str:
    """'a', 'test' -> 'protocol_a/test': how the identity names a split."""
    return f"{protocol_dir(protocol)}/{split}"


def content_identity(root: str | os.PathLike) -> dict:
    """The content identity of every frame under `root` (decodes every layer file: seconds per hundred frames).
    A frame that cannot be read is left out (`rh-verify` names it)."""
    root = Path(root)
    frames: dict[str, str] = {}
    by_split: dict[str, dict[str, str]] = {}
    for fj in iter_frame_jsons(root):
        rel = fj.relative_to(root).as_posix()
        parts = rel.split("/")
        subject, pdir, split = parts[:3]
        view = parts[3] if len(parts) == 5 else None  # a multi-view split's camera folder
        try:
            frames[rel] = digest = content.frame_digest(fj)
        except (ValueError, KeyError, TypeError, OSError):  # not a frame record, or a layer missing or unreadable:
            continue                                       # rh-verify reports it; it is in no split's identity
        by_split.setdefault(f"{pdir}/{split}", {})[frame_key(subject, int(fj.stem[len("frame_"):]), view)] = digest
    splits = {k: {"digest": content.combine(v), "frames": len(v)} for k, v in sorted(by_split.items())}
    return {"format": content.IDENTITY_FORMAT, "dataset": content.combine({k: v["digest"] for k, v in splits.items()}),
            "splits": splits, "frames": frames}


def write_manifest(root: str | os.PathLike) -> Path:
    """sha256 and size of every file under `root` but the manifest itself and temporaries, sorted by path, and the
    content identity of its frames."""
    root = Path(root)
    entries = {}
    for p in sorted(root.rglob("*")):
        if _is_listed(root, p):
            entries[p.relative_to(root).as_posix()] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
    out = root / MANIFEST_JSON
    write_json(out, {"format": MANIFEST_FORMAT, "files": entries, "identity": content_identity(root)})
    return out


def _read(root: str | os.PathLike) -> dict:
    path = Path(root) / MANIFEST_JSON
    data = read_json(path)
    if not isinstance(data, dict) or data.get("format") not in _READABLE or not isinstance(data.get("files"), dict):
        raise ValueError(f"{path}: not an {MANIFEST_FORMAT} manifest (expected {{'format', 'files', 'identity'}})")
    if data["format"] == MANIFEST_FORMAT and not isinstance(data.get("identity"), dict):
        raise ValueError(f"{path}: {MANIFEST_FORMAT} manifest without its 'identity' (rewrite it: rerun rh-generate)")
    return data


def read_identity(root: str | os.PathLike) -> dict | None:
    """The manifest's content identity, or None for a format-1 manifest (written before identities existed)."""
    return _read(root).get("identity")


def split_identity(root: str | os.PathLike, protocol: str, split: str) -> str | None:
    """The recorded content identity of one split (what rh-eval scored), or None (format-1 manifest, or no such
    split)."""
    ident = read_identity(root)
    return ((ident or {}).get("splits", {}).get(split_key(protocol, split)) or {}).get("digest")


def read_manifest(root: str | os.PathLike) -> dict[str, ManifestEntry]:
    """The manifest's entries by relative path. FileNotFoundError if there is none (an unfinished run); ValueError
    if it is not a manifest of a readable format."""
    path = Path(root) / MANIFEST_JSON
    data = _read(root)
    try:
        return {rel: ManifestEntry(str(e["sha256"]), int(e["bytes"])) for rel, e in data["files"].items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: malformed entry ({exc!r})") from exc


def unlisted_files(root: str | os.PathLike, listed: dict[str, ManifestEntry]) -> list[str]:
    """Files on disk the manifest does not list (temporaries included: a finished dataset has none), sorted."""
    root = Path(root)
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*")
               if p.is_file() and p.name != MANIFEST_JSON and not _is_log(root, p)}
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
