"""The generator's pipeline: protocol spec → characters → poses → lights → Mitsuba → frame writer → dataset.

Every random choice comes from a generator seeded by (dataset seed, what it is for, which subject/split/frame), so
any frame can be produced on its own — by a rerun that resumes, or by another worker — and comes out the same.
"""
from __future__ import annotations

import dataclasses
import importlib.metadata as md
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from rh_common import sh
from rh_common.imageio import read_json, write_json
from rh_dataset import __version__
from rh_common.camera import Camera, frame_body
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant
from rh_dataset.spec import ProtocolSpec, SplitSpec
from rh_dataset.writer import contact_sheet, frame_is_complete, frame_stem, write_frame, write_manifest

__all__ = ["GenerateOptions", "GenerateError", "FrameTask", "plan", "generate", "subject_name", "rng_for",
           "DATASET_FORMAT"]

DATASET_FORMAT = "rh-dataset/1"


class GenerateError(RuntimeError):
    """A run that cannot start or continue; the message names the problem and the fix."""


@dataclass(frozen=True)
class GenerateOptions:
    out: Path
    spec: ProtocolSpec
    settings: RenderSettings
    seed: int = 0
    variant: str | None = None
    overwrite: bool = False
    workers: int = 1
    # Where frames are rendered: "local" (this machine, `workers` processes) or "ray" (rh_dataset.backends.ray_backend:
    # tasks of up to `ray_frames_per_task` frames of one subject and split, on the cluster at `ray_address`).
    backend: str = "local"
    ray_address: str | None = None
    ray_frames_per_task: int = 8
    ray_cpus_per_task: float = 1.0
    ray_gpus_per_task: float = 0.0
    # The file `spec.character` names (rh-generate --character): rendered for every subject instead of anny.
    character_path: Path | None = None


@dataclass(frozen=True)
class FrameTask:
    subject: int
    split: str
    index: int


def subject_name(i: int) -> str:
    return f"subject_{i:03d}"


_PURPOSES = {"character": 1, "camera": 2, "light": 3, "pose": 4, "render": 5}
_SPLIT_CODES = {"train": 1, "test": 2}


def rng_for(seed: int, purpose: str, *keys: int | str) -> np.random.Generator:
    """An independent generator for one purpose and one (subject, split, frame) key."""
    words = [seed, _PURPOSES[purpose]]
    for k in keys:
        words.append(k if isinstance(k, int) else _SPLIT_CODES.get(k, sum(k.encode()) + 1000))
    return np.random.default_rng(np.random.SeedSequence(words))


def plan(spec: ProtocolSpec) -> list[FrameTask]:
    return [FrameTask(s, split.name, i) for s in range(spec.subjects) for split in spec.splits
            for i in range(split.frames)]


