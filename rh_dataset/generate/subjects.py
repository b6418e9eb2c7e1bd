"""The subject source: a `DatasetPlan` in; for each subject index its character, the record of it that
character.json keeps, the camera that frames it, and each frame's pose, posed meshes and frame-JSON body record.

One interface (`SubjectSource`), two kinds of subjects: `AnnySubjects` samples a clothed anny character per subject
(its recipe from the seed), `ImportedSubjects` renders the one rigged file of `--character` for every subject. The
frame stage (rh_dataset.generate.frames) asks the source and never which kind it is.
"""
from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from rh_dataset.generate.plan import DatasetPlan, GenerateError, motion_frame, pose_frame
from rh_dataset.generate.seeding import rng_for
from rh_common.camera import Camera, frame_body, orbit_cameras
from rh_dataset.spec import SplitSpec

__all__ = ["framing_box", "CAMERA_FILL", "Subject", "SubjectSource", "AnnySubjects", "ImportedSubjects",
           "subject_source", "imported_bone_map", "rig_cameras"]

CAMERA_FILL = 0.96
"""Fraction of the frame's height the framed box fills (rh_common.camera.frame_body)."""


def framing_box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box a generated subject's camera frames, from the rest pose's bounds (min, max): random poses reach up to
    ~0.2 body heights above the head (arms overhead) and sideways about as far as the A-pose's hands; feet stay near
    the ground (the root does not move). Frame that box, not the rest pose's."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    h = hi[2] - lo[2]
    return (np.array([lo[0] - 0.05 * h, lo[1], lo[2] - 0.03 * h]),
            np.array([hi[0] + 0.05 * h, hi[1], hi[2] + 0.18 * h]))


@dataclass(frozen=True)
class Subject:
    index: int
    character: Any
    record: dict
    """What character.json keeps: an anny recipe, or the imported character's description."""
    camera: Camera
    views: tuple[Camera, ...] = ()
    """The rig's cameras (protocol c: `ProtocolSpec.rig`, one per view, `rh_common.camera.orbit_cameras` on the
    box `camera` frames); () for a single-camera protocol."""


class SubjectSource(Protocol):
    def check(self) -> None:
        """Fail (or warn) on a bad input before any file is written; called once, by the driver."""

    def subject(self, s: int) -> Subject: ...

    def pose(self, subject: Subject, split: SplitSpec, i: int) -> Any:
        """Frame i's pose of the split (a BodyPose or an ImportedPose)."""

    def meshes(self, subject: Subject, pose, cloth: str = "skinned", cloth_stats: dict | None = None) -> list:
        """The posed meshes the renderer consumes; `cloth`: how draped garments are posed (RenderSettings.cloth);
        `cloth_stats`, if given, receives how they were posed ("mode": "skinned" or "simulated" where `cloth` is
        "auto"; nothing where the character has no draped cloth to pose)."""

    def hidden_faces(self, subject: Subject) -> dict | None:
        """Triangles the clothes hide (culled when RenderSettings.cull), or None when nothing is known hidden."""

    def body_record(self, subject: Subject, split: SplitSpec, i: int, pose) -> dict:
        """The frame JSON's "body": model, pose, turntable angle, and for a pose from captured motion its source."""


def rig_cameras(spec, lo, hi) -> tuple[Camera, ...]:
    """The rig's cameras framing the box [lo, hi] (every view at one distance), or () without a rig."""
    if spec.rig is None:
        return ()
    return tuple(orbit_cameras(lo, hi, spec.width, spec.height, spec.fov_y_deg, spec.rig.views, fill=CAMERA_FILL))


def subject_source(plan: DatasetPlan) -> SubjectSource:
    return AnnySubjects(plan) if plan.spec.character is None else ImportedSubjects(plan)


def _base_motion_record(plan: DatasetPlan, split: SplitSpec, i: int) -> dict | None:
    """For a pose from captured motion: the file (name, sha256), its frame and how the clip was sampled."""
    source, j = pose_frame(plan.spec, split, i)
    if split.poses == "turntable" or source.poses != "motion":
        return None
    from rh_dataset.poses.motion import read_motion_cached

    ms = source.motion
    record = read_motion_cached(ms.file, ms.sha256).record(motion_frame(ms, j))
    record.update(start=ms.start, stride=ms.stride, heading=ms.heading, in_place=ms.in_place)
    return record


