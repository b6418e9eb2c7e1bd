"""Every flag of every command-line tool explains itself in --help."""
from __future__ import annotations

import argparse
import importlib

import pytest

PARSERS = ["rana.cli", "rana.pretrain", "rh_dataset.cli", "rh_dataset.export.cli", "rh_eval.cli"]


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