def versions() -> dict[str, str]:
    out = {"rh": __version__, "python": platform.python_version()}
    for pkg in ("mitsuba", "drjit", "anny", "numpy", "torch"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "absent"
    return out


# --------------------------------------------------------------------------------------------------------------
# Dataset folder bookkeeping


def _dataset_record(opts: GenerateOptions) -> dict:
    return {
        "spec": opts.spec.to_json(),
        "spec_digest": opts.spec.digest(),
        "seed": opts.seed,
        "render": dataclasses.asdict(opts.settings),
    }


def prepare_out(opts: GenerateOptions) -> None:
    """Refuse to mix datasets: a folder must be empty, ours with the same settings, or `--overwrite` given."""
    out = opts.out
    if out.exists() and not out.is_dir():
        raise GenerateError(f"--out {out} is a file; pass a folder")
    ds_path = out / "dataset.json"
    key = f"protocol_{opts.spec.protocol}"
    record = read_json_roundtrip(_dataset_record(opts))  # compare as it reads back (tuples become lists)
    if ds_path.is_file():
        ds = read_json(ds_path)
        if ds.get("format") != DATASET_FORMAT:
            raise GenerateError(f"{ds_path} is not an rh dataset ({ds.get('format')!r}); choose another --out")
        old = ds.get("protocols", {}).get(key)
        if old is not None and old != record and not opts.overwrite:
            raise GenerateError(
                f"{out} already holds {key} made with other settings (spec {old.get('spec_digest')}, seed "
                f"{old.get('seed')}, render {old.get('render')}); rerun with the same flags to resume, choose another "
                f"--out, or pass --overwrite to replace it")
    elif out.is_dir() and any(p for p in out.iterdir() if not p.name.startswith(".")):
        raise GenerateError(f"{out} is not empty and holds no dataset.json: it is not an rh dataset; "
                            "choose an empty or new --out folder")
    else:
        ds = {"format": DATASET_FORMAT, "protocols": {}}
    if opts.overwrite and key in ds.get("protocols", {}) and ds["protocols"][key] != record:
        import shutil

        for d in out.glob(f"subject_*/{key}"):
            shutil.rmtree(d)
    ds["generator_version"] = __version__
    ds.setdefault("protocols", {})[key] = record
    write_json(ds_path, ds)


# --------------------------------------------------------------------------------------------------------------
# Per-subject state


@dataclass
class SubjectState:
    index: int
    character: object
    recipe_json: dict
    camera: Camera


def _imported_character(opts: GenerateOptions):
    """The imported character of this run, checked against the description (its name and sha256)."""
    from rh_dataset.characters.imported import character_digest, load_character_file

    src, path = opts.spec.character, opts.character_path
    if path is None:
        raise GenerateError(f"this protocol renders the imported character {src.file}; pass --character PATH/{src.file}")
    path = Path(path)
    if not path.is_file():
        raise GenerateError(f"--character {path}: no such file")
    if path.name != src.file or character_digest(path) != src.sha256:
        raise GenerateError(f"--character {path} is not the file this dataset was made with ({src.file}, sha256 "
                            f"{src.sha256[:16]}...); pass that file, another --out, or --overwrite")
    return load_character_file(path, scale=src.scale)


def _motion_poses_used(opts: GenerateOptions, s: int, character) -> list:
    """Every pose the non-turntable splits of this run will take (for framing the camera around all of them)."""
    used = {}
    for split in opts.spec.splits:
        if split.poses != "turntable":
            for i in range(split.frames):
                p = _pose_for(opts, split, s, i, character)
                used[p.label] = p.pose
    return list(used.values())


def _build_imported_subject(opts: GenerateOptions, s: int) -> SubjectState:
    from rh_dataset.characters.imported import imported_bounds

    character = _imported_character(opts)
    # Exact framing: the box every used pose fills at every turntable angle (imported_bounds), plus 3%.
    lo, hi = imported_bounds(character, [None, *_motion_poses_used(opts, s, character)])
    pad = 0.03 * (hi[2] - lo[2])
    cam = frame_body(lo - pad, hi + pad, opts.spec.width, opts.spec.height, opts.spec.fov_y_deg, fill=0.96)
    record = character.to_json()
    _keep_character_record(opts, s, record)
    return SubjectState(s, character, record, cam)


def _keep_character_record(opts: GenerateOptions, s: int, record: dict) -> None:
    """Write the subject's character.json, or check that the one already there describes this character (a resumed
    run must not mix characters)."""
    path = opts.out / subject_name(s) / "character.json"
    if path.is_file() and not opts.overwrite:
        if read_json(path) != read_json_roundtrip(record):
            raise GenerateError(f"{path} describes another character than this run would make; "
                                "use another --out or --overwrite")
    else:
        write_json(path, record)


def build_subject(opts: GenerateOptions, s: int) -> SubjectState:
    from rh_dataset.characters import build_character, body_bounds, pose_character, sample_recipe

    if opts.spec.character is not None:
        return _build_imported_subject(opts, s)
    recipe = sample_recipe(rng_for(opts.seed, "character", s), pool=opts.spec.character_pool, index=s)
    character = build_character(recipe)
    lo, hi = body_bounds(pose_character(character, None, None))
    # Random poses reach up to ~0.2 body heights above the head (arms overhead) and sideways about as far as the
    # A-pose's hands; feet stay near the ground (the root does not move). Frame that box, not the rest pose's.
    h = hi[2] - lo[2]
    lo = np.array([lo[0] - 0.05 * h, lo[1], lo[2] - 0.03 * h])
    hi = np.array([hi[0] + 0.05 * h, hi[1], hi[2] + 0.18 * h])
    cam = frame_body(lo, hi, opts.spec.width, opts.spec.height, opts.spec.fov_y_deg, fill=0.96)
    recipe_json = recipe.to_json()
    _keep_character_record(opts, s, recipe_json)
    return SubjectState(s, character, recipe_json, cam)


def read_json_roundtrip(obj: dict) -> dict:
    import json

    from rh_common.imageio import dumps_json

    return json.loads(dumps_json(obj))


def _pose_source(opts: GenerateOptions, split: SplitSpec) -> SplitSpec:
    """The split whose pose source a split uses ('train' reuses the train split's)."""
    return opts.spec.split("train") if split.poses == "train" else split


def _motion_frame(motion_spec, i: int) -> int:
    return motion_spec.start + i * motion_spec.stride


def _pose_for(opts: GenerateOptions, split: SplitSpec, s: int, i: int, character=None):
    from rh_common.body_model import load_anny
    from rh_dataset.poses import sample_pose, turntable

    if opts.spec.character is not None:  # an imported character: its rest-pose turntable, or its own motion
        from rh_dataset.characters.imported import ImportedPose, motion_frames, split_pose

        source = _pose_source(opts, split)
        if split.poses != "turntable" and source.poses == "motion":  # --motion, retargeted onto its own rig
            from rh_dataset.poses.motion import read_motion_cached
            from rh_dataset.poses.retarget import retarget

            ms = source.motion
            motion = read_motion_cached(ms.file, ms.sha256)
            frame = _motion_frame(ms, i)
            pose = retarget(motion, character.skeleton, imported_bone_map(motion.skeleton, character.skeleton,
                                                                          ms.file),
                            frames=[frame], in_place=ms.in_place, heading=ms.heading)[0]
            return ImportedPose(pose, label=f"motion:{Path(ms.file).name}#{frame}")
        n = opts.spec.split("train").frames if split.poses == "train" else split.frames
        return split_pose(split.poses, n, i, motion_frames(character))
    if split.poses == "turntable":
        return turntable(split.frames)[i]
    source = _pose_source(opts, split)
    if source.poses == "motion":
        from rh_dataset.poses.motion import read_motion_cached
        from rh_dataset.poses.retarget import motion_to_anny

        ms = source.motion
        motion = read_motion_cached(ms.file, ms.sha256)
        # Retargeted onto this subject's own body, so the leg-length scaling of the root fits it.
        return motion_to_anny(motion, character.phenotype, frames=[_motion_frame(ms, i)], in_place=ms.in_place,
                              heading=ms.heading, model=load_anny())[0]
    key = "train" if split.poses == "train" else split.name
    return sample_pose(rng_for(opts.seed, "pose", s, key, i), load_anny())


def imported_bone_map(source, target, motion_file) -> dict[str, str]:
    """Motion bones onto an imported rig: `guess_bone_map` (anny, CMU, Mixamo tables, keywords), else the bones the
    two rigs share by name (a clip exported from the character's own rig). Refuses a map that matches nothing."""
    from rh_dataset.poses.retarget import guess_bone_map

    bone_map = guess_bone_map(source, target)
    if not bone_map:
        bone_map = {n: n for n in source.names if n in target.index}
    if not bone_map:
        raise GenerateError(f"motion {motion_file}: none of its bones ({', '.join(source.names[:6])}, ...) match the "
                            f"imported character's ({', '.join(target.names[:6])}, ...); rename the bones or "
                            f"retarget with rh_dataset.poses.retarget.retarget and an explicit bone_map")
    return bone_map


def _motion_record(opts: GenerateOptions, split: SplitSpec, i: int, pose, phenotype) -> dict | None:
    """For a pose from captured motion: the file (name, sha256), its frame, and the self-intersections the prior's
    check finds (reported, not rejected: the frame shows what the capture did, retargeted)."""
    if split.poses == "turntable" or _pose_source(opts, split).poses != "motion":
        return None
    from rh_common.body_model import load_anny
    from rh_dataset.poses import find_intersections
    from rh_dataset.poses.motion import read_motion_cached

    ms = _pose_source(opts, split).motion
    record = read_motion_cached(ms.file, ms.sha256).record(_motion_frame(ms, i))
    record.update(start=ms.start, stride=ms.stride, heading=ms.heading, in_place=ms.in_place)
    if phenotype is not None:  # anny's self-intersection check; an imported rig has no such model
        record["intersections"] = [dataclasses.asdict(x) for x in find_intersections(pose, load_anny(),
                                                                                      phenotype=phenotype)]
    return record


def resolve_motion(spec: ProtocolSpec) -> ProtocolSpec:
    """Read every split's motion once (failing early, before any file is written), check that the split's frames
    fit in the clip, and fix an automatic stride (the split's frames spread over the clip)."""
    from rh_dataset.poses.motion import read_motion_cached

    splits = []
    for split in spec.splits:
        if split.motion is not None:
            ms = split.motion
            n = len(read_motion_cached(ms.file, ms.sha256))
            if ms.start >= n:
                raise GenerateError(f"motion {ms.file} has {n} frames; start {ms.start} is past its end")
            stride = ms.stride if ms.stride is not None else max(1, (n - ms.start) // split.frames)
            last = ms.start + (split.frames - 1) * stride
            if last >= n:
                raise GenerateError(
                    f"split {split.name} needs {split.frames} frames from motion {ms.file} (frames {ms.start}, "
                    f"{ms.start + stride}, ... {last}) but the clip has {n}: lower --frames, --motion-stride or "
                    f"--motion-start")
            split = dataclasses.replace(split, motion=dataclasses.replace(ms, stride=stride))
        splits.append(split)
    return dataclasses.replace(spec, splits=tuple(splits))


def _light_for(opts: GenerateOptions, split: SplitSpec, s: int, i: int, library: dict):
    from rh_dataset.lights import build_light, sample_light

    protocol_key = opts.spec.protocol
    if split.light == "fixed":
        rng = rng_for(opts.seed, "light", s, protocol_key, split.name)
    else:
        rng = rng_for(opts.seed, "light", s, protocol_key, split.name, i)
    spec = sample_light(rng, library, exposure_ev_range=opts.spec.exposure_ev_range, allow_sunsky=opts.spec.sunsky)
    return build_light(spec)


def exposure_for(light) -> float:
    """Display exposure of a light: the reciprocal of the map's mean radiance over the sphere.

    It depends on the light only, so every frame under one fixed light shares one exposure (a training video
    does not flicker), and the random EV jitter of the light is undone for display while the HDR keeps it.
    """
    H, W = light.radiance.shape[:2]
    w = sh.pixel_solid_angles(H, W)
    lum = light.radiance @ np.array([0.2126, 0.7152, 0.0722])
    mean = float((lum * w[:, None] if w.ndim == 1 else lum * w).sum() / (4 * np.pi))
    return 1.0 / mean if mean > 1e-12 else 1.0


def frame_meta(opts: GenerateOptions, subj: SubjectState, split: SplitSpec, i: int, pose, light, render_seed: int,
               exposure: float) -> dict:
    cam = subj.camera
    R = cam.world_to_opengl_rotation()
    sh_world = np.asarray(light.sh_world, dtype=np.float64)
    if opts.spec.character is not None:
        body = {"model": "imported", "character": dataclasses.asdict(opts.spec.character),
                "pose": pose.to_json(subj.character.skeleton), "turntable_deg": float(pose.turntable_deg)}
    else:
        body = {"model": "anny", "phenotype": subj.character.phenotype, "pose": pose.to_json(),
                "turntable_deg": float(getattr(pose, "turntable_deg", 0.0))}
    return {
        "subject": subject_name(subj.index),
        "protocol": opts.spec.protocol,
        "split": split.name,
        "width": cam.width,
        "height": cam.height,
        "camera": cam.to_json(),
        "body": body,
        "light": {**light_spec_json(light.spec), "sh_world": sh_world, "sh_camera": sh.rotate(sh_world, R),
                  "negative_pixels_clamped": int(light.negative_pixels_clamped)},
        "exposure": exposure,
        "render": {**dataclasses.asdict(opts.settings), "seed": render_seed, "variant": select_variant(None),
                   "denoised": bool(opts.settings.denoise)},
        "versions": versions(),
    }


def light_spec_json(spec) -> dict:
    d = dataclasses.asdict(spec)
    d["source"] = os.path.basename(str(d.get("source", "")))  # no machine-specific absolute paths in the data
    return d


# --------------------------------------------------------------------------------------------------------------
# The run


def _light_library(spec: ProtocolSpec) -> dict:
    from rh_dataset.lights import bundled_hdris, hdri_library

    return hdri_library(spec.hdri_folder) if spec.hdri_folder else bundled_hdris()


def run_subject(opts: GenerateOptions, s: int, on_frame: Callable[[FrameTask, bool], None], *,
                frames: dict[str, range] | None = None, sheets: bool = True) -> None:
    """Render every missing frame of one subject (all splits) and its contact sheets.

    `frames` (split name -> frame indices) restricts the work to those frames (a distributed task's share);
    `sheets=False` leaves the contact sheets to whoever knows that every frame of the split is done."""
    from rh_dataset.characters import pose_character
    from rh_dataset.lights import mitsuba_emitter_dict
    from rh_dataset.render.cull import hidden_faces

    select_variant(opts.variant)
    library = _light_library(opts.spec)
    subj = None
    key = f"protocol_{opts.spec.protocol}"
    for split in opts.spec.splits:
        if frames is not None and split.name not in frames:
            continue
        split_dir = opts.out / subject_name(s) / key / split.name
        for i in (range(split.frames) if frames is None else frames[split.name]):
            task = FrameTask(s, split.name, i)
            if frame_is_complete(split_dir, i, split.layers):
                on_frame(task, True)
                continue
            if subj is None:
                subj = build_subject(opts, s)
            pose = _pose_for(opts, split, s, i, subj.character)
            light = _light_for(opts, split, s, i, library)
            if opts.spec.character is not None:
                from rh_dataset.characters.imported import pose_imported

                meshes = pose_imported(subj.character, pose.pose, pose.root_transform)
            else:
                meshes = pose_character(subj.character, dict(pose.bones), pose.root_transform)
            render_seed = int(rng_for(opts.seed, "render", s, key, split.name, i).integers(0, 2**31 - 2))
            # Only what the split needs: its scene class's path depth, no emitter without path tracing, no skin
            # the clothes hide (rh_dataset.render.cull); the frame JSON records it under render.scene_model.
            settings = opts.settings.for_split(split)
            result = render_frame(meshes, mitsuba_emitter_dict(light) if split.path_traced else None, subj.camera,
                                  settings, split.layers, render_seed,
                                  hidden=hidden_faces(subj.character)
                                  if settings.cull and opts.spec.character is None else None)
            exposure = exposure_for(light)
            meta = frame_meta(dataclasses.replace(opts, settings=settings), subj, split, i, pose, light, render_seed,
                              exposure)
            meta["render"]["scene_model"] = result.info
            if (motion := _motion_record(opts, split, i, pose, getattr(subj.character, "phenotype", None))) is not None:
                meta["body"]["motion"] = motion
            write_frame(split_dir, i, result.layers, meta)
            on_frame(task, False)
        if sheets:
            contact_sheet(split_dir, list(range(split.frames)), split.layers)


def generate(opts: GenerateOptions, *, progress: bool = True) -> dict:
    """Generate (or resume) a dataset; returns counts. Writes dataset.json first and manifest.json last."""
    opts = dataclasses.replace(opts, out=Path(opts.out))
    if opts.workers < 1:
        raise GenerateError(f"--workers must be >= 1, got {opts.workers}")
    if opts.backend not in ("local", "ray"):
        raise GenerateError(f"--backend must be 'local' or 'ray', got {opts.backend!r}")
    if opts.backend == "ray":
        from rh_dataset.backends.ray_backend import check_options

        check_options(opts)
    # Fail on a missing or unreadable light before any file is written (maps are cached once loaded).
    from rh_dataset.lights import load_hdri

    library = _light_library(opts.spec)
    if not library and not opts.spec.sunsky:
        raise GenerateError(f"no .exr/.hdr environment maps in {opts.spec.hdri_folder}; point --hdri-folder at maps")
    for path in library.values():
        load_hdri(path)
    # A motion file is read (through Blender) and checked before anything is written, like the lights.
    opts = dataclasses.replace(opts, spec=resolve_motion(opts.spec))
    if opts.spec.character is not None:
        _check_imported(opts)
    select_variant(opts.variant)
    prepare_out(opts)
    tasks = plan(opts.spec)
    counts = {"rendered": 0, "skipped": 0}
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), unit="frame", disable=not progress, dynamic_ncols=True,
               desc=f"protocol {opts.spec.protocol}")

    def on_frame(task: FrameTask, skipped: bool) -> None:
        counts["skipped" if skipped else "rendered"] += 1
        bar.set_postfix_str(f"{subject_name(task.subject)}/{task.split}/{frame_stem(task.index)}", refresh=False)
        bar.update(1)

    t0 = time.perf_counter()
    if opts.backend == "ray":
        from rh_dataset.backends.ray_backend import run_ray

        run_ray(opts, on_frame)
    elif opts.workers == 1:
        for s in range(opts.spec.subjects):
            run_subject(opts, s, on_frame)
    else:
        _run_parallel(opts, on_frame)
    bar.close()
    write_manifest(opts.out)
    counts["seconds"] = time.perf_counter() - t0
    return counts


