"""Exports of a finished dataset to other layouts: the published Relighting Humans one, ZJU-MoCap, USD stages.

`rh-export --dataset D --protocol a --format relighting-humans|zju-mocap|usd --out O`; docs/INTEROP.md says what
each format holds and how it differs from the original.
"""
from .cli import FORMATS, export_dataset, main
from .common import ExportError, FrameRef, iter_frames

__all__ = ["FORMATS", "ExportError", "FrameRef", "export_dataset", "iter_frames", "main"]