def _pose_bytes(pose) -> bytes:
    """A pose's bone deltas (sorted by bone) and root transform as bytes: equal for the same pose."""
    parts = [name.encode() + np.ascontiguousarray(m, np.float64).tobytes() for name, m in sorted(pose.bones.items())]
    root = pose.root_transform
    return b"|".join(parts) + b"#" + (b"" if root is None else np.ascontiguousarray(root, np.float64).tobytes())


def _with_motion(body: dict, motion: dict | None) -> dict:
    if motion is not None:
        body["motion"] = motion
    return body


class AnnySubjects:
    """A clothed anny character per subject, sampled from the seed; poses from the turntable, the pose prior or
    captured motion retargeted onto the subject's own body."""

    # The "auto" cloth mode's simulated frames of the subject last posed, by pose (at most this many): protocol b's
    # test split shows its train split's poses again, and a simulation costs tens of seconds (docs/TRADEOFFS.md,
    # "Simulated where skinning fails"). The same inputs give the simulation's same bits, so nothing else changes.
    KEPT_SIMULATED = 64

    def __init__(self, plan: DatasetPlan) -> None:
        self.plan = plan
        self._simulated: dict[tuple, list] = {}  # (subject index, pose bytes) -> posed meshes

    def check(self) -> None:
        pass

    def subject(self, s: int) -> Subject:
        from rh_dataset.characters import body_bounds, build_character, pose_character, sample_recipe

        spec = self.plan.spec
        recipe = sample_recipe(rng_for(self.plan.seed, "character", s), pool=spec.character_pool, index=s)
        character = build_character(recipe, drape=self.plan.settings.drape)
        lo, hi = framing_box(*body_bounds(pose_character(character, None, None)))
        cam = frame_body(lo, hi, spec.width, spec.height, spec.fov_y_deg, fill=CAMERA_FILL)
        return Subject(s, character, recipe.to_json(), cam, rig_cameras(spec, lo, hi))

    def pose(self, subject: Subject, split: SplitSpec, i: int):
        from rh_common.body_model import load_anny
        from rh_dataset.poses import sample_pose, turntable

        if split.poses == "turntable":
            return turntable(split.frames)[i]
        source, j = pose_frame(self.plan.spec, split, i)  # an olat split's frame i shows pose j of its source
        if source.poses == "turntable":
            return turntable(source.frames)[j]
        if source.poses == "motion":
            from rh_dataset.poses.motion import read_motion_cached
            from rh_dataset.poses.retarget import motion_to_anny

            ms = source.motion
            motion = read_motion_cached(ms.file, ms.sha256)
            # Retargeted onto this subject's own body, so the leg-length scaling of the root fits it.
            return motion_to_anny(motion, subject.character.phenotype, frames=[motion_frame(ms, j)],
                                  in_place=ms.in_place, heading=ms.heading, model=load_anny())[0]
        return sample_pose(rng_for(self.plan.seed, "pose", subject.index, source.name, j), load_anny())

    def meshes(self, subject: Subject, pose, cloth: str = "skinned", cloth_stats: dict | None = None) -> list:
        from rh_dataset.characters import pose_character

        key = (subject.index, _pose_bytes(pose)) if cloth == "auto" else None  # only "auto" keeps frames
        if key in self._simulated:
            if cloth_stats is not None:
                cloth_stats["mode"] = "simulated"
            return list(self._simulated[key])
        stats = {} if cloth == "auto" else None
        meshes = pose_character(subject.character, dict(pose.bones), pose.root_transform, cloth, cloth_stats=stats)
        if cloth_stats is not None and stats and any(p.covered_skin is not None for p in subject.character.parts):
            cloth_stats["mode"] = stats["mode"]
        if key is not None and stats["mode"] == "simulated":
            if any(k[0] != subject.index for k in self._simulated) or len(self._simulated) >= self.KEPT_SIMULATED:
                self._simulated.clear()
            self._simulated[key] = list(meshes)
        return meshes

    def hidden_faces(self, subject: Subject):
        from rh_dataset.render.cull import hidden_faces

        return hidden_faces(subject.character)

    def body_record(self, subject: Subject, split: SplitSpec, i: int, pose) -> dict:
        body = {"model": "anny", "phenotype": subject.character.phenotype, "pose": pose.to_json(),
                "turntable_deg": float(getattr(pose, "turntable_deg", 0.0))}
        motion = _base_motion_record(self.plan, split, i)
        if motion is not None:
            # Self-intersections the prior's check finds: reported, not rejected (the frame shows what the capture
            # did, retargeted).
            from rh_common.body_model import load_anny
            from rh_dataset.poses import find_intersections

            motion["intersections"] = [dataclasses.asdict(x) for x in find_intersections(
                pose, load_anny(), phenotype=subject.character.phenotype)]
        return _with_motion(body, motion)


