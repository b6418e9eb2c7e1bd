"""One frame: a `DatasetPlan`, a `SubjectSource` and its `Subject`, a split and a frame index in; the frame's layer
files and JSON on disk and a `FrameResult` (what was written, the seconds of each stage) out.

`render_frame_to_disk` is the one function that renders and writes a frame: the local backend, the Ray backend
(through `run_subject`) and bench/bench_generate.py all call it, so they render the same scene (camera, culling,
lights, settings). `run_subject` renders a subject's missing frames and writes its contact sheets. The render
stage's whole input for one camera is a `FrameScene` (plain data: meshes, light, camera, settings, seed), rendered
by `render_scene`; bench/bench_render_stage.py saves these and renders them again on another machine (a GPU one).
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
from typing import TYPE_CHECKING, Callable

import numpy as np

from rh_common import layout, sh
from rh_common.imageio import read_json
from rh_dataset import __version__
from rh_dataset.generate.folder import keep_character_record
from rh_dataset.generate.plan import DatasetPlan, FrameTask, GenerateError, light_library, olat_frame
from rh_dataset.generate.seeding import rng_for
from rh_dataset.generate.subjects import Subject, SubjectSource
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant
from rh_dataset.spec import SplitSpec
from rh_dataset.writer import contact_sheet, write_frame

if TYPE_CHECKING:  # annotations only: the render stage and the lights import Mitsuba's loader
    from rh_common.camera import Camera
    from rh_dataset.lights import Light
    from rh_dataset.render.passes import FrameRender

__all__ = ["FrameResult", "FrameScene", "OnFrame", "render_frame_to_disk", "render_scene", "frame_scenes", "run_subject",
           "check_same_variant", "contact_sheets", "light_for", "olat_light",
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
    """What the renderer built (also the frame JSON's render.scene_model; a multi-view frame's last camera's)."""
    json_paths: tuple[Path, ...] = ()
    """Every frame JSON written: one per camera of a multi-view frame (`json_path` is the first)."""


@dataclass(frozen=True)
class FrameScene:
    """What the render stage takes for one camera of one frame, decided upstream (pose, light, culling, the split's
    settings, the frame's seed) and nothing else: `render_scene` renders it on the process's Mitsuba variant. Plain
    data (numpy arrays and the project's dataclasses; no Mitsuba object, the emitter is built from `light` where it
    is rendered), so one made on this machine can be pickled and rendered on another variant or machine."""

    meshes: tuple
    """The posed shapes: triangle meshes (`render.scene.MeshLike`) and hair strands (`StrandsLike`)."""
    light: Light | None
    """The frame's light; None for a split that does not path-trace (no emitter)."""
    camera: Camera
    settings: RenderSettings
    """The plan's settings for this split (`RenderSettings.for_split`: the scene class's path depth)."""
    layers: tuple[str, ...]
    seed: int
    hidden: dict | None
    """Faces hidden under clothes, per mesh name (`render.cull`), or None without culling."""
    exposure: float


def render_scene(scene: FrameScene) -> FrameRender:
    """Render a `FrameScene`: `render.passes.render_frame`'s result (the layers, each pass's seconds)."""
    from rh_dataset.lights import mitsuba_emitter_dict
    from rh_dataset.render.passes import render_frame

    emitter = mitsuba_emitter_dict(scene.light) if scene.light is not None else None
    return render_frame(scene.meshes, emitter, scene.camera, scene.settings, scene.layers, scene.seed,
                        hidden=scene.hidden, exposure=scene.exposure)


def light_for(plan: DatasetPlan, split: SplitSpec, s: int, i: int, library: dict):
    """The frame's light: one per (subject, split) for a 'fixed' split, the frame's direction of the set for an
    'olat' split (no random draw), else one per frame (from the protocol's light mixture when it has one)."""
    from rh_dataset.lights import build_light, sample_light

    if split.light == "olat":
        return olat_light(split, i)
    if split.light == "train":  # frame i under the train split's light of frame i (its one fixed light)
        split = plan.spec.split("train")
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
               render_seed: int, exposure: float, olat: dict | None = None, *, camera=None,
               view: str | None = None) -> dict:
    """The frame JSON without its file checksums (the writer adds those). `settings` are the split's own
    (`RenderSettings.for_split`); `olat` is an OLAT frame's `light.olat` block (`lights.olat_record`); `camera`
    and `view` (cam_NN) a multi-view frame's camera (default: the subject's one camera, no view)."""
    cam = subject.camera if camera is None else camera
    R = cam.world_to_opengl_rotation()
    sh_world = np.asarray(light.sh_world, dtype=np.float64)
    return {**({"view": view} if view is not None else {}),
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
                         index: int, views: list[int | None] | None = None) -> FrameResult:
    """Render frame `index` of `split` for `subject` and write its layers and JSON (atomically, rh_dataset.writer).
    A multi-view split's frame (protocol c) is posed and lit once, then rendered from each camera of `views` (default
    every camera of the split), each camera-frame written whole in its own folder; `seconds` add up over them.
    Renders whether or not the frame is already on disk: skipping complete frames is `run_subject`'s job."""
    s = subject.index
    seconds: dict[str, float] = {}
    cloth: dict = {}
    pose, meshes, light, exposure, hidden = _pose_and_light(plan, source, subject, split, index, seconds, cloth)
    t = time.perf_counter()
    olat = None
    if split.light == "olat":
        from rh_dataset.lights import olat_record

        olat = olat_record(light, split.olat.directions, olat_frame(split, index)[1])
    body = source.body_record(subject, split, index, pose)
    seconds["meta"] = time.perf_counter() - t
    json_paths, info = [], {}
    for view, folder, scene in _scenes(plan, subject, split, index, views, meshes, light, exposure, hidden):
        result = render_scene(scene)
        for k, v in result.seconds.items():
            seconds[k] = seconds.get(k, 0.0) + v
        t = time.perf_counter()
        meta = frame_meta(plan.spec.protocol, scene.settings, subject, split.name, body, light, scene.seed, exposure,
                          olat, camera=scene.camera, view=None if view is None else layout.view_name(view))
        meta["render"]["scene_model"] = info = result.info
        if "mode" in cloth:  # the "auto" cloth mode: how this frame's draped cloth was posed
            meta["render"]["cloth_posed"] = cloth["mode"]
        seconds["meta"] += time.perf_counter() - t
        t = time.perf_counter()
        write_frame(folder, index, result.layers, meta)
        seconds["write"] = seconds.get("write", 0.0) + time.perf_counter() - t
        json_paths.append(layout.frame_json_path(folder, index))
    return FrameResult(FrameTask(s, split.name, index), json_paths[0], seconds, info, tuple(json_paths))


