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
