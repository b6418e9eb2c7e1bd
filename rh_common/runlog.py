"""A long command's log file, so a job on a cluster can be followed without a terminal.

In: the log's path and the lines a command reports (start, settings, progress, warnings, end). Out: one text file
that grows by whole lines, each stamped with UTC time, flushed as written (`tail -f` shows it live). Python warnings
raised while the log is open are written to it too.

A log is appended to, never replaced: a resumed run adds its own block after the earlier runs' blocks. It is a
record of runs, not part of what it logs, so a dataset's manifest and content identity leave it out
(`rh_common.layout.LOG_DIR`).
"""
from __future__ import annotations

import os
import time
import warnings
from pathlib import Path
from typing import TextIO

__all__ = ["RunLog"]


class RunLog:
    """`with RunLog(path) as log: log.line("...")`. Warnings are also shown as usual on stderr."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._file: TextIO | None = None
        self._showwarning = None

    def __enter__(self) -> "RunLog":
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "a", encoding="utf-8")
        self._showwarning = warnings.showwarning
        previous = self._showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            self.line(f"warning: {category.__name__}: {message} ({Path(filename).name}:{lineno})")
            previous(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        return self

    def line(self, text: str) -> None:
        if self._file is None:
            return
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        for part in str(text).splitlines() or [""]:
            self._file.write(f"{stamp} {part}\n")
        self._file.flush()

    def __exit__(self, exc_type, exc, tb) -> None:
        warnings.showwarning = self._showwarning
        if self._file is not None:
            self._file.close()
            self._file = None
