"""Declarative scene and protocol descriptions (`scenes/*.json`), validated on load.

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

from rh_common.imageio import dumps_json

__all__ = [
    "SCENES_DIR",
    "SpecError",
    "SplitSpec",
    "CharacterSource",
    "ProtocolSpec",
    "Preset",
    "load_protocol",
    "load_presets",
    "available_protocols",
]

SCENES_DIR = Path(__file__).resolve().parent.parent / "scenes"

POSE_SOURCES = ("turntable", "random", "train")
LIGHT_SOURCES = ("fixed", "random")
KNOWN_LAYERS = ("image", "mask", "albedo", "normal", "depth")


class SpecError(ValueError):
    """An invalid scene/protocol description; the message names the file or field and the fix."""


def _check_keys(where: str, data: dict, allowed: set[str], required: set[str]) -> None:
    if not isinstance(data, dict):
        raise SpecError(f"{where}: expected an object, got {type(data).__name__}")
    unknown = set(data) - allowed
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
    missing = required - set(data)
    if missing:
        raise SpecError(f"{where}: missing key(s) {sorted(missing)}")


@dataclass(frozen=True)
class SplitSpec:
    name: str
    frames: int
    poses: str
    """turntable (A-pose, 360 degrees), random (pose prior), or train (the same poses as this protocol's train split)."""
    light: str
    """fixed (one light for the whole split) or random (a new light per frame)."""
    layers: tuple[str, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.frames, int) or self.frames < 1:
            raise SpecError(f"split {self.name}: frames must be a positive integer, got {self.frames!r}")
        if self.poses not in POSE_SOURCES:
            raise SpecError(f"split {self.name}: poses must be one of {POSE_SOURCES}, got {self.poses!r}")
        if self.light not in LIGHT_SOURCES:
            raise SpecError(f"split {self.name}: light must be one of {LIGHT_SOURCES}, got {self.light!r}")
        bad = [x for x in self.layers if x not in KNOWN_LAYERS]
        if bad or not self.layers:
            raise SpecError(f"split {self.name}: layers must be a non-empty subset of {KNOWN_LAYERS}, got {bad or '[]'}")


@dataclass(frozen=True)
class CharacterSource:
    """An imported rigged character (`rh-generate --character FILE`) rendered for every subject instead of anny
    characters. Only the file's name and content hash enter the description, and so its digest: a dataset holds no
    machine paths, and another file (or the same name with other content) is another dataset, never resumed into."""

    file: str
    """The file's name (.glb, .gltf or .fbx), without its folder."""
    sha256: str
    """`rh_dataset.characters.imported.character_digest` of the file (a .gltf's external buffers and images too)."""
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
    character: CharacterSource | None = None
    """An imported character for every subject instead of anny characters; None = anny (the default)."""
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if self.protocol not in ("a", "b"):
            raise SpecError(f"{self.source or self.name}: protocol must be 'a' or 'b', got {self.protocol!r}")
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
            if s.poses == "train":
                if "train" not in names or names.index("train") > names.index(s.name):
                    raise SpecError(f"split {s.name}: poses 'train' needs a train split before it")
                train = self.splits[names.index("train")]
                if train.frames < s.frames:
                    raise SpecError(f"split {s.name} reuses train poses but has more frames ({s.frames}) than train "
                                    f"({train.frames})")
        lo, hi = self.exposure_ev_range
        if not lo <= hi:
            raise SpecError(f"exposure_ev_range must be [low, high] with low <= high, got {self.exposure_ev_range}")

    def split(self, name: str) -> SplitSpec:
        for s in self.splits:
            if s.name == name:
                return s
        raise KeyError(name)

    def with_overrides(self, *, subjects: int | None = None, frames: int | None = None,
                       resolution: tuple[int, int] | None = None, hdri_folder: str | None = None,
                       character: CharacterSource | None = None) -> "ProtocolSpec":
        """A copy with command-line overrides applied; `frames` caps every split (for small runs)."""
        spec = self
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
        d["splits"] = [dataclasses.asdict(s) for s in self.splits]
        return d

    def digest(self) -> str:
        return hashlib.sha256(dumps_json(self.to_json()).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Preset:
    name: str
    spp: int
    aov_spp: int
    max_depth: int
    description: str = ""


_PROTOCOL_KEYS = {"format", "name", "protocol", "description", "subjects", "character_pool", "resolution",
                  "fov_y_deg", "splits", "lights"}
_SPLIT_KEYS = {"frames", "poses", "light", "layers"}
_LIGHT_KEYS = {"sunsky", "exposure_ev_range", "hdri_folder"}


def _parse_protocol(path: Path, data: Any) -> ProtocolSpec:
    where = str(path)
    _check_keys(where, data, _PROTOCOL_KEYS, _PROTOCOL_KEYS - {"description", "lights"})
    if data["format"] != "rh-scene/1":
        raise SpecError(f"{where}: format must be 'rh-scene/1', got {data['format']!r}")
    res = data["resolution"]
    if not (isinstance(res, list) and len(res) == 2):
        raise SpecError(f"{where}: resolution must be [width, height]")
    splits = []
    if not isinstance(data["splits"], dict):
        raise SpecError(f"{where}: splits must be an object of split name -> split")
    for name, s in data["splits"].items():
        _check_keys(f"{where}: split {name}", s, _SPLIT_KEYS, _SPLIT_KEYS)
        splits.append(SplitSpec(name=name, frames=s["frames"], poses=s["poses"], light=s["light"],
                                layers=tuple(s["layers"])))
    lights = data.get("lights", {})
    _check_keys(f"{where}: lights", lights, _LIGHT_KEYS, set())
    return ProtocolSpec(
        name=data["name"], protocol=data["protocol"], description=data.get("description", ""),
        subjects=data["subjects"], character_pool=data["character_pool"], width=res[0], height=res[1],
        fov_y_deg=float(data["fov_y_deg"]), splits=tuple(splits), sunsky=bool(lights.get("sunsky", False)),
        exposure_ev_range=tuple(lights.get("exposure_ev_range", (-0.5, 0.5))),
        hdri_folder=lights.get("hdri_folder"), source=where,
    )


def available_protocols() -> dict[str, Path]:
    return {p.stem: p for p in sorted(SCENES_DIR.glob("*.json")) if p.stem != "presets"}


def load_protocol(name_or_path: str) -> ProtocolSpec:
    """Load `scenes/<name>.json` ('a' and 'b' are short for protocol_a/protocol_b) or a path to a JSON file."""
    known = available_protocols()
    aliases = {"a": "protocol_a", "b": "protocol_b"}
    key = aliases.get(name_or_path, name_or_path)
    path = known.get(key) or Path(name_or_path)
    if not path.is_file():
        raise SpecError(f"unknown protocol {name_or_path!r}: choose one of {sorted(['a', 'b', *known])} "
                        f"or pass the path of a scene JSON file")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise SpecError(f"{path}: not valid JSON ({exc})") from exc
    return _parse_protocol(path, data)


def load_presets() -> dict[str, Preset]:
    path = SCENES_DIR / "presets.json"
    data = json.loads(path.read_text())
    out = {}
    for name, p in data["presets"].items():
        _check_keys(f"{path}: preset {name}", p, {"spp", "aov_spp", "max_depth", "description"},
                    {"spp", "aov_spp", "max_depth"})
        out[name] = Preset(name=name, **p)
    return out
