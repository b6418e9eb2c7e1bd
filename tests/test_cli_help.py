"""Every flag of every command-line tool explains itself in --help: the project's rule, kept by two checks.

  * the installed tools' parsers (rana, rana-pretrain, rh-generate, rh-export, rh-eval), built: every action of
    every subcommand has help text, and says its default at most once;
  * the source, read with `ast` (nothing imported): every `add_argument(...)` call in a .py file of bench/, tools/,
    rh_dataset/, rh_eval/, rana/, rh_common/ and rh_demo/ passes a non-empty `help=` (`argparse.SUPPRESS` counts).
    This reaches the bench scripts and tools whose parsers are built inside `main()` and are never imported by a
    test; it fails listing `file:line flag` for each call without one, and runs in a fraction of a second.
Why: a flag without help text can only be read from its script's code; about a hundred bench flags had none.
"""
from __future__ import annotations

import argparse
import ast
import importlib
from pathlib import Path

import pytest

PARSERS = ["rana.cli", "rana.pretrain", "rh_dataset.cli", "rh_dataset.export.cli", "rh_eval.cli"]
ROOT = Path(__file__).resolve().parents[1]
SOURCE_DIRS = ("bench", "tools", "rh_dataset", "rh_eval", "rana", "rh_common", "rh_demo")


def _undocumented(parser: argparse.ArgumentParser, path: str):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _undocumented(sub, f"{path} {name}")
        elif not isinstance(action, argparse._HelpAction) and not (action.help or "").strip():
            yield f"{path}: {'/'.join(action.option_strings) or action.dest}"


@pytest.mark.parametrize("module", PARSERS)
def test_every_flag_has_help(module):
    parser = importlib.import_module(module).build_parser()
    assert len(parser._actions) > 1
    assert list(_undocumented(parser, module)) == []


@pytest.mark.parametrize("module", PARSERS)
def test_each_default_is_said_once(module):
    """A flag's help says its default at most once, and never the meaningless "(default: None)"."""
    parser = importlib.import_module(module).build_parser()
    parsers = [parser] + [sub for a in parser._actions if isinstance(a, argparse._SubParsersAction)
                          for sub in a.choices.values()]
    for p in parsers:
        for action in p._actions:
            text = p._get_formatter()._expand_help(action) if action.help else ""
            assert text.count("(default") <= 1, (module, action.option_strings, text)
            assert "(default: None)" not in text, (module, action.option_strings, text)


def _calls_without_help(path: Path):
    """`file:line flag` of each `add_argument(...)` call in `path` whose `help=` is missing, None or blank."""
    source = path.read_text()
    if "add_argument" not in source:  # most files: no need to parse them
        return
    for node in ast.walk(ast.parse(source, str(path))):
        if not isinstance(node, ast.Call) or getattr(node.func, "attr", None) != "add_argument":
            continue
        text = next((k.value for k in node.keywords if k.arg == "help"), None)
        blank = text is None or (isinstance(text, ast.Constant) and not (isinstance(text.value, str)
                                                                         and text.value.strip()))
        if blank or (isinstance(text, ast.JoinedStr) and not text.values):
            flag = "/".join(a.value for a in node.args if isinstance(a, ast.Constant) and isinstance(a.value, str))
            yield f"{path.relative_to(ROOT)}:{node.lineno} {flag or '?'}"


def test_every_add_argument_in_the_source_has_help():
    files = [f for d in SOURCE_DIRS for f in sorted((ROOT / d).rglob("*.py"))]
    assert len(files) > 100, f"found only {len(files)} .py files under {ROOT}"
    missing = [m for f in files for m in _calls_without_help(f)]
    assert not missing, f"{len(missing)} add_argument calls without help= text:\n" + "\n".join(missing)
