"""One frame: a `DatasetPlan`, a `SubjectSource` and its `Subject`, a split and a frame index in; the frame's layer
files and JSON on disk and a `FrameResult` (what was written, the seconds of each stage) out.

`render_frame_to_disk` is the one function that renders and writes a frame: the local backend, the Ray backend
(through `run_subject`) and bench/bench_generate.py all call it, so they render the same scene (camera, culling,
lights, settings). `run_subject` renders a subject's missing frames and writes its contact sheets.
"""
from __future__ import annotations

import dataclasses
import functools
import importlib.metadata as md
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from rh_common import layout, sh
from rh_dataset import __version__
from rh_dataset.generate.folder import keep_character_record
from rh_dataset.generate.plan import DatasetPlan, FrameTask, light_library, olat_frame
from rh_dataset.generate.seeding import rng_for
from rh_dataset.generate.subjects import Subject, SubjectSource
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant
from rh_dataset.spec import SplitSpec
from rh_dataset.writer import contact_sheet, write_frame

__all__ = ["FrameResult", "OnFrame", "render_frame_to_disk", "run_subject", "light_for", "olat_light",
           "exposure_for", "frame_meta", "versions"]

OnFrame = Callable[[FrameTask, bool], None]
"""Called once per frame of a run: (the frame, whether it was already complete and skipped)."""


@dataclass(frozen=True)
class FrameResult:
    task: FrameTask
    json_path: Path
    seconds: dict[str, float]
    """Wall time of each stage: pose, light, load, beauty, aov (and denoise), meta, write; total is their sum."""
    scene_model: dict
    """What the renderer built (also the frame JSON's render.scene_model)."""


def light_for(plan: DatasetPlan, split: SplitSpec, s: int, i: int, library: dict):
    """The frame's light: one per (subject, split) for a 'fixed' split, the frame's direction of the set for an
    'olat' split (no random draw), else one per frame (from the protocol's light mixture when it has one)."""
    from rh_dataset.lights import build_light, sample_light

    if split.light == "olat":
        return olat_light(split, i)
    protocol_key = plan.spec.protocol
    if split.light == "fixed":
        rng = rng_for(plan.seed, "light", s, protocol_key, split.name)
    else:
        rng = rng_for(plan.seed, "light", s, protocol_key, split.name, i)
    mixture = plan.spec.light_mixture if split.light == "random" else None  # training lights stay as they were
    spec = sample_light(rng, library, exposure_ev_range=plan.spec.exposure_ev_range, allow_sunsky=plan.spec.sunsky,
                        mixture=mixture)
    return build_light(spec)


def olat_light(split: SplitSpec, i: int):
    """The OLAT light of frame i of an olat split: the set's direction i % n, at the strength `olat_scale` gives."""
    from rh_dataset.lights import LightSpec, build_light, olat_directions, olat_params, olat_scale

    o = split.olat
    k = olat_frame(split, i)[1]
    az, el = olat_directions(o.directions)[k]
    params = olat_params(az, el, o.radius_deg, o.colour)
    return build_light(LightSpec("olat", f"{o.directions}_{k:02d}", "", 0.0, olat_scale(params), params=params))


def exposure_for(light) -> float:
    """Display exposure of a light: the reciprocal of the map's mean radiance over the sphere.

    It depends on the light only, so every frame under one fixed light shares one exposure (a training video
    does not flicker), and the random EV jitter of the light is undone for display while the HDR keeps it.
    An OLAT light instead gets π / luminance(E_facing), E_facing the irradiance on a surface facing it, so a
    white surface facing it displays at 1 (the mean-radiance rule would put it at 4 for any small source).
    """
    if light.spec.kind == "olat":
        from rh_dataset.lights import olat_record

        from rh_common.colourspace import luminance

        return float(np.pi / float(luminance(np.asarray(olat_record(light, "", 0)["irradiance_facing"]))))
    H, W = light.radiance.shape[:2]
    w = sh.pixel_solid_angles(H, W)
    lum = light.radiance @ np.array([0.2126, 0.7152, 0.0722])
    mean = float((lum * w[:, None] if w.ndim == 1 else lum * w).sum() / (4 * np.pi))
    return 1.0 / mean if mean > 1e-12 else 1.0


# Every pinned package (constraints.txt) whose version can change a pixel, a pose or a light of a frame: the
# renderer, the body model and what it computes with, the samplers' numpy, the denoiser, the image codecs.
PIXEL_PACKAGES = ("mitsuba", "drjit", "anny", "warp-lang", "roma", "torch", "numpy", "scipy", "pyoidn", "openexr",
                  "pillow", "colour-science")


def versions() -> dict[str, str]:
    """What computed a frame: the packages above and the LLVM that Dr.Jit compiles its kernels with (a system
    library, not a pip package). Recorded in the frame JSON; not part of the content identity. Read once per
    process (reading 12 package records cost ~30 ms a frame)."""
    return dict(_versions())


@functools.lru_cache(maxsize=1)
def _versions() -> tuple[tuple[str, str], ...]:
    import drjit.detail

    out = {"rh": __version__, "python": platform.python_version(),
           "llvm": ".".join(map(str, drjit.detail.llvm_version()))}
    for pkg in PIXEL_PACKAGES:
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "absent"
    return tuple(out.items())