def frame_scenes(plan: DatasetPlan, source: SubjectSource, subject: Subject, split: SplitSpec, index: int,
                 views: list[int | None] | None = None) -> list[FrameScene]:
    """The `FrameScene` of each camera of frame `index` (of `views`, default all), exactly what
    `render_frame_to_disk` renders for it; nothing is rendered or written."""
    _, meshes, light, exposure, hidden = _pose_and_light(plan, source, subject, split, index, {})
    return [scene for _, _, scene in _scenes(plan, subject, split, index, views, meshes, light, exposure, hidden)]


def _pose_and_light(plan, source, subject, split, index, seconds: dict[str, float], cloth: dict | None = None):
    """The frame's pose, posed meshes, light, display exposure and culled faces (None unless the split culls);
    the posing's and the light's seconds go into `seconds` under "pose" and "light", how the draped cloth was
    posed into `cloth` (`SubjectSource.meshes`' `cloth_stats`)."""
    t = time.perf_counter()
    pose = source.pose(subject, split, index)
    meshes = source.meshes(subject, pose, plan.settings.cloth, cloth)
    seconds["pose"] = time.perf_counter() - t
    t = time.perf_counter()
    light = light_for(plan, split, subject.index, index, light_library(plan.spec))
    exposure = exposure_for(light)
    seconds["light"] = time.perf_counter() - t
    hidden = source.hidden_faces(subject) if plan.settings.for_split(split).cull else None
    return pose, meshes, light, exposure, hidden


