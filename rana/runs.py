"""Run folders and the files rana trains into: config beside the checkpoints, `checkpoints/step-%09d.pt`, a JSONL
loss log, resume; and `pretrained.pt`, what rana-pretrain hands to personalization.

    <run>/config.json            {"config": <rana-config/2 JSON>, <run facts>} (written when the run starts; a
                                 resume must match it)
    <run>/checkpoints/step-000001000.pt
    <run>/losses.jsonl           one JSON object per logged step: {"step", "phase", "seconds", <loss terms>}

Checkpoints are written atomically (temporary file, fsync, rename): a run killed at any moment resumes from the
newest complete one, and the loss log is cut back to that step so the plot has no duplicated stretch.

Every checkpoint holds only tensors, plain containers and numbers/strings (a config as its JSON dict), and is read
with `torch.load(weights_only=True)` (`load_tensors`): opening a checkpoint cannot run code. Files written by
earlier versions held nothing else (their one odd entry, pretrained.pt's config as `repr(config)`, is a string,
read by `config_from_repr`), so they still load; a file that does hold other objects is refused in one line that
says how to make it again.
"""
from __future__ import annotations

import json
import pickle
import re
from dataclasses import dataclass, field
from pathlib import Path

import torch

from rh_common.imageio import atomic_path, read_json, write_json

from .config import RanaConfig
from .config_json import config_from_json, config_from_repr, config_to_json

__all__ = ["RunDir", "ConfigMismatch", "Pretrained", "load_tensors"]

_CKPT = re.compile(r"^step-(\d{9})\.pt$")


