"""Tiny datasets made once per test session by the real generator, shared by tests/test_export_*.py: protocol a
(32 px) and, for the published layout, protocol b from the `published_b` scene (64x36)."""
from __future__ import annotations

from pathlib import Path

_CACHE: dict[str, Path] = {}

_RENDER = ["--subjects", "1", "--frames", "2", "--spp", "2", "--aov-spp", "1", "--max-depth", "2", "--drape", "coarse",
           "--no-progress"]
TINY = ["--protocol", "a", "--resolution", "32", *_RENDER]
PUBLISHED_B = ["--protocol", "published_b", "--resolution", "64x36", *_RENDER]


def _dataset(tmp_path_factory, args: list[str]) -> Path:
    key = args[1]
    if key not in _CACHE:
        from rh_dataset.cli import main

        out = tmp_path_factory.mktemp(f"export_src_{key}") / "ds"
        assert main([*args, "--out", str(out)]) == 0
        _CACHE[key] = out
    return _CACHE[key]


def tiny_dataset(tmp_path_factory) -> Path:
    return _dataset(tmp_path_factory, TINY)


def published_dataset(tmp_path_factory) -> Path:
    """Protocol b from the `published_b` scene (train renders albedo and normal too), non-square like 1280x720."""
    return _dataset(tmp_path_factory, PUBLISHED_B)
