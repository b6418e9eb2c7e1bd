"""The generator's side of writing a dataset: frames with their render diagnostics, and contact sheets.

In: a split folder, a frame index, the rendered layers and the frame metadata (`rh_dataset.generate.frame_meta`).
Out: the frame files through `rh_common.layout` (which owns the layout, the frame JSON and the manifest), with the
beauty image's firefly count added to `render`; `contact_sheet.png` previews per split.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
from PIL import Image

from rh_common import layout
from rh_common.imageio import write_png

__all__ = ["write_frame", "contact_sheet"]


def write_frame(split_dir: str | os.PathLike, index: int, layers: Mapping[str, np.ndarray], meta: dict,
                workers: int | None = None) -> Path:
    """`rh_common.layout.write_frame` (`workers`: its encoding threads), with `render.fireflies` recorded when the
    frame has an image."""
    record = dict(meta)
    if "image" in layers and np.all(np.isfinite(layers["image"])):  # a NaN image: layout.write_frame refuses it
        # Reported, never hidden: the count of isolated over-bright pixels of the image as written (no clamping).
        from rh_dataset.render.passes import count_fireflies

        record["render"] = {**record.get("render", {}), "fireflies": count_fireflies(layers["image"])}
    return layout.write_frame(split_dir, index, layers, record, workers=workers)


def contact_sheet(split_dir: str | os.PathLike, indices: list[int], layers: Iterable[str], *, tile: int = 128,
                  max_frames: int = 24) -> Path | None:
    """A grid of PNG previews: one row per shown frame group, columns = image/albedo/normal/mask when present."""
    split_dir = Path(split_dir)
    cols = [l for l in ("image", "albedo", "normal", "mask") if l in set(layers)]
    if not indices or not cols:
        return None
    if len(indices) > max_frames:
        pick = np.linspace(0, len(indices) - 1, max_frames).round().astype(int)
        indices = [indices[i] for i in sorted(set(pick))]
    per_row = max(1, 8 // len(cols)) if len(cols) > 1 else 8
    n_rows = -(-len(indices) // per_row)
    gap = 2
    W = per_row * (len(cols) * tile + gap)
    sheet = Image.new("RGB", (W, n_rows * (tile + gap)), (24, 24, 24))
    for k, idx in enumerate(indices):
        r, c = divmod(k, per_row)
        for j, layer in enumerate(cols):
            name = [f for f in layout.layer_files(idx, layer) if f.endswith(".png")][0]
            with Image.open(split_dir / name) as im:
                im = im.convert("RGB")
                im.thumbnail((tile, tile))
                x = c * (len(cols) * tile + gap) + j * tile + (tile - im.width) // 2
                y = r * (tile + gap) + (tile - im.height) // 2
                sheet.paste(im, (x, y))
    out = split_dir / layout.CONTACT_SHEET
    write_png(out, np.asarray(sheet))
    return out
