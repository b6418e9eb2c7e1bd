"""The one argparse help formatter of our commands: argparse's defaults formatter, minus the noise.

In: nothing (a `formatter_class` for `argparse.ArgumentParser`). Out: `--help` text where a flag's default is shown
once. argparse's `ArgumentDefaultsHelpFormatter` appends "(default: ...)" to every flag, so a help text that already
says what the default is ("(default: the protocol's, 49 for a and b)") got a second, wrong "(default: None)", and
every on/off switch got "(default: False)".
"""
from __future__ import annotations

import argparse

__all__ = ["HelpFormatter"]


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "(default" in text or action.default in (None, False, argparse.SUPPRESS) or action.nargs == 0:
            return text
        return super()._get_help_string(action)
