"""Pictures beside a result: small display-space tiles of the evaluated region for a fixed, seeded set of frames.

In:  the frames of one `rh-eval` run (`select_fixed` before the loop), the per-frame rows (`select_extremes` after
     it), and for each chosen frame the `FramePrediction`/`FrameGroundTruth` the evaluator read (`frame_tiles`).
Out: `ThumbnailSet`, written by `write_thumbnails` as `<result stem>.thumbs/` (WebP tiles + `index.json`), which
     is all `rh-leaderboard` needs to show frames: neither the dataset nor the predictions.

Which frames (docs/EVALUATION.md, "Pictures"): per subject, the `PER_SUBJECT` test frames that come first when
ordered by sha256("rh-thumbs/1|<subject>|<frame index>") (the same for every method and every run: nothing about
the method enters), plus this method's own best, median and worst frame by its headline metric. Each tile is the
crop the metrics see (the convention's region, composited over its background, in display space), area-averaged
down to at most `TILE_PX` on its long side: the person fills the tile. Error maps: LDR-FLIP's per-pixel map of
that crop for image and albedo (the map FLIP's mean is taken of), the angle between normals (0-90 degrees) for
normals; both through the magma colour map.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rh_common.colourspace import quantize8
from rh_common.imageio import atomic_dir, read_json, write_json, write_webp

from .conventions import BACKGROUNDS, Convention, albedo_to_space, composite, compute_region
from .dataset_io import albedo_from_stored, display_from_stored, normal_from_stored
from .metrics.flip import flip_map
from .metrics.normal import angular_error_map
from .resample import shrink_area
from .scoring import match_ground_truth

__all__ = ["SELECTION_SEED", "PER_SUBJECT", "TILE_PX", "THUMBS_FORMAT", "seeded_rank", "select_fixed",
           "headline_metric", "select_extremes", "frame_crops", "frame_tiles", "ThumbnailSet", "thumbs_dir_for",
           "write_thumbnails", "light_summary", "collect_thumbnails"]

SELECTION_SEED = "rh-thumbs/1"
PER_SUBJECT = 4
TILE_PX = 128
WEBP_QUALITY = 80
THUMBS_FORMAT = "rh-eval-thumbs/1"
NORMAL_ERROR_MAX_DEG = 90.0
# (column, lower is better): the first one a run has is its headline (image LPIPS ranks the leaderboard)
HEADLINES = (("image_lpips", True), ("image_psnr", False), ("image_ssim", False), ("image_flip", True),
             ("image_dists", True), ("normal_deg", True))


def seeded_rank(subject: str, index: int) -> str:
    """The frame's place in the fixed selection: a hash of its name only, so every method and run agrees."""
    return hashlib.sha256(f"{SELECTION_SEED}|{subject}|{int(index)}".encode()).hexdigest()


def select_fixed(frames, per_subject: int = PER_SUBJECT) -> set[str]:
    """Keys ('subject/frame_NNNNNN') of the fixed frames among `frames` (objects with .subject, .index, .key)."""
    by_subject: dict[str, list] = {}
    for f in frames:
        by_subject.setdefault(f.subject, []).append(f)
    keys = set()
    for fs in by_subject.values():
        fs.sort(key=lambda f: seeded_rank(f.subject, f.index))
        keys.update(f.key for f in fs[:per_subject])
    return keys


def headline_metric(cols: list[str]) -> tuple[str, bool] | None:
    for c, low in HEADLINES:
        if c in cols:
            return c, low
    return None


