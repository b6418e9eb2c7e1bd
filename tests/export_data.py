"""Tiny datasets made once per test session by the real generator, shared by tests/test_export_*.py: protocol a
(32 px) and, for the published layout, protocol b from the `published_b` scene (64x36)."""
from __future__ import annotations

from pathlib import Path

_CACHE: dict[str, Path] = {}

TINY = ["--protocol", "a", "--subjects", "1", "--frames", "2", "--resolution", "32", "--spp", "2", "--aov-spp", "1",
        "--max-depth", "2", "--no-progress"]


PUBLISHED_B = ["--protocol", "published_b", "--subjects", "1", "--frames", "2", "--resolution", "64x36", "--spp", "2",
               "--aov-spp", "1", "--max-depth", "2", "--no-progress"]


def published_dataset(tmp_path_factory) -> Path:
    """Protocol b from the `published_b` scene (train renders albedo and normal too), non-square like 1280x720."""
    if "published_b" not in _CACHE:
        from rh_dataset.cli import main

        out = tmp_path_factory.mktemp("export_src_pub") / "ds"
        assert main([*PUBLISHED_B, "--out", str(out)]) == 0
        _CACHE["published_b"] = out
    return _CACHE["published_b"]


def tiny_dataset(tmp_path_factory) -> Path:
    if "a" not in _CACHE:
        from rh_dataset.cli import main

        out = tmp_path_factory.mktemp("export_src") / "ds"
        assert main([*TINY, "--out", str(out)]) == 0
        _CACHE["a"] = out
    return _CACHE["a"]
