"""A tiny protocol-a dataset made once per test session by the real generator, shared by tests/test_export_*.py."""
from __future__ import annotations

from pathlib import Path

_CACHE: dict[str, Path] = {}

TINY = ["--protocol", "a", "--subjects", "1", "--frames", "2", "--resolution", "32", "--spp", "2", "--aov-spp", "1",
        "--max-depth", "2", "--no-progress"]


def tiny_dataset(tmp_path_factory) -> Path:
    if "a" not in _CACHE:
        from rh_dataset.cli import main

        out = tmp_path_factory.mktemp("export_src") / "ds"
        assert main([*TINY, "--out", str(out)]) == 0
        _CACHE["a"] = out
    return _CACHE["a"]
