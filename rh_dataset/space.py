"""How many bytes a run will write, and whether the target file system holds them.

In: a `DatasetPlan` (protocol, subjects, splits and their layers, resolution, output folder). Out: the bytes still to
write (frames whose JSON is not on disk yet, at measured bytes per pixel of every layer file), and `check_space`,
which refuses a run the free space (`shutil.disk_usage`) cannot hold, with one line (`rh-generate
--no-space-check` skips it).

The per-file figures are the largest bytes per pixel `python bench/bench_sizes.py --preset draft --resolutions 128
256 512 --frames 3` measured (protocol a, subject 0; README, "Stopping, resuming and disk space"): the estimate
errs high. The `draft`
preset's noise makes the beauty EXR at least as large as `standard`'s (path-tracing noise is what its ZIP cannot
compress), so the figures hold for every preset.
"""
from __future__ import annotations

import shutil

from rh_common import layout
from rh_common.interrupt import human_bytes, nearest_folder

__all__ = ["BYTES_PER_PIXEL", "FIXED_BYTES", "frame_bytes", "remaining_bytes", "frames_finished", "check_space",
           "SpaceError"]

BYTES_PER_PIXEL = {  # bench/bench_sizes.py --preset draft --resolutions 128 256 512 --frames 3: the largest
    "image.exr": 11.918,  # float32 RGB is 12 bytes a pixel raw: ZIP cannot compress path-tracing noise
    "image.png": 1.363,
    "mask.png": 0.044,
    "albedo.exr": 1.094,
    "albedo.png": 0.185,
    "normal.exr": 1.350,
    "normal.png": 0.277,
    "depth.exr": 0.476,
}
FIXED_BYTES = {"json": 32_372, "contact_sheet": 87_492}
"""Bytes per frame JSON (a test frame's; a train frame's is 5.5 kB) and per split's contact sheet."""

# No margin on top: the figures are per-file maxima over three resolutions (PNG overheads make small frames dearer
# per pixel), so a 512x512 test frame is estimated at 4.4 MB where the bench measured 3.8 MB.
MARGIN = 1.0


class SpaceError(RuntimeError):
    """The output's file system cannot hold the run; the message names the folder, the need and the fix."""


def frame_bytes(layers, width: int, height: int) -> int:
    """Estimated bytes of one frame with these layers at this size (its JSON included)."""
    px = width * height
    total = FIXED_BYTES["json"]
    for layer in layers:
        for name in layout.layer_files(0, layer):
            total += BYTES_PER_PIXEL[name.split("_", 2)[2]] * px
    return int(total)


def frames_finished(plan) -> tuple[int, int]:
    """(frames whose JSON is on disk, frames of the plan). A frame's JSON is written last, so this is what a
    rerun skips (unless a file was altered since, which the rerun's checksums catch)."""
    done = total = 0
    for s in range(plan.spec.subjects):
        for split in plan.spec.splits:
            for _, d in plan.view_dirs(s, split):  # a multi-view split: every camera's frames
                total += split.frames
                done += sum(layout.frame_json_path(d, i).is_file() for i in range(split.frames))
    return done, total


def remaining_bytes(plan) -> int:
    """Bytes the plan still has to write: every frame whose JSON is missing, the contact sheets, with the margin."""
    total = 0
    for s in range(plan.spec.subjects):
        for split in plan.spec.splits:
            for _, d in plan.view_dirs(s, split):
                missing = sum(not layout.frame_json_path(d, i).is_file() for i in range(split.frames))
                if missing:
                    total += missing * frame_bytes(split.layers, plan.spec.width, plan.spec.height)
                    total += FIXED_BYTES["contact_sheet"]
    return int(total * MARGIN)


def check_space(plan) -> int:
    """Refuse (SpaceError) a run whose remaining bytes exceed the free space of --out's file system; returns the
    estimate."""
    need = remaining_bytes(plan)
    where = nearest_folder(plan.out)
    free = shutil.disk_usage(where).free
    if need > free:
        raise SpaceError(
            f"{plan.out} needs about {human_bytes(need)} for this run but its file system ({where}) has "
            f"{human_bytes(free)} free: free space, choose another --out, generate fewer --subjects/--frames, or "
            f"pass --no-space-check to start anyway (the run then stops cleanly when the disk fills, and resumes)")
    return need
