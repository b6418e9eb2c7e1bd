"""Run folders: config beside the checkpoints, `checkpoints/step-%09d.pt`, a JSONL loss log, resume.

    <run>/config.json            the full RanaConfig (written when the run starts; a resume must match it)
    <run>/checkpoints/step-000001000.pt
    <run>/losses.jsonl           one JSON object per logged step: {"step", "phase", "seconds", <loss terms>}

Checkpoints are written atomically (temporary file, fsync, rename): a run killed at any moment resumes from the
newest complete one, and the loss log is cut back to that step so the plot has no duplicated stretch.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import torch

from rh_common.imageio import atomic_path, read_json, write_json

from .config import RanaConfig, config_from_json, config_to_json

__all__ = ["RunDir", "ConfigMismatch"]

_CKPT = re.compile(r"^step-(\d{9})\.pt$")


def _comparable(d: dict) -> dict:
    # Knobs that do not change results (thread count, the preset's name) may differ between a run and its resume.
    d = json.loads(json.dumps(d))
    for k in ("threads", "preset"):
        d.get("config", {}).pop(k, None)
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
            old = read_json(p)
            if _comparable(json.loads(json.dumps(new))) != _comparable(old):
                raise ConfigMismatch(
                    f"{p} was written with other settings; resume with the same flags, choose another run folder, "
                    f"or pass --force to restart it")
        write_json(p, new)

    def read_config(self) -> tuple[RanaConfig, dict]:
        d = read_json(self.path / "config.json")
        return config_from_json(d["config"]), {k: v for k, v in d.items() if k != "config"}

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
        return torch.load(path, map_location="cpu", weights_only=False)

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
