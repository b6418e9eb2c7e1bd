"""The ground-truth feature cache of `rh-eval`: network features by key, in memory (an LRU bounded in bytes) and
optionally in a folder of `.pt` files, so a second method evaluated against the same dataset skips every
ground-truth forward pass.

In: a key (hex digest: ground-truth file sha256s, convention, network, weight sha256s; built by `rh_eval.evaluate`)
and a feature structure (tensors in lists/tuples). Out: the same structure back, or None.
"""
from __future__ import annotations

import sys
from collections import OrderedDict
from pathlib import Path
from typing import Any

import torch

__all__ = ["FeatureCache"]


class FeatureCache:
    """Ground-truth network features: an in-memory LRU bounded in bytes, optionally backed by a folder of `.pt`
    files (read back with `torch.load(weights_only=True)`). Keys are hex digests of (GT file sha256s, convention,
    network, weight sha256)."""

    def __init__(self, max_bytes: int = 2 << 30, cache_dir: Path | None = None) -> None:
        self.max_bytes = max_bytes
        self.cache_dir = Path(cache_dir) if cache_dir else None
        self._mem: OrderedDict[str, tuple[Any, int]] = OrderedDict()
        self._bytes = 0
        self.hits = self.misses = self.disk_hits = 0

    @staticmethod
    def _nbytes(obj) -> int:
        if isinstance(obj, torch.Tensor):
            return obj.numel() * obj.element_size()
        if isinstance(obj, (list, tuple)):
            return sum(FeatureCache._nbytes(o) for o in obj)
        return 0

    def get(self, key: str):
        if key in self._mem:
            self._mem.move_to_end(key)
            self.hits += 1
            return self._mem[key][0]
        if self.cache_dir is not None:
            path = self.cache_dir / f"{key}.pt"
            if path.is_file():
                try:
                    obj = torch.load(path, map_location="cpu", weights_only=True)
                except Exception as exc:  # a damaged cache entry is recomputed, and said so
                    print(f"rh-eval: ignoring unreadable cache entry {path} ({exc})", file=sys.stderr)
                else:
                    self.disk_hits += 1
                    self._remember(key, obj)
                    return obj
        self.misses += 1
        return None

    def put(self, key: str, obj) -> None:
        self._remember(key, obj)
        if self.cache_dir is not None:
            from rh_common.imageio import atomic_path

            self.cache_dir.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.cache_dir / f"{key}.pt") as tmp:
                torch.save(_clone(obj), tmp)  # a view would save its whole batch

    def _remember(self, key: str, obj) -> None:
        n = self._nbytes(obj)
        if n > self.max_bytes:
            return
        self._mem[key] = (obj, n)
        self._bytes += n
        while self._bytes > self.max_bytes:
            _, (_, m) = self._mem.popitem(last=False)
            self._bytes -= m


def _clone(obj):
    if isinstance(obj, torch.Tensor):
        return obj.clone()
    return type(obj)(_clone(o) for o in obj)