def light_spec_json(spec) -> dict:
    d = spec.as_dict()  # procedural kinds add their `params`; envmap and sunsky blocks are unchanged
    d["source"] = os.path.basename(str(d.get("source", "")))  # no machine-specific absolute paths in the data
    return d


def frame_meta(protocol: str, settings: RenderSettings, subject: Subject, split_name: str, body: dict, light,
               render_seed: int, exposure: float, olat: dict | None = None) -> dict:
    """The frame JSON without its file checksums (the writer adds those). `settings` are the split's own
    (`RenderSettings.for_split`); `olat` is an OLAT frame's `light.olat` block (`lights.olat_record`)."""
    cam = subject.camera
    R = cam.world_to_opengl_rotation()
    sh_world = np.asarray(light.sh_world, dtype=np.float64)
    return {
        "subject": layout.subject_name(subject.index),
        "protocol": protocol,
        "split": split_name,
        "width": cam.width,
        "height": cam.height,
        "camera": cam.to_json(),
        "body": body,
        "light": {**light_spec_json(light.spec), "sh_world": sh_world, "sh_camera": sh.rotate(sh_world, R),
                  "negative_pixels_clamped": int(light.negative_pixels_clamped), **({"olat": olat} if olat else {})},
        "exposure": exposure,
        "render": {**dataclasses.asdict(settings), "seed": render_seed, "variant": select_variant(None),
                   "denoised": bool(settings.denoise)},
        "versions": versions(),
    }


def render_frame_to_disk(plan: DatasetPlan, source: SubjectSource, subject: Subject, split: SplitSpec,
                         index: int) -> FrameResult:
    """Render frame `index` of `split` for `subject` and write its layers and JSON (atomically, rh_dataset.writer).
    Renders whether or not the frame is already on disk: skipping complete frames is `run_subject`'s job."""
    from rh_dataset.lights import mitsuba_emitter_dict
    from rh_dataset.render.passes import render_frame

    s = subject.index
    seconds: dict[str, float] = {}
    t = time.perf_counter()
    pose = source.pose(subject, split, index)
    meshes = source.meshes(subject, pose)
    seconds["pose"] = time.perf_counter() - t
    t = time.perf_counter()
    light = light_for(plan, split, s, index, light_library(plan.spec))
    exposure = exposure_for(light)
    seconds["light"] = time.perf_counter() - t
    key = f"protocol_{plan.spec.protocol}"
    render_seed = int(rng_for(plan.seed, "render", s, key, split.name, index).integers(0, 2**31 - 2))
    # Only what the split needs: its scene class's path depth, no emitter without path tracing, no skin the clothes
    # hide (rh_dataset.render.cull); the frame JSON records it under render.scene_model.
    settings = plan.settings.for_split(split)
    result = render_frame(meshes, mitsuba_emitter_dict(light) if split.path_traced else None, subject.camera,
                          settings, split.layers, render_seed,
                          hidden=source.hidden_faces(subject) if settings.cull else None)
    seconds.update(result.seconds)
    t = time.perf_counter()
    olat = None
    if split.light == "olat":
        from rh_dataset.lights import olat_record

        olat = olat_record(light, split.olat.directions, olat_frame(split, index)[1])
    meta = frame_meta(plan.spec.protocol, settings, subject, split.name,
                      source.body_record(subject, split, index, pose), light, render_seed, exposure, olat)
    meta["render"]["scene_model"] = result.info
    seconds["meta"] = time.perf_counter() - t
    t = time.perf_counter()
    split_dir = plan.split_dir(s, split.name)
    write_frame(split_dir, index, result.layers, meta)
    seconds["write"] = time.perf_counter() - t
    return FrameResult(FrameTask(s, split.name, index), layout.frame_json_path(split_dir, index), seconds, result.info)


def run_subject(plan: DatasetPlan, source: SubjectSource, s: int, on_frame: OnFrame, *,
                frames: dict[str, range] | None = None, sheets: bool = True) -> None:
    """Render every missing frame of one subject (all splits) and its contact sheets.

    `frames` (split name -> frame indices) restricts the work to those frames (a distributed task's share);
    `sheets=False` leaves the contact sheets to whoever knows that every frame of the split is done."""
    select_variant(plan.variant)
    subject = None
    for split in plan.spec.splits:
        if frames is not None and split.name not in frames:
            continue
        split_dir = plan.split_dir(s, split.name)
        for i in (range(split.frames) if frames is None else frames[split.name]):
            task = FrameTask(s, split.name, i)
            if layout.frame_is_complete(split_dir, i, split.layers):
                on_frame(task, True)
                continue
            if subject is None:  # built only when a frame is missing: a finished subject resumes at once
                subject = source.subject(s)
                keep_character_record(plan, s, subject.record)
            render_frame_to_disk(plan, source, subject, split, i)
            on_frame(task, False)
        if sheets:
            contact_sheet(split_dir, list(range(split.frames)), split.layers)
