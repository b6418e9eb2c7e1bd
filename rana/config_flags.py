"""Command-line flags made from RANA's config: one `--section.field` flag per field, its help the field's docstring.

In: an argparse parser (`add_config_flags`), then the parsed namespace and a preset (`apply_config_flags`). Out: the
preset with every given flag applied, validated as any `RanaConfig` is (a bad value: `ValueError` naming the
flag's field). Mode fields (`Literal`) become flags with choices, so `--help` lists their values. nerfstudio's
habit, without tyro.
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import typing
from typing import Literal

from .config import SECTIONS, RanaConfig, field_types

__all__ = ["add_config_flags", "apply_config_flags", "field_docs"]


@functools.lru_cache(maxsize=None)
def field_docs(cls: type) -> dict[str, str]:
    """The attribute docstrings of a dataclass (the string literal right after each field), by field name."""
    src = inspect.getsource(cls)
    tree = ast.parse(src)
    body = tree.body[0].body  # type: ignore[attr-defined]
    docs: dict[str, str] = {}
    for a, b in zip(body, body[1:]):
        if isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name) and isinstance(b, ast.Expr) \
                and isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
            docs[a.target.id] = " ".join(b.value.value.split())
    return docs


def _parse_bool(s: str) -> bool:
    low = s.lower()
    if low in ("1", "true", "yes", "on"):
        return True
    if low in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected a boolean (true/false), got {s!r}")


def add_config_flags(parser: argparse.ArgumentParser, sections: tuple[str, ...] | None = None) -> None:
    """Add `--section.field` flags (default None = keep the preset's value) with the field docstrings as help."""
    top_docs = field_docs(RanaConfig)
    g = parser.add_argument_group("top-level knobs")
    for name in ("seed", "threads"):
        g.add_argument(f"--{name}", type=int, default=None, help=top_docs[name].replace("%", "%%"))
    for sec, cls in SECTIONS.items():
        if sections is not None and sec not in sections:
            continue
        g = parser.add_argument_group(f"{sec} knobs", (top_docs.get(sec) or "").replace("%", "%%"))
        docs = field_docs(cls)
        for f in dataclasses.fields(cls):
            t = field_types(cls)[f.name]
            # A mode flag lists its values (argparse refuses others); the rest are checked when the config is built.
            kind = dict(choices=typing.get_args(t)) if typing.get_origin(t) is Literal else \
                dict(type=_parse_bool if t is bool else t, metavar=t.__name__.upper())
            g.add_argument(f"--{sec}.{f.name}", dest=f"cfg__{sec}__{f.name}", default=None, **kind,
                           help=f"{docs.get(f.name, '')} (preset value if omitted)".replace("%", "%%"))


def apply_config_flags(cfg: RanaConfig, args: argparse.Namespace) -> RanaConfig:
    """The preset `cfg` with every flag that was given applied."""
    for name in ("seed", "threads"):
        v = getattr(args, name, None)
        if v is not None:
            cfg = dataclasses.replace(cfg, **{name: v})
    for key, v in vars(args).items():
        if not key.startswith("cfg__") or v is None:
            continue
        _, sec, name = key.split("__")
        cfg = dataclasses.replace(cfg, **{sec: dataclasses.replace(getattr(cfg, sec), **{name: v})})
    return cfg