def _scenes(plan, subject, split, index, views, meshes, light, exposure, hidden):
    """(view, its folder, its FrameScene) for each camera of the frame in `views` (None: all)."""
    # Only what the split needs: its scene class's path depth, no emitter without path tracing, no skin the clothes
    # hide (rh_dataset.render.cull); the frame JSON records it under render.scene_model.
    settings = plan.settings.for_split(split)
    s, key = subject.index, f"protocol_{plan.spec.protocol}"
    for view, folder in plan.view_dirs(s, split):
        if views is not None and view not in views:
            continue
        camera = subject.camera if view is None else subject.views[view]
        # Each camera its own sample stream; a single-camera frame keeps the stream it always had.
        keys = (split.name, index) if view is None else (split.name, index, view)
        seed = int(rng_for(plan.seed, "render", s, key, *keys).integers(0, 2**31 - 2))
        yield view, folder, FrameScene(meshes=tuple(meshes), light=light if split.path_traced else None, camera=camera,
                                       settings=settings, layers=tuple(split.layers), seed=seed, hidden=hidden,
                                       exposure=exposure)


def contact_sheets(plan: DatasetPlan, s: int, split: SplitSpec) -> None:
    """The split's contact sheet, one per camera folder of a multi-view split."""
    for _, folder in plan.view_dirs(s, split):
        contact_sheet(folder, list(range(split.frames)), split.layers)


def check_same_variant(plan: DatasetPlan, s: int, split: SplitSpec, variant: str) -> None:
    """Refuse to add frames rendered on `variant` to a split whose frames on disk another Mitsuba variant rendered
    (the first frame JSON found tells; each records `render.variant`). cuda_ad_rgb and llvm_ad_rgb draw the same
    samples with other last bits, and their frames are not the same benchmark by `rh-verify --against`
    (docs/ARCHITECTURE.md, "Content identity"), so a split must not mix them. Checked where the frames are rendered
    (a Ray worker's own variant, not the head's)."""
    for _, folder in plan.view_dirs(s, split):
        for path in sorted(Path(folder).glob("frame_*.json"))[:1]:
            try:
                made = read_json(path).get("render", {}).get("variant")
            except (OSError, ValueError):
                continue  # an unreadable frame is redone anyway; rh-verify reports it
            if made is not None and made != variant:
                raise GenerateError(f"{path} was rendered with Mitsuba's {made}, this run uses {variant}: the two "
                                    f"variants' frames are not the same benchmark; resume with --variant {made}, or "
                                    "choose another --out")


def run_subject(plan: DatasetPlan, source: SubjectSource, s: int, on_frame: OnFrame, *,
                frames: dict[str, range] | None = None, sheets: bool = True) -> None:
    """Render every missing frame of one subject (all splits) and its contact sheets.

    `frames` (split name -> frame indices) restricts the work to those frames (a distributed task's share);
    `sheets=False` leaves the contact sheets to whoever knows that every frame of the split is done. A frame of a
    multi-view split is done when every camera's is complete; a rerun renders only the cameras still missing."""
    variant = select_variant(plan.variant)
    subject = None
    for split in plan.spec.splits:
        if frames is not None and split.name not in frames:
            continue
        checked = False
        for i in (range(split.frames) if frames is None else frames[split.name]):
            task = FrameTask(s, split.name, i)
            missing = [v for v, d in plan.view_dirs(s, split) if not layout.frame_is_complete(d, i, split.layers)]
            if not missing:
                on_frame(task, True)
                continue
            if not checked:
                check_same_variant(plan, s, split, variant)
                checked = True
            if subject is None:  # built only when a frame is missing: a finished subject resumes at once
                subject = source.subject(s)
                keep_character_record(plan, s, subject.record)
            render_frame_to_disk(plan, source, subject, split, i, views=missing)
            on_frame(task, False)
        if sheets:
            contact_sheets(plan, s, split)