def _check_imported(opts: GenerateOptions) -> None:
    """Read the imported character before any file is written (a bad file fails here, not in a worker; the reading
    is cached on disk for the workers), and say once if its test poses fall back to the rest pose."""
    import sys

    character = _imported_character(opts)
    motion_splits = [s.name for s in opts.spec.splits if s.poses != "turntable"]
    if motion_splits and not character.clips:
        print(f"rh-generate: {opts.spec.character.file} has no animation and no motion was given: the "
              f"{', '.join(motion_splits)} split(s) render its rest pose (frame JSON pose label "
              f"'rest (no motion source)'); use a file with an animation clip for novel poses", file=sys.stderr)


def _worker(opts: GenerateOptions, s: int, queue) -> None:
    import drjit as dr

    dr.set_thread_count(max(1, (os.cpu_count() or 1) // opts.workers))
    run_subject(opts, s, lambda task, skipped: queue.put((task, skipped)))


def _run_parallel(opts: GenerateOptions, on_frame: Callable[[FrameTask, bool], None]) -> None:
    """One process per subject at a time, `workers` at once; frames report back through a queue."""
    import multiprocessing as mp
    import queue as queue_mod
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = mp.get_context("spawn")  # drjit's JIT state must not be forked
    with ctx.Manager() as manager:
        q = manager.Queue()
        with ProcessPoolExecutor(max_workers=opts.workers, mp_context=ctx) as pool:
            pending = {pool.submit(_worker, opts, s, q) for s in range(opts.spec.subjects)}
            while pending:
                done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                for f in done:
                    f.result()  # re-raise a worker's error here
                while True:
                    try:
                        on_frame(*q.get_nowait())
                    except queue_mod.Empty:
                        break
            while True:
                try:
                    on_frame(*q.get_nowait())
                except queue_mod.Empty:
                    break


def iter_frames(root: Path) -> Iterator[Path]:
    yield from sorted(Path(root).glob("subject_*/protocol_*/*/frame_*.json"))
