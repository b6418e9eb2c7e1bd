"""The dataset plan: what one `rh-generate` run makes, independent of where it renders.

In: the protocol description (`ProtocolSpec`), render settings, seed, Mitsuba variant, the output folder and, for an
imported character, its file. Out: a `DatasetPlan` (checked by `resolve_plan`: lights readable, motion clips read
and their strides fixed) and its `FrameTask`s, the (subject, split, frame) units every backend renders. Where the
frames are rendered (processes, Ray tasks) is each backend's own settings (rh_dataset.backends), not part of this.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from rh_common import layout
from rh_dataset.render.scene import RenderSettings
from rh_dataset.spec import ProtocolSpec, SplitSpec

__all__ = ["DatasetPlan", "FrameTask", "GenerateError", "DATASET_FORMAT", "frame_tasks",
           "resolve_plan", "pose_source", "pose_frame", "olat_frame", "motion_frame", "light_library"]

DATASET_FORMAT = "rh-dataset/1"


class GenerateError(RuntimeError):
    """A run that cannot start or continue; the message names the problem and the fix."""


@dataclass(frozen=True)
class DatasetPlan:
    """What is made: every file of the dataset follows from these fields alone."""

    out: Path
    spec: ProtocolSpec
    settings: RenderSettings
    seed: int = 0
    variant: str | None = None
    overwrite: bool = False
    # The file `spec.character` names (rh-generate --character): rendered for every subject instead of anny.
    character_path: Path | None = None

    def split_dir(self, subject: int, split: str) -> Path:
        return layout.split_dir(self.out, subject, self.spec.protocol, split)

    def view_dirs(self, subject: int, split: SplitSpec) -> list[tuple[int | None, Path]]:
        """(rig view, folder of its frames) for each camera the split renders: `<split>/cam_NN` per view of a
        multi-view split (protocol c), else [(None, the split folder)]."""
        d = self.split_dir(subject, split.name)
        if split.cameras is None:
            return [(None, d)]
        return [(v, d / layout.view_name(v)) for v in split.cameras]


@dataclass(frozen=True)
class FrameTask:
    subject: int
    split: str
    index: int


def frame_tasks(spec: ProtocolSpec) -> list[FrameTask]:
    """Every frame of the protocol, in the order the local backend renders them."""
    return [FrameTask(s, split.name, i) for s in range(spec.subjects) for split in spec.splits
            for i in range(split.frames)]


def pose_source(spec: ProtocolSpec, split: SplitSpec) -> SplitSpec:
    """The split whose pose source a split uses ('train' and 'test' reuse that split's, and so on down the chain:
    protocol b's test reuses train's, so an olat split reusing test's poses shows train's)."""
    return pose_frame(spec, split, 0)[0]


def olat_frame(split: SplitSpec, i: int) -> tuple[int, int]:
    """(pose index, direction index) of frame i of an olat split: pose-major, every direction of a pose in turn."""
    n = split.olat.n_directions
    return i // n, i % n


def pose_frame(spec: ProtocolSpec, split: SplitSpec, i: int) -> tuple[SplitSpec, int]:
    """The split that draws the pose frame i of `split` shows, and that pose's frame index there."""
    if split.olat is not None:
        i = olat_frame(split, i)[0]
    while split.poses in ("train", "test"):
        split = spec.split(split.poses)
    return split, i


def motion_frame(motion_spec, i: int) -> int:
    return motion_spec.start + i * motion_spec.stride


def light_library(spec: ProtocolSpec) -> dict:
    """Name -> file of the environment maps this protocol draws its lights from."""
    from rh_dataset.lights import bundled_hdris, hdri_library

    return hdri_library(spec.hdri_folder) if spec.hdri_folder else bundled_hdris()


def resolve_plan(plan: DatasetPlan) -> DatasetPlan:
    """Check every input that a worker would otherwise fail on, before any file is written: the light maps (read
    once; cached), and the motion clips (read once, through Blender; an automatic stride is fixed here)."""
    from rh_dataset.lights import load_hdri

    plan = dataclasses.replace(plan, out=Path(plan.out))
    library = light_library(plan.spec)
    mixture = plan.spec.light_mixture
    # Fixed (training) lights always draw as protocols a and b do; random ones from the mixture when there is one.
    needs_maps = not plan.spec.sunsky and (mixture is None or mixture.get("real", 0) > 0
                                           or any(s.light == "fixed" for s in plan.spec.splits))
    if not library and needs_maps:
        raise GenerateError(f"no .exr/.hdr environment maps in {plan.spec.hdri_folder}; point --hdri-folder at maps")
    for path in library.values():
        load_hdri(path)
    return dataclasses.replace(plan, spec=resolve_motion(plan.spec))


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