class ImportedSubjects:
    """The imported character of `--character` for every subject: train = its rest-pose turntable, other splits =
    its own animation, or `--motion` retargeted onto its rig. Has no self-intersection check and no culling."""

    def __init__(self, plan: DatasetPlan) -> None:
        self.plan = plan
        self._character = None

    def character(self):
        """The imported character, checked against the description (its name and sha256); read once."""
        if self._character is None:
            from rh_dataset.characters.imported_reader import character_digest, load_character_file

            src, path = self.plan.spec.character, self.plan.character_path
            if path is None:
                raise GenerateError(f"this protocol renders the imported character {src.file}; pass --character "
                                    f"PATH/{src.file}")
            path = Path(path)
            if not path.is_file():
                raise GenerateError(f"--character {path}: no such file")
            if path.name != src.file or character_digest(path) != src.sha256:
                raise GenerateError(f"--character {path} is not the file this dataset was made with ({src.file}, "
                                    f"sha256 {src.sha256[:16]}...); pass that file, another --out, or --overwrite")
            self._character = load_character_file(path, scale=src.scale)
        return self._character

    def check(self) -> None:
        """Read the character before any file is written (a bad file fails here, not in a worker; the reading is
        cached on disk for the workers), and say once if its test poses fall back to the rest pose."""
        character = self.character()
        spec = self.plan.spec
        motion_splits = [s.name for s in spec.splits if s.poses != "turntable"]
        if motion_splits and not character.clips:
            print(f"rh-generate: {spec.character.file} has no animation and no motion was given: the "
                  f"{', '.join(motion_splits)} split(s) render its rest pose (frame JSON pose label "
                  f"'rest (no motion source)'); use a file with an animation clip for novel poses", file=sys.stderr)

    def subject(self, s: int) -> Subject:
        from rh_dataset.characters.imported_model import imported_bounds

        character = self.character()
        spec = self.plan.spec
        # Exact framing: the box every used pose fills at every turntable angle (imported_bounds), plus 3%.
        used = {}
        for split in spec.splits:
            if split.poses != "turntable":
                for i in range(split.frames):
                    p = self._pose(character, split, i)
                    used[p.label] = p.pose
        lo, hi = imported_bounds(character, [None, *used.values()])
        pad = 0.03 * (hi[2] - lo[2])
        cam = frame_body(lo - pad, hi + pad, spec.width, spec.height, spec.fov_y_deg, fill=CAMERA_FILL)
        return Subject(s, character, character.to_json(), cam, rig_cameras(spec, lo - pad, hi + pad))

    def pose(self, subject: Subject, split: SplitSpec, i: int):
        return self._pose(subject.character, split, i)

    def _pose(self, character, split: SplitSpec, i: int):
        from rh_dataset.characters.imported_model import ImportedPose, motion_frames, split_pose

        spec = self.plan.spec
        source, j = pose_frame(spec, split, i)
        if split.poses != "turntable" and source.poses == "motion":  # --motion, retargeted onto its own rig
            from rh_dataset.poses.motion import read_motion_cached
            from rh_dataset.poses.retarget import retarget

            ms = source.motion
            motion = read_motion_cached(ms.file, ms.sha256)
            frame = motion_frame(ms, j)
            bone_map = imported_bone_map(motion.skeleton, character.skeleton, ms.file)
            pose = retarget(motion, character.skeleton, bone_map, frames=[frame], in_place=ms.in_place,
                            heading=ms.heading)[0]
            return ImportedPose(pose, label=f"motion:{Path(ms.file).name}#{frame}")
        return split_pose(source.poses, source.frames, j, motion_frames(character))

    def meshes(self, subject: Subject, pose, cloth: str = "skinned", cloth_stats: dict | None = None) -> list:
        """An imported character's clothes are part of its own skinned mesh: `cloth` does not apply."""
        from rh_dataset.characters.imported_model import pose_imported

        return pose_imported(subject.character, pose.pose, pose.root_transform)

    def hidden_faces(self, subject: Subject):
        return None  # an imported rig does not say which skin its clothes cover

    def body_record(self, subject: Subject, split: SplitSpec, i: int, pose) -> dict:
        body = {"model": "imported", "character": dataclasses.asdict(self.plan.spec.character),
                "pose": pose.to_json(subject.character.skeleton), "turntable_deg": float(pose.turntable_deg)}
        return _with_motion(body, _base_motion_record(self.plan, split, i))


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
