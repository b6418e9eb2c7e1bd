"""The render presets and scene classes of rh_dataset/scenes/presets.json, validated.

In: presets.json (or a file of its format). Out: `Preset` (samples per pixel, sampler, path depth, focused-pass
samples, how draped cloth is posed) by name, and `SceneClass` (the path depth a kind of scene needs, with the
measurement it rests on). The protocol files (`spec.py`) name a scene class per split; a preset turns it into a depth
(`Preset.depth_for`) and a Russian-roulette depth (`Preset.roulette_for`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from .scene_files import SCENES_DIR, SpecError, _check_keys

__all__ = ["Preset", "SceneClass", "load_presets", "load_scene_classes"]


@dataclass(frozen=True)
class Preset:
    name: str
    spp: int
    aov_spp: int
    max_depth: int | None
    """None ("scene_class" in the JSON): each split's scene class chooses the depth (`SplitSpec.max_depth`)."""
    sampler: str = "independent"
    """Mitsuba's sample generator for both passes (`rh_dataset.render.sampler`), chosen by bench/bench_sampler.py."""
    env_spp: int | None = None
    """Samples per pixel where no person is (`rh_dataset.render.focus`); None: every pixel gets spp."""
    adaptive_tiers: tuple[int, ...] | None = None
    """Counts a person's pixel may get in proportion to its noise, spp their mean (`rh_dataset.render.adaptive`)."""
    cloth: str = "skinned"
    """How draped garments reach each frame's pose (`RenderSettings.cloth`), chosen by bench/bench_cloth_pose.py."""
    drape: str = "full"
    """How finely draped garments are simulated (`RenderSettings.drape`)."""
    description: str = ""

    def depth_for(self, scene_class: str) -> int:
        """The path depth this preset renders a scene of `scene_class` with."""
        if self.max_depth is not None:
            return self.max_depth
        classes = load_scene_classes()
        if scene_class not in classes:
            raise SpecError(f"unknown scene class {scene_class!r}; known: {sorted(classes)}")
        return classes[scene_class].max_depth

    def roulette_for(self, scene_class: str) -> int | None:
        """The Russian-roulette depth this preset renders a scene of `scene_class` with (None: Mitsuba's default)."""
        if self.max_depth is not None:
            return None
        self.depth_for(scene_class)  # the unknown-class error
        return load_scene_classes()[scene_class].rr_depth


@dataclass(frozen=True)
class SceneClass:
    """A kind of scene whose light transport behaves alike, so one path depth serves all of it.

    `max_depth` is the smallest depth whose truncation error (display-space PSNR over the person against the same
    render at depth 16, same samples) is at least `tolerance_db`; `measured` records the measurement it rests on
    (bench/bench_savings.py, docs/TRADEOFFS.md)."""

    name: str
    max_depth: int
    tolerance_db: float
    rr_depth: int | None = None
    """Depth from which paths end by Russian roulette (unbiased: `RenderSettings.rr_depth`); None: Mitsuba's default."""
    description: str = ""
    measured: dict = field(default_factory=dict, compare=False)


def load_presets(path: Path | None = None) -> dict[str, Preset]:
    """The render presets of rh_dataset/scenes/presets.json (or of `path`, a file of the same format)."""
    from .render.sampler import SAMPLERS

    path = SCENES_DIR / "presets.json" if path is None else Path(path)
    data = json.loads(path.read_text())
    out = {}
    for name, p in data["presets"].items():
        _check_keys(f"{path}: preset {name}", p, {"spp", "aov_spp", "max_depth", "sampler", "env_spp", "cloth", "drape",
                                                   "adaptive_tiers", "description"},
                    {"spp", "aov_spp", "max_depth", "sampler"})
        if p["sampler"] not in SAMPLERS:
            raise SpecError(f"{path}: preset {name}: unknown sampler {p['sampler']!r}; choose one of "
                            f"{', '.join(SAMPLERS)}")
        from .characters.cloth_pose import CLOTH_MODES

        if p.get("cloth", "skinned") not in CLOTH_MODES:
            raise SpecError(f"{path}: preset {name}: cloth must be one of {', '.join(CLOTH_MODES)}, got "
                            f"{p['cloth']!r}")
        from .characters.drape import DRAPE_LEVELS

        if p.get("drape", "full") not in DRAPE_LEVELS:
            raise SpecError(f"{path}: preset {name}: drape must be one of {', '.join(DRAPE_LEVELS)}, got "
                            f"{p['drape']!r}")
        env = p.get("env_spp")
        if env is not None and (not isinstance(env, int) or not 1 <= env <= p["spp"]):
            raise SpecError(f"{path}: preset {name}: env_spp must be an integer in [1, spp] or absent, got {env!r}")
        p = dict(p)
        if p.get("adaptive_tiers") is not None:
            from .render.adaptive import check_tiers

            try:
                p["adaptive_tiers"] = check_tiers(p["adaptive_tiers"], p["spp"], env)
            except ValueError as e:
                raise SpecError(f"{path}: preset {name}: {e}") from None
        if p["max_depth"] == "scene_class":
            p["max_depth"] = None
        elif not isinstance(p["max_depth"], int) or p["max_depth"] < 2:
            raise SpecError(f"{path}: preset {name}: max_depth must be an integer >= 2 or \"scene_class\"")
        out[name] = Preset(name=name, **p)
    return out


def load_scene_classes() -> dict[str, SceneClass]:
    """The scene classes of rh_dataset/scenes/presets.json, each with the path depth its measurement chose."""
    path = SCENES_DIR / "presets.json"
    data = json.loads(path.read_text())
    out = {}
    for name, c in data.get("scene_classes", {}).items():
        _check_keys(f"{path}: scene class {name}", c, {"max_depth", "rr_depth", "tolerance_db", "description",
                                                       "measured"}, {"max_depth", "tolerance_db"})
        if not isinstance(c["max_depth"], int) or c["max_depth"] < 2:
            raise SpecError(f"{path}: scene class {name}: max_depth must be an integer >= 2")
        rr = c.get("rr_depth")
        if rr is not None and (not isinstance(rr, int) or not 1 <= rr <= c["max_depth"]):
            raise SpecError(f"{path}: scene class {name}: rr_depth must be an integer in [1, max_depth] or absent")
        out[name] = SceneClass(name=name, **c)
    return out
