"""Declarative scene and protocol descriptions (`rh_dataset/scenes/*.json`), validated on load.

A description says what a protocol needs and nothing else: which splits, how many frames, which poses and lights,
which layers. Unknown keys are errors (a typo must not silently fall back to a default).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rh_common.imageio import dumps_json, sha256_file

from .rig import CameraRig, parse_rig
from .scene_files import SCENES_DIR, SpecError, _check_keys

__all__ = [
    "SCENES_DIR",
    "SpecError",
    "SplitSpec",
    "MotionSpec",
    "OlatSpec",
    "CameraRig",
    "CharacterSource",
    "ProtocolSpec",
    "load_protocol",
    "available_protocols",
]


POSE_SOURCES = ("turntable", "random", "train", "test", "motion")
LIGHT_SOURCES = ("fixed", "random", "olat", "train")
KNOWN_LAYERS = ("image", "mask", "albedo", "normal", "depth")


@dataclass(frozen=True)
class MotionSpec:
    """Captured motion as a split's pose source (rh_dataset.poses.motion / retarget): frame i of the split is the
    file's frame `start + i * stride`, retargeted onto each subject's anny body."""

    file: str = field(compare=False)
    """Path of the .bvh (or .fbx/.glb/.gltf) file. Not part of the digest: the content (sha256) is."""
    sha256: str
    start: int = 0
    stride: int | None = None
    """Motion frames between consecutive split frames; None = spread the split over the clip (resolved when a run
    starts, when the clip's length is known)."""
    heading: str = "file"
    """'file': the body faces where the actor faced; 'front': every frame turned to face the camera."""
    in_place: bool = True
    """Keep the pelvis above its rest position (the camera frames it); False keeps the clip's trajectory."""

    def __post_init__(self) -> None:
        if not isinstance(self.start, int) or isinstance(self.start, bool) or self.start < 0:
            raise SpecError(f"motion {self.file}: start must be a non-negative integer, got {self.start!r}")
        if self.stride is not None and (not isinstance(self.stride, int) or isinstance(self.stride, bool)
                                        or self.stride < 1):
            raise SpecError(f"motion {self.file}: stride must be a positive integer, got {self.stride!r}")
        if self.heading not in ("file", "front"):
            raise SpecError(f"motion {self.file}: heading must be 'file' or 'front', got {self.heading!r}")
        if not isinstance(self.in_place, bool):
            raise SpecError(f"motion {self.file}: in_place must be true or false, got {self.in_place!r}")

    @classmethod
    def from_file(cls, path: str | Path, **kwargs) -> "MotionSpec":
        """A MotionSpec for a file on disk (its sha256 computed now); a missing file is a SpecError."""
        path = Path(path)
        if not path.is_file():
            raise SpecError(f"motion file {path} does not exist: pass the path of a .bvh (or .fbx/.glb/.gltf) file")
        return cls(file=str(path), sha256=sha256_file(path), **kwargs)

    def to_json(self) -> dict:
        return {"name": Path(self.file).name, "sha256": self.sha256, "start": self.start, "stride": self.stride,
                "heading": self.heading, "in_place": self.in_place}


@dataclass(frozen=True)
class OlatSpec:
    """The lights of an 'olat' split (rh_dataset.lights.olat): every pose of the split under each direction of the
    named set in turn, a disc of angular radius `radius_deg` and linear Rec.709 `colour`; frame i shows pose
    i // len(directions) under direction i % len(directions)."""

    directions: str
    radius_deg: float = 3.0
    colour: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        from rh_dataset.lights.olat import check_colour, check_radius, olat_directions

        try:
            olat_directions(self.directions)
            check_radius(self.radius_deg, "olat radius_deg")
            check_colour(list(self.colour), "olat colour")
        except ValueError as exc:
            raise SpecError(str(exc)) from None

    @property
    def n_directions(self) -> int:
        from rh_dataset.lights.olat import olat_directions

        return len(olat_directions(self.directions))


@dataclass(frozen=True)
class SplitSpec:
    name: str
    frames: int
    poses: str
    """turntable (A-pose, 360 degrees), random (pose prior), train or test (the same poses as this protocol's train
    or test split)."""
    light: str
    """fixed (one light for the whole split), random (a new light per frame), olat (each pose under each of the
    `olat` block's directions) or train (frame i under the train split's light of frame i: its one fixed light)."""
    layers: tuple[str, ...]
    motion: MotionSpec | None = None
    """The captured motion when poses is 'motion' (None otherwise)."""
    scene_class: str | None = None
    """What kind of scene the split path-traces (`scene_classes` in presets.json): it picks the beauty pass's
    path depth. Required when the split has an `image` layer, absent otherwise (nothing is path-traced)."""
    max_depth: int | None = None
    """The scene class's path depth, resolved on load (so a changed class table changes the spec's digest and a
    resumed run refuses to mix depths). None for splits that do not path-trace."""
    rr_depth: int | None = None
    """The scene class's Russian-roulette depth, resolved on load as max_depth is (None: Mitsuba's default)."""
    olat: OlatSpec | None = None
    """The OLAT lights when light is 'olat' (None otherwise)."""
    cameras: tuple[int, ...] | None = None
    """Views of the protocol's camera rig this split renders (indices into `CameraRig.views`), every frame from
    each of them; None: the protocol's one camera per subject (protocols a and b)."""

    @property
    def path_traced(self) -> bool:
        """Only the `image` layer needs light transport; every other layer comes from the AOV pass."""
        return "image" in self.layers

    def __post_init__(self) -> None:
        if (self.poses == "motion") != (self.motion is not None):
            raise SpecError(f"split {self.name}: poses 'motion' and a 'motion' block go together (got poses "
                            f"{self.poses!r} {'with' if self.motion else 'without'} a motion block)")
        if not isinstance(self.frames, int) or self.frames < 1:
            raise SpecError(f"split {self.name}: frames must be a positive integer, got {self.frames!r}")
        if self.poses not in POSE_SOURCES:
            raise SpecError(f"split {self.name}: poses must be one of {POSE_SOURCES}, got {self.poses!r}")
        if self.light not in LIGHT_SOURCES:
            raise SpecError(f"split {self.name}: light must be one of {LIGHT_SOURCES}, got {self.light!r}")
        if (self.light == "olat") != (self.olat is not None):
            raise SpecError(f"split {self.name}: light 'olat' and an 'olat' block go together (got light "
                            f"{self.light!r} {'with' if self.olat else 'without'} an olat block)")
        if self.cameras is not None and (not self.cameras or len(set(self.cameras)) != len(self.cameras) or any(
                isinstance(c, bool) or not isinstance(c, int) or c < 0 for c in self.cameras)):
            raise SpecError(f"split {self.name}: cameras must be distinct view indices (>= 0), got {self.cameras!r}")
        bad = [x for x in self.layers if x not in KNOWN_LAYERS]
        if bad or not self.layers:
            raise SpecError(f"split {self.name}: layers must be a non-empty subset of {KNOWN_LAYERS}, got {bad or '[]'}")
        if self.path_traced and self.scene_class is None:
            from .presets import load_scene_classes

            raise SpecError(f"split {self.name}: a split with an 'image' layer must declare its scene_class (one of "
                            f"{sorted(load_scene_classes())}); it chooses the path depth")
        if not self.path_traced and self.scene_class is not None:
            raise SpecError(f"split {self.name}: scene_class {self.scene_class!r} given but the split has no 'image' "
                            "layer, so nothing is path-traced; remove it")


@dataclass(frozen=True)
class CharacterSource:
    """An imported rigged character (`rh-generate --character FILE`) rendered for every subject instead of anny
    characters. Only the file's name and content hash enter the description, and so its digest: a dataset holds no
    machine paths, and another file (or the same name with other content) is another dataset, never resumed into."""

    file: str
    """The file's name (.glb, .gltf or .fbx), without its folder."""
    sha256: str
    """`rh_dataset.characters.imported_reader.character_digest` of the file (a .gltf's external buffers, images too)."""
    scale: float | None = None
    """Multiplier on the imported metres; None = detect metres or centimetres from the character's height."""

    def __post_init__(self) -> None:
        if not isinstance(self.file, str) or not self.file or "/" in self.file or "\\" in self.file:
            raise SpecError(f"character file must be a bare file name, got {self.file!r}")
        if not (isinstance(self.sha256, str) and len(self.sha256) == 64
                and all(c in "0123456789abcdef" for c in self.sha256)):
            raise SpecError(f"character sha256 must be 64 lower-case hex digits, got {self.sha256!r}")
        if self.scale is not None and not (isinstance(self.scale, (int, float)) and 0 < self.scale < 1e6):
            raise SpecError(f"character scale must be a positive number, got {self.scale!r}")


@dataclass(frozen=True)
class ProtocolSpec:
    name: str
    protocol: str
    description: str
    subjects: int
    character_pool: str
    width: int
    height: int
    fov_y_deg: float
    splits: tuple[SplitSpec, ...]
    sunsky: bool = False
    """Whether random lights may also be Mitsuba's analytic sun-and-sky model besides the HDRIs."""
    exposure_ev_range: tuple[float, float] = (-0.5, 0.5)
    hdri_folder: str | None = None
    """A folder of .exr/.hdr maps to draw lights from instead of the bundled Poly Haven set."""
    light_mixture: dict | None = field(default=None, hash=False)
    """kind -> weight (`rh_dataset.lights.MIXTURE_KEYS`: 'real' maps, 'sunsky', 'studio', 'window', 'outdoor')
    the 'random' splits draw their lights from; None = the uniform choice among the maps (protocols a and b).
    'fixed' lights (the training light) never use it, so a mixed scene's train split is its protocol's."""
    character: CharacterSource | None = None
    """An imported character for every subject instead of anny characters; None = anny (the default)."""
    rig: CameraRig | None = None
    """Several cameras per frame (protocol c): every split names the views it renders; None = one camera."""
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        where = self.source or self.name
        if self.protocol not in ("a", "b", "c"):
            raise SpecError(f"{where}: protocol must be 'a', 'b' or 'c', got {self.protocol!r}")
        if (self.protocol == "c") != (self.rig is not None):
            raise SpecError(f"{where}: protocol 'c' (multi-view) and a 'cameras' block go together")
        if not isinstance(self.subjects, int) or self.subjects < 1:
            raise SpecError(f"{self.source or self.name}: subjects must be a positive integer, got {self.subjects!r}")
        for dim in ("width", "height"):
            v = getattr(self, dim)
            if not isinstance(v, int) or not 8 <= v <= 8192:
                raise SpecError(f"resolution {dim} must be an integer in [8, 8192], got {v!r}: "
                                f"pass e.g. --resolution 512 or --resolution 512x384")
        if self.character_pool not in ("benchmark", "pretrain"):
            raise SpecError(f"character_pool must be 'benchmark' or 'pretrain', got {self.character_pool!r}")
        names = [s.name for s in self.splits]
        if len(set(names)) != len(names) or not names:
            raise SpecError(f"{self.source or self.name}: split names must be unique and non-empty: {names}")
        for s in self.splits:
            if (s.cameras is None) != (self.rig is None):
                raise SpecError(f"{where}: split {s.name}: a protocol with a 'cameras' block names each split's "
                                f"cameras, one without names none")
            if s.cameras is not None and max(s.cameras) >= len(self.rig.views):
                raise SpecError(f"{where}: split {s.name}: camera {max(s.cameras)} is not a view of the rig (it has "
                                f"{len(self.rig.views)}: 0..{len(self.rig.views) - 1})")
            if s.light == "train":
                if "train" not in names or names.index("train") >= names.index(s.name) or s.poses != "train":
                    raise SpecError(f"{where}: split {s.name}: light 'train' needs a train split before it and poses "
                                    f"'train' (frame i under train's light of frame i)")
                if self.split("train").light not in ("fixed", "random"):
                    raise SpecError(f"{where}: split {s.name}: light 'train' reuses a fixed or random train light")
            if s.poses in ("train", "test"):
                if s.poses not in names or names.index(s.poses) >= names.index(s.name):
                    raise SpecError(f"split {s.name}: poses {s.poses!r} needs a {s.poses} split before it")
                src = self.splits[names.index(s.poses)]
                if src.light == "olat":
                    raise SpecError(f"split {s.name}: poses {s.poses!r} names an olat split; reuse the poses of a "
                                    f"split with one pose per frame")
                n_poses = -(-s.frames // s.olat.n_directions) if s.olat else s.frames
                if src.frames < n_poses:
                    raise SpecError(f"split {s.name} reuses {s.poses} poses but has more poses ({n_poses}) than "
                                    f"{s.poses} has frames ({src.frames})")
        lo, hi = self.exposure_ev_range
        if not lo <= hi:
            raise SpecError(f"exposure_ev_range must be [low, high] with low <= high, got {self.exposure_ev_range}")
        if self.light_mixture is not None:
            from rh_dataset.lights.sampling import check_mixture  # the lights package imports Mitsuba lazily

            where = self.source or self.name
            if self.sunsky:
                raise SpecError(f"{where}: lights: give sunsky a weight in the mixture instead of sunsky: true")
            try:
                check_mixture(self.light_mixture)
            except ValueError as exc:
                raise SpecError(f"{where}: lights: {exc}") from None

    def split(self, name: str) -> SplitSpec:
        for s in self.splits:
            if s.name == name:
                return s
        raise KeyError(name)

    def with_overrides(self, *, subjects: int | None = None, frames: int | None = None,
                       resolution: tuple[int, int] | None = None, hdri_folder: str | None = None,
                       motion: MotionSpec | None = None,
                       character: CharacterSource | None = None) -> "ProtocolSpec":
        """A copy with command-line overrides applied; `frames` caps every split (for small runs); `motion`
        replaces the pose prior: every split drawing random poses takes the motion's (protocol a: test; protocol
        b: train, whose poses its test split reuses)."""
        spec = self
        if motion is not None:
            if not any(s.poses == "random" for s in spec.splits):
                raise SpecError(f"{spec.source or spec.name}: no split draws poses from the prior ('random'), so "
                                f"there is nothing for --motion to replace")
            spec = dataclasses.replace(spec, splits=tuple(
                dataclasses.replace(s, poses="motion", motion=motion) if s.poses == "random" else s
                for s in spec.splits))
        if character is not None:
            spec = dataclasses.replace(spec, character=character)
        if subjects is not None:
            spec = dataclasses.replace(spec, subjects=subjects)
        if frames is not None:
            if frames < 1:
                raise SpecError(f"--frames must be a positive integer, got {frames}")
            spec = dataclasses.replace(spec, splits=tuple(dataclasses.replace(s, frames=min(frames, s.frames))
                                                          for s in spec.splits))
        if resolution is not None:
            spec = dataclasses.replace(spec, width=resolution[0], height=resolution[1])
        if hdri_folder is not None:
            spec = dataclasses.replace(spec, hdri_folder=hdri_folder)
        return spec

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d.pop("source")
        if d["character"] is None:  # anny datasets keep the description (and digest) they had before imports
            d.pop("character")
        if d["light_mixture"] is None:  # datasets without a mixture keep the description (and digest) they had
            d.pop("light_mixture")
        if d["rig"] is None:  # single-camera protocols keep the description (and digest) they had
            d.pop("rig")
        d["splits"] = [dataclasses.asdict(s) for s in self.splits]
        for split, out in zip(self.splits, d["splits"]):
            if split.olat is None:
                out.pop("olat")  # splits without OLAT lights keep the record (and digest) they always had
            if split.cameras is None:
                out.pop("cameras")
            if split.rr_depth is None:
                out.pop("rr_depth")  # classes without a roulette depth keep the record (and digest) they had
            if split.motion is None:
                out.pop("motion")  # datasets without motion keep the record (and digest) they always had
            else:
                out["motion"] = split.motion.to_json()
        return d

    def digest(self) -> str:
        return hashlib.sha256(dumps_json(self.to_json()).encode()).hexdigest()[:16]


_PROTOCOL_KEYS = {"format", "name", "protocol", "description", "subjects", "character_pool", "resolution",
                  "fov_y_deg", "splits", "lights", "cameras"}
_SPLIT_KEYS = {"frames", "poses", "light", "layers", "motion", "scene_class", "olat", "cameras"}
_MOTION_KEYS = {"file", "start", "stride", "heading", "in_place"}
_OLAT_KEYS = {"directions", "radius_deg", "colour"}
_LIGHT_KEYS = {"sunsky", "exposure_ev_range", "hdri_folder", "mixture"}


def _parse_protocol(path: Path, data: Any) -> ProtocolSpec:
    where = str(path)
    _check_keys(where, data, _PROTOCOL_KEYS, _PROTOCOL_KEYS - {"description", "lights", "cameras"})
    if data["format"] != "rh-scene/1":
        raise SpecError(f"{where}: format must be 'rh-scene/1', got {data['format']!r}")
    res = data["resolution"]
    if not (isinstance(res, list) and len(res) == 2):
        raise SpecError(f"{where}: resolution must be [width, height]")
    splits = []
    if not isinstance(data["splits"], dict):
        raise SpecError(f"{where}: splits must be an object of split name -> split")
    for name, s in data["splits"].items():
        _check_keys(f"{where}: split {name}", s, _SPLIT_KEYS, _SPLIT_KEYS - {"motion", "scene_class", "olat",
                                                                              "cameras"})
        cameras = s.get("cameras")
        if cameras is not None and not isinstance(cameras, list):
            raise SpecError(f"{where}: split {name}: cameras must be a list of view indices, got {cameras!r}")
        motion = None
        if "motion" in s:
            m = s["motion"]
            _check_keys(f"{where}: split {name}: motion", m, _MOTION_KEYS, {"file"})
            file = Path(m["file"])
            if not file.is_absolute():
                file = path.parent / file  # relative to the scene file, like any path in it
            motion = MotionSpec.from_file(file, **{k: v for k, v in m.items() if k != "file"})
        from .presets import load_scene_classes

        cls = s.get("scene_class")
        classes = load_scene_classes()
        if cls is not None and cls not in classes:
            raise SpecError(f"{where}: split {name}: unknown scene_class {cls!r}; known: {sorted(classes)} "
                            f"(rh_dataset/scenes/presets.json)")
        olat = None
        if "olat" in s:
            _check_keys(f"{where}: split {name}: olat", s["olat"], _OLAT_KEYS, {"directions"})
            o = dict(s["olat"])
            if "colour" in o:
                o["colour"] = tuple(o["colour"]) if isinstance(o["colour"], list) else o["colour"]
            try:
                olat = OlatSpec(**o)
            except SpecError as exc:
                raise SpecError(f"{where}: split {name}: {exc}") from None
        try:
            splits.append(SplitSpec(name=name, frames=s["frames"], poses=s["poses"], light=s["light"],
                                    layers=tuple(s["layers"]), motion=motion, scene_class=cls,
                                    max_depth=classes[cls].max_depth if cls is not None else None,
                                    rr_depth=classes[cls].rr_depth if cls is not None else None, olat=olat,
                                    cameras=tuple(cameras) if cameras is not None else None))
        except SpecError as exc:
            raise SpecError(f"{where}: {exc}") from None
    rig = parse_rig(where, data["cameras"]) if "cameras" in data else None
    lights = data.get("lights", {})
    _check_keys(f"{where}: lights", lights, _LIGHT_KEYS, set())
    return ProtocolSpec(
        name=data["name"], protocol=data["protocol"], description=data.get("description", ""),
        subjects=data["subjects"], character_pool=data["character_pool"], width=res[0], height=res[1],
        fov_y_deg=float(data["fov_y_deg"]), splits=tuple(splits), sunsky=bool(lights.get("sunsky", False)),
        exposure_ev_range=tuple(lights.get("exposure_ev_range", (-0.5, 0.5))),
        hdri_folder=lights.get("hdri_folder"), light_mixture=lights.get("mixture"), rig=rig, source=where,
    )


def available_protocols() -> dict[str, Path]:
    return {p.stem: p for p in sorted(SCENES_DIR.glob("*.json")) if p.stem != "presets"}


def load_protocol(name_or_path: str) -> ProtocolSpec:
    """Load `rh_dataset/scenes/<name>.json` ('a' and 'b' are short for protocol_a/protocol_b) or a path to a JSON
    file of the user's own."""
    known = available_protocols()
    aliases = {"a": "protocol_a", "b": "protocol_b", "c": "protocol_c"}
    key = aliases.get(name_or_path, name_or_path)
    path = known.get(key) or Path(name_or_path)
    if not path.is_file():
        raise SpecError(f"unknown protocol {name_or_path!r}: choose one of {sorted(['a', 'b', 'c', *known])} "
                        f"or pass the path of a scene JSON file")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise SpecError(f"{path}: not valid JSON ({exc})") from exc
    return _parse_protocol(path, data)
