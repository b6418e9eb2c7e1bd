"""RANA configs on disk: JSON with a schema version, and the older forms still read.

In: a `RanaConfig` (`config_to_json`); what a run folder's config.json or a checkpoint's "config" entry holds
(`config_from_json`, `config_from_repr`). Out: a dict of JSON primitives `{"schema": "rana-config/2", <fields>}`,
or a validated `RanaConfig`. Every error is one line that names the key, so a checkpoint of another version never
loads silently with the wrong settings.

Forms written before the schema existed (no "schema" key; read as version 1):

* unversioned dicts (config.json of earlier runs). A field missing there takes the value it had when it did not
  exist yet: `model.residual_coarse` False (direct-output heads), `texture.texturenet_input` 'shaded' (the paper),
  `pretrain.light_source` 'random-sh'; any other missing field its default, as earlier readers did.
* `repr(RanaConfig)` strings (pretrained.pt's "config" entry): parsed as calls of the config classes with literal
  arguments only (nothing is evaluated), then read as an unversioned dict.

A version 2 config must carry every field: a field added later comes with a new version and its own line above.
"""
from __future__ import annotations

import ast
import dataclasses
from typing import Any

from .config import SECTIONS, RanaConfig

__all__ = ["SCHEMA", "config_to_json", "config_from_json", "config_from_repr"]

SCHEMA = "rana-config/2"

# Version 1 -> 2: the fields added after version-1 files were written, at the value those files' runs used.
_V1_DEFAULTS = {"model": {"residual_coarse": False}, "texture": {"texturenet_input": "shaded"},
                "pretrain": {"light_source": "random-sh"}}


def config_to_json(cfg: RanaConfig) -> dict:
    """The config as JSON primitives, led by its schema version; `config_from_json` gives back an equal config."""
    return {"schema": SCHEMA, **dataclasses.asdict(cfg)}


def _keys(where: str, d: dict, known: set[str], complete: bool) -> None:
    unknown = sorted(set(d) - known)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}")
    missing = sorted(known - set(d)) if complete else []
    if missing:
        raise ValueError(f"{where}: missing key(s) {missing} ({SCHEMA} configs carry every field)")


def config_from_json(d: Any) -> RanaConfig:
    """Rebuild a config from `config_to_json`'s dict, or from a version-1 (unversioned) one."""
    if not isinstance(d, dict):
        raise ValueError(f"config: expected a JSON object, got {type(d).__name__}")
    d = dict(d)
    schema = d.pop("schema", None)
    if schema is not None and schema != SCHEMA:
        raise ValueError(f"config: schema {schema!r} is not one this rana reads ({SCHEMA!r} or unversioned); "
                         f"use the rana version that wrote it, or start the run again")
    v1 = schema is None
    _keys("config", d, {f.name for f in dataclasses.fields(RanaConfig)}, complete=not v1)
    kw: dict[str, Any] = {}
    for k, v in d.items():
        if k not in SECTIONS:
            kw[k] = v
            continue
        cls = SECTIONS[k]
        if not isinstance(v, dict):
            raise ValueError(f"config.{k}: expected a JSON object, got {v!r}")
        _keys(f"config.{k}", v, {f.name for f in dataclasses.fields(cls)}, complete=not v1)
        kw[k] = cls(**({**_V1_DEFAULTS.get(k, {}), **v} if v1 else v))
    return RanaConfig(**kw)


def config_from_repr(text: str) -> RanaConfig:
    """A `repr(RanaConfig)` (pretrained.pt before rana-config/2), read without evaluating it: only calls of the
    config classes with keyword arguments that are literals."""
    classes = {c.__name__ for c in (RanaConfig, *SECTIONS.values())}

    def value(node: ast.expr) -> Any:
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in classes \
                and not node.args and all(kw.arg for kw in node.keywords):
            return {kw.arg: value(kw.value) for kw in node.keywords}
        return ast.literal_eval(node)  # raises ValueError on anything else

    try:
        tree = ast.parse(text, mode="eval").body
        if not (isinstance(tree, ast.Call) and getattr(tree.func, "id", None) == "RanaConfig"):
            raise ValueError("not a RanaConfig(...) call")
        d = value(tree)
    except (SyntaxError, ValueError) as exc:
        raise ValueError(f"config: not a stored RanaConfig repr ({' '.join(str(exc).split())})") from exc
    return config_from_json(d)