def select_extremes(rows: list[dict], keys: list[str], cols: list[str]) -> dict[str, str]:
    """{'best'|'median'|'worst': key} of the frames with a defined headline value (ties: dataset order). The median
    is the lower middle of the sorted list. +inf PSNR (identical) is the best there is."""
    head = headline_metric(cols)
    if head is None:
        return {}
    col, low = head
    vals = [(float(r[col]), i) for i, r in enumerate(rows) if isinstance(r.get(col), (int, float))
            and not math.isnan(r[col])]
    if not vals:
        return {}
    vals.sort(key=lambda vi: ((vi[0] if low else -vi[0]), vi[1]))
    return {"best": keys[vals[0][1]], "median": keys[vals[(len(vals) - 1) // 2][1]], "worst": keys[vals[-1][1]]}


def light_summary(light) -> dict:
    """The frame JSON's light, without its SH coefficients: the scalar fields a caption can show."""
    if not isinstance(light, dict):
        return {}
    return {k: v for k, v in sorted(light.items()) if isinstance(v, (str, int, float, bool))}


# ------------------------------------------------------------------------------------------------ pixels
def frame_crops(pred, gt, conv: Convention) -> dict[str, np.ndarray] | None:
    """The crops the metrics compare, float64 in [0, 1] (normals: vectors), keyed `<layer>` and `<layer>_gt`, plus
    `inside` (the ground-truth mask in the crop). The same conversions, in the same order, as
    `scoring.prepare_frame` (tests/test_eval_thumbnails.py checks them against its network inputs). None: empty
    ground-truth mask (no region)."""
    gt = match_ground_truth(pred, gt, conv)
    region = compute_region(gt.mask, conv)
    if region.empty:
        return None
    crop = (slice(region.y0, region.y1), slice(region.x0, region.x1))
    out = {"inside": gt.mask[crop] >= conv.mask_threshold, "region": region}
    if pred.image is not None:
        out["image"] = composite(display_from_stored(pred.image[crop], gt), region, conv)
        out["image_gt"] = composite(display_from_stored(gt.need("image")[crop], gt), region, conv)
    if pred.albedo is not None:
        out["albedo"] = composite(albedo_to_space(albedo_from_stored(pred.albedo)[crop], conv), region, conv)
        out["albedo_gt"] = composite(albedo_to_space(albedo_from_stored(gt.need("albedo"))[crop], conv), region,
                                     conv)
    if pred.normal is not None:
        out["normal"] = normal_from_stored(pred.normal[crop])
        out["normal_gt"] = normal_from_stored(gt.need("normal")[crop])
    return out


def _tile_size(h: int, w: int) -> tuple[int, int]:
    s = max(h, w) / TILE_PX
    if s <= 1:
        return h, w
    return max(1, round(h / s)), max(1, round(w / s))


_MAGMA: np.ndarray | None = None


def _colourise(v01: np.ndarray) -> np.ndarray:
    """(h, w) values in [0, 1] through magma (256-entry table) to (h, w, 3) uint8."""
    global _MAGMA
    if _MAGMA is None:
        from matplotlib import colormaps

        _MAGMA = quantize8(colormaps["magma"](np.linspace(0.0, 1.0, 256))[:, :3])
    return _MAGMA[quantize8(v01)]


def frame_tiles(pred, gt, conv: Convention) -> dict[str, np.ndarray] | None:
    """uint8 (h, w, 3) tiles: for each layer the prediction has, `<layer>`, `<layer>_gt` and `<layer>_err`."""
    c = frame_crops(pred, gt, conv)
    if c is None:
        return None
    size = _tile_size(*c["inside"].shape)
    tiles = {}
    for layer in ("image", "albedo"):
        if layer in c:
            err = flip_map(c[layer], c[layer + "_gt"], data_range=1.0, ppd=conv.flip_ppd)
            tiles[layer] = quantize8(shrink_area(c[layer], size))
            tiles[layer + "_gt"] = quantize8(shrink_area(c[layer + "_gt"], size))
            tiles[layer + "_err"] = _colourise(shrink_area(err[..., None], size)[..., 0])
    if "normal" in c:
        inside = c["inside"]
        region = c["region"]
        alpha = region.alpha if region.alpha is not None else inside.astype(np.float64)
        bg = np.asarray(BACKGROUNDS[conv.background], dtype=np.float64)
        for name in ("normal", "normal_gt"):
            n = c[name]
            length = np.linalg.norm(n, axis=-1, keepdims=True)
            rgb = np.divide(n, length, out=np.zeros_like(n), where=length > 0) * 0.5 + 0.5  # the usual picture
            tiles[name] = quantize8(shrink_area(alpha[..., None] * rgb + (1 - alpha[..., None]) * bg, size))
        deg = np.where(inside, angular_error_map(c["normal"], c["normal_gt"]), 0.0)  # compared inside the mask
        tiles["normal_err"] = _colourise(shrink_area((deg / NORMAL_ERROR_MAX_DEG)[..., None], size)[..., 0])
    return tiles


# ------------------------------------------------------------------------------------------------ files
@dataclass
class ThumbnailSet:
    """What `write_thumbnails` writes: the selection's record and, per frame, its tiles and index entry."""

    selection: dict
    frames: list[dict] = field(default_factory=list)  # index entries (name, subject, frame, roles, light, scores)
    tiles: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # frame name -> tile name -> pixels


def collect_thumbnails(frames, rows: list[dict], cols: list[str], fixed: set[str], tiles: dict,
                       make_tiles) -> ThumbnailSet:
    """The selection of one run: `frames` (its `PredFrame`s) with their CSV `rows`, the `fixed` keys whose tiles
    the loop made (`tiles`: key -> tiles or None), and `make_tiles(frame)` for the extremes it did not."""
    keys = [pf.gt.key for pf in frames]
    roles: dict[str, list[str]] = {k: ["fixed"] for k in fixed}
    for role, k in select_extremes(rows, keys, cols).items():
        roles.setdefault(k, []).append(role)
    head = headline_metric(cols)
    out = ThumbnailSet({"seed": SELECTION_SEED, "per_subject": PER_SUBJECT, "tile_px": TILE_PX,
                        "headline": head[0] if head else None, "lower_is_better": head[1] if head else None,
                        "rule": f"per subject the {PER_SUBJECT} test frames first by sha256('{SELECTION_SEED}|"
                                f"<subject>|<frame index>'), plus this method's best, median (lower middle) and "
                                f"worst frame by its headline metric; frames with an empty ground-truth mask have "
                                f"no tiles"})
    for pf, row, k in zip(frames, rows, keys):
        if k not in roles:
            continue
        t = tiles[k] if k in tiles else make_tiles(pf)
        if t is None:
            continue
        scores = {c: ("inf" if isinstance(row.get(c), float) and row[c] == math.inf else row.get(c)) for c in cols}
        out.tiles[k] = t
        out.frames.append({"name": k, "subject": pf.gt.subject, "frame": pf.gt.index, "roles": roles[k],
                           **({"view": pf.gt.view} if pf.gt.view is not None else {}),
                           "seeded_rank": seeded_rank(pf.gt.subject, pf.gt.index), "scores": scores,
                           "light": light_summary(read_json(pf.gt.json_path).get("light"))})
    return out


def thumbs_dir_for(json_path: Path) -> Path:
    return json_path.with_name(json_path.stem + ".thumbs")


def write_thumbnails(folder: Path, thumbs: ThumbnailSet) -> dict:
    """Write the tiles and `index.json` into `folder`, replacing it whole (`atomic_dir`: a reader sees the old set
    or the new one). Returns the result's `thumbnails`
    record (folder name, counts, bytes)."""
    folder = Path(folder)
    with atomic_dir(folder) as tmp:
        entries, total = [], 0
        for entry in thumbs.frames:
            files = {}
            for name, px in sorted(thumbs.tiles[entry["name"]].items()):
                rel = f"{entry['name']}_{name}.webp"  # '<subject>/frame_NNNNNN_<tile>.webp'
                write_webp(tmp / rel, px, quality=WEBP_QUALITY)
                total += (tmp / rel).stat().st_size
                files[name] = rel
            entries.append({**entry, "tiles": files})
        index = {"format": THUMBS_FORMAT, "tile_px": TILE_PX, "webp_quality": WEBP_QUALITY,
                 "selection": thumbs.selection, "frames": entries, "tile_bytes": total,
                 "error_maps": {"image": "LDR-FLIP per-pixel map of the evaluated crop, [0, 1], magma",
                                "albedo": "LDR-FLIP per-pixel map of the albedo crop (albedo space), [0, 1], magma",
                                "normal": f"angle between normals inside the mask, 0-{NORMAL_ERROR_MAX_DEG:g} "
                                          f"degrees, magma"}}
        write_json(tmp / "index.json", index)
    return {"dir": folder.name, "index": "index.json", "n_frames": len(thumbs.frames), "tile_bytes": total,
            "format": THUMBS_FORMAT}