def load_tensors(path: str | Path, remedy: str):
    """`torch.load(weights_only=True)` on the CPU: tensors, plain containers and primitives only. A file holding
    other objects raises a one-line ValueError ending in `remedy` (how to write that file again)."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        raise ValueError(f"{path}: holds objects other than tensors, containers and numbers (an older or foreign "
                         f"file); {remedy}") from exc


def _comparable(d: dict) -> dict:
    # The config as this version writes it (an older config.json reads through its migration, so a run started
    # before the schema resumes when its settings are the same); knobs that do not change results (thread count,
    # the preset's name) may differ between a run and its resume.
    d = json.loads(json.dumps(d))
    d["config"] = config_to_json(config_from_json(d.get("config")))
    for k in ("threads", "preset"):
        d["config"].pop(k, None)
    return d


class ConfigMismatch(ValueError):
    """Resuming a run with another configuration."""


class RunDir:
    def __init__(self, path: str | Path):
        self.path = Path(path)

    @property
    def ckpt_dir(self) -> Path:
        return self.path / "checkpoints"

    @property
    def log_path(self) -> Path:
        return self.path / "losses.jsonl"

    def clear(self) -> None:
        """Forget a previous run in this folder (checkpoints, loss log, cached coarse stage); used by --force."""
        for _, p in self.checkpoints():
            p.unlink(missing_ok=True)
        for name in ("losses.jsonl", "coarse.pt"):
            (self.path / name).unlink(missing_ok=True)

    # ------------------------------------------------------------------------------ config
    def init_config(self, cfg: RanaConfig, extra: dict | None = None, *, force: bool = False) -> None:
        """Write config.json, or check it equals the existing one (a resume with other settings is refused)."""
        p = self.path / "config.json"
        new = {"config": config_to_json(cfg), **(extra or {})}
        if p.is_file() and not force:
            try:
                old = _comparable(read_json(p))
            except ValueError as exc:
                raise ConfigMismatch(f"{p}: {exc}; pass --force to restart the run with this version") from exc
            if _comparable(new) != old:
                raise ConfigMismatch(
                    f"{p} was written with other settings; resume with the same flags, choose another run folder, "
                    f"or pass --force to restart it")
        write_json(p, new)

    def read_config(self) -> tuple[RanaConfig, dict]:
        """The run's config and the other facts stored beside it (dataset, subject, ...)."""
        p = self.path / "config.json"
        d = read_json(p)
        try:
            return config_from_json(d.get("config")), {k: v for k, v in d.items() if k != "config"}
        except ValueError as exc:
            raise ValueError(f"{p}: {exc}") from exc

    # ------------------------------------------------------------------------------ checkpoints
    def checkpoints(self) -> list[tuple[int, Path]]:
        if not self.ckpt_dir.is_dir():
            return []
        out = []
        for p in self.ckpt_dir.iterdir():
            m = _CKPT.match(p.name)
            if m:
                out.append((int(m.group(1)), p))
        return sorted(out)

    def latest(self) -> tuple[int, Path] | None:
        c = self.checkpoints()
        return c[-1] if c else None

    def save(self, step: int, state: dict, keep: int = 0) -> Path:
        p = self.ckpt_dir / f"step-{step:09d}.pt"
        with atomic_path(p) as tmp:
            torch.save({"step": step, **state}, tmp)
        # The config is also copied beside the checkpoints, so a checkpoints folder alone is self-describing.
        cfg = self.path / "config.json"
        if cfg.is_file():
            write_json(self.ckpt_dir / "config.json", read_json(cfg))
        if keep > 0:
            for _, old in self.checkpoints()[:-keep]:
                old.unlink(missing_ok=True)
        return p

    def load(self, path: Path | None = None) -> dict:
        if path is None:
            latest = self.latest()
            if latest is None:
                raise FileNotFoundError(f"{self.ckpt_dir}: no checkpoints (train the run first)")
            path = latest[1]
        return load_tensors(path, f"rerun `rana train` with --force for the run folder {self.path} to write it again")

    def resume(self, parts: dict) -> int:
        """Load the newest checkpoint into `parts` (name -> module or optimizer; None entries are skipped), cut
        the loss log back to its step and return that step; 0 when there is no checkpoint."""
        latest = self.latest()
        if latest is None:
            return 0
        st = self.load(latest[1])
        for name, obj in parts.items():
            if obj is not None:
                obj.load_state_dict(st[name])
        self.truncate_log(latest[0])
        return latest[0]

    # ------------------------------------------------------------------------------ loss log
    def truncate_log(self, step: int) -> None:
        """Drop log lines at or after `step` (they belong to work lost since that checkpoint)."""
        if not self.log_path.is_file():
            return
        keep = []
        for line in self.log_path.read_text().splitlines():
            try:
                if json.loads(line)["step"] < step:
                    keep.append(line)
            except (ValueError, KeyError):
                continue
        with atomic_path(self.log_path) as tmp:
            tmp.write_text("".join(k + "\n" for k in keep))

    def log(self, record: dict) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        with open(self.log_path, "a") as f:
            f.write(json.dumps(record, sort_keys=True) + "\n")

    def read_log(self) -> list[dict]:
        if not self.log_path.is_file():
            return []
        return [json.loads(l) for l in self.log_path.read_text().splitlines() if l.strip()]


@dataclass
class Pretrained:
    """`<out>/pretrained.pt`: G_N and G_A (and TextureNet) after pretraining, with the config they were trained
    with, what `rana train --pretrained` starts from."""

    G_N: dict  # state dicts
    G_A: dict
    config: RanaConfig
    texturenet: dict | None = None
    subjects: list[str] = field(default_factory=list)  # the pretraining characters

    @property
    def texturenet_input(self) -> str:
        """What the TextureNet was trained to start from (older files without the field: 'shaded', via the
        config's version-1 reading)."""
        return self.config.texture.texturenet_input

    def save(self, path: str | Path) -> Path:
        with atomic_path(Path(path)) as tmp:
            torch.save({"G_N": self.G_N, "G_A": self.G_A, "texturenet": self.texturenet,
                        "config": config_to_json(self.config), "subjects": list(self.subjects)}, tmp)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> "Pretrained":
        remedy = "run rana-pretrain again to rewrite it"
        d = load_tensors(path, remedy)
        try:
            stored = d["config"]
            cfg = config_from_repr(stored) if isinstance(stored, str) else config_from_json(stored)
            return cls(d["G_N"], d["G_A"], cfg, d.get("texturenet"), list(d.get("subjects", [])))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{path}: not a pretrained.pt of rana-pretrain ({exc}); {remedy}") from exc
