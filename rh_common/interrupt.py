"""How every command stops: on SIGINT/SIGTERM, or on a full disk or a forbidden folder, with one line, never a
traceback.

In: a command's `main(argv) -> int`, decorated with `@command("rh-generate")`; while it runs, `on_stop(...)` tells
what is finished so far. Out: the same `main`, which
- on SIGINT (Ctrl-C) or SIGTERM unwinds through every `finally` (so `rh_common.imageio.atomic_path` removes its
  temporary file), prints one line (what is finished, that nothing partial was kept, the command that resumes) and
  returns 130 (SIGINT) or 143 (SIGTERM), as a shell reports a process killed by that signal;
- on an `OSError` ENOSPC, EDQUOT, EACCES, EPERM or EROFS anywhere in its work prints one line naming the file, the
  free space and the fix, and returns 1 (`EXIT_DISK`);
- with `--debug` in its arguments (every command's parser declares it with `add_debug_flag`) lets the traceback
  through instead.

A stop can be lost on the way: Python cannot raise out of a C library's callback (rtree's ctypes stream, under
trimesh's search-tree queries, prints "Exception ignored" and carries on, perhaps with a wrong answer). So the
signal is also remembered, and `checkpoint()` raises it again: `rh_common.imageio.atomic_path` calls it before it
commits a file, so nothing computed across a lost stop is kept; an error that escapes after a stop (the library's
own failure at the lost exception) is reported as that stop.

A further SIGINT/SIGTERM while the command unwinds is ignored, so that the clean-up itself (removing a temporary
file, stopping worker processes) cannot be cut short; `kill -9` stays safe because every write is atomic.
Worker processes call `worker_signals()` first: SIGTERM then unwinds them the same way (a terminated worker leaves
no temporary file either).

The active commands are a process-wide stack because signal handlers are process-wide: a command called from
another (rh-demo runs rh-generate's `main`) nests, and only the outermost one installs handlers and prints.
"""
from __future__ import annotations

import errno
import functools
import shlex
import shutil
import signal
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

__all__ = ["command", "on_stop", "Stopped", "checkpoint", "worker_signals", "signals_kept", "add_debug_flag", "resume_command", "disk_error_line",
           "human_bytes", "nearest_folder", "EXIT_DISK", "DISK_ERRNOS"]

EXIT_DISK = 1
DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS}
_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """Raised in the main thread by SIGINT or SIGTERM once `command` (or `worker_signals`) is in place.

    A KeyboardInterrupt, so code that already cleans up on Ctrl-C cleans up on SIGTERM too."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass
class _Command:
    prog: str
    argv: list[str]
    finished: Callable[[], str] | None = None
    remaining_bytes: Callable[[], int | None] | None = None


_active: list[_Command] = []
# The signal that stopped us: a library may catch our `Stopped` and raise a plain KeyboardInterrupt in its place
# (Ray's blocking calls do), and the line and the exit code must still name SIGTERM.
_received: list[int] = []


def _raise_stopped(signum: int, frame) -> None:
    # The first signal stops the command; later ones are ignored so that no `finally` is interrupted half-way.
    for s in _SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    _received.append(signum)
    raise Stopped(signum)


def checkpoint() -> None:
    """Raise `Stopped` if a stopping signal has arrived: its own exception may have been lost in a C callback (see
    the module docstring). Call it before committing work; outside a command it does nothing."""
    if _received:
        raise Stopped(_received[-1])


def _quiet_lost_stops(previous_hook):
    """A `sys.unraisablehook` that says nothing of a `Stopped` lost in a C callback (Python would print "Exception
    ignored" and its traceback beside the one-line stop): the signal is remembered and raised again at the next
    `checkpoint`. Everything else goes to `previous_hook`."""

    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, Stopped):
            return
        previous_hook(unraisable)

    hook.quiets_lost_stops = True
    return hook


def _install_quiet_hook() -> None:
    if not getattr(sys.unraisablehook, "quiets_lost_stops", False):
        sys.unraisablehook = _quiet_lost_stops(sys.unraisablehook)


def worker_signals() -> None:
    """In a worker process: SIGINT and SIGTERM raise `Stopped`, so the worker unwinds (and removes its temporary
    files) instead of dying mid-write."""
    _install_quiet_hook()
    for s in _SIGNALS:
        signal.signal(s, _raise_stopped)


@contextmanager
def signals_kept() -> Iterator[None]:
    """Around a library's start-up that takes over SIGINT/SIGTERM (ray.init sets a Python SIGTERM handler that
    exits, and its core worker a native one that aborts): the handlers in place before are put back after, at the
    OS level too. Main thread only (elsewhere nothing is changed)."""
    before = {s: signal.getsignal(s) for s in _SIGNALS} if _is_main_thread() else {}
    try:
        yield
    finally:
        for s, handler in before.items():
            if handler is not None:
                signal.signal(s, handler)


def add_debug_flag(parser) -> None:
    """The `--debug` flag every command takes (read by `command` before parsing, declared here for `--help`)."""
    parser.add_argument("--debug", action="store_true",
                        help="on an interruption or a disk/permission error, show the Python traceback instead of "
                             "the one-line message")


def on_stop(finished: Callable[[], str], remaining_bytes: Callable[[], int | None] | None = None) -> None:
    """Tell the running command what to say if it stops now: `finished()` -> e.g. "3 of 8 frames finished",
    `remaining_bytes()` -> the bytes still to write (for a full disk). Outside a command it does nothing."""
    if _active:
        _active[-1].finished = finished
        _active[-1].remaining_bytes = remaining_bytes


def resume_command(prog: str, argv: list[str]) -> str:
    """The command line that reruns (and so resumes) this command, quoted for a POSIX shell."""
    return shlex.join([prog, *argv])


def human_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} TB"


def nearest_folder(path: str | Path) -> Path:
    """`path` if it is a folder, else its nearest existing ancestor folder (where free space is measured)."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p if p.is_dir() else p.parent


def disk_error_line(prog: str, exc: OSError, *, resume: str, finished: str = "",
                    remaining_bytes: int | None = None) -> str:
    """The one line for a full disk, a quota, a forbidden or a read-only folder."""
    target = Path(exc.filename) if exc.filename else None
    folder = nearest_folder(target.parent if target is not None else Path.cwd())
    named = str(target) if target is not None else f"a file in {folder}"
    done = f"{finished}; " if finished else ""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        what = "no space left on device" if exc.errno == errno.ENOSPC else "disk quota exceeded"
        try:
            free = f"{human_bytes(shutil.disk_usage(folder).free)} free in {folder}"
        except OSError:
            free = f"in {folder}"
        need = f", about {human_bytes(remaining_bytes)} still to write" if remaining_bytes else ""
        fix = f"free space there (or move the folder to a larger disk){need}"
        return (f"{prog}: error: {what} writing {named} ({free}); {done}no partial file was kept; {fix}, then "
                f"resume with: {resume}")
    if exc.errno == errno.EROFS:
        return (f"{prog}: error: read-only file system: {named}; {done}no partial file was kept; choose a folder "
                f"on a writable file system, or remount it read-write and resume with: {resume}")
    return (f"{prog}: error: permission denied: {named}; {done}no partial file was kept; check the permissions of "
            f"{folder} (ls -ld {shlex.quote(str(folder))}) or choose a folder you can write to, then resume with: "
            f"{resume}")


def _is_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def command(prog: str, *, not_on_resume: tuple[str, ...] = ()
            ) -> Callable[[Callable[[list[str] | None], int]], Callable[[list[str] | None], int]]:
    """Decorate a command's `main(argv=None) -> int` (see the module docstring). `not_on_resume`: switches the
    resume command leaves out (`--force` restarts a run: repeating it would throw away what was finished)."""

    def decorate(main: Callable[[list[str] | None], int]) -> Callable[[list[str] | None], int]:
        @functools.wraps(main)
        def run(argv: list[str] | None = None) -> int:
            args = list(sys.argv[1:] if argv is None else argv)
            debug = "--debug" in args
            outer = not _active
            cmd = _Command(prog, [a for a in args if a not in not_on_resume and a != "--debug"])
            _active.append(cmd)
            previous = None
            if outer:
                _received.clear()
            hook_before = sys.unraisablehook
            if outer and _is_main_thread():
                _install_quiet_hook()
                previous = {s: signal.signal(s, _raise_stopped) for s in _SIGNALS}
            try:
                return main(argv)
            except KeyboardInterrupt as exc:
                if debug or not outer:
                    raise
                signum = getattr(exc, "signum", None) or (_received[-1] if _received else signal.SIGINT)
                if argv is None:
                    # A console script: the process ends next. Keep further signals ignored, or a second Ctrl-C
                    # during the interpreter's teardown (which restores the default handlers) would replace the
                    # exit code by "killed by SIGINT".
                    previous = None
                return _stopped(prog, cmd, signum)
            except Exception as raised:
                exc = _disk_error(raised) if isinstance(raised, OSError) else None
                if exc is not None and outer and not debug:
                    _say(disk_error_line(prog, exc, resume=resume_command(prog, cmd.argv),
                                         finished=_finished(cmd, ""), remaining_bytes=_call(cmd.remaining_bytes)))
                    return EXIT_DISK
                # After a stop whose exception was lost in a C callback, the library fails in its own way: that
                # failure is the stop's doing, and the user asked for the stop.
                if debug or not outer or not _received:
                    raise
                if argv is None:
                    previous = None
                return _stopped(prog, cmd, _received[-1])
            finally:
                _active.remove(cmd)
                if outer:
                    _received.clear()
                if outer and argv is not None:
                    sys.unraisablehook = hook_before  # called from Python (a test, rh-demo): leave it as it was
                if outer and argv is None and previous is not None:
                    # A console script whose work is done: the interpreter exits next. A Ctrl-C during its
                    # teardown (Ray, Warp, Mitsuba shutting down) would otherwise print a KeyboardInterrupt
                    # traceback and replace the exit status, for a run that finished.
                    previous = {s: signal.SIG_IGN for s in previous}
                if previous is not None:
                    for s, h in previous.items():
                        signal.signal(s, h if h is not None else signal.SIG_DFL)

        return run

    return decorate


def _stopped(prog: str, cmd: _Command, signum: int) -> int:
    _say(f"{prog}: stopped by {signal.Signals(signum).name}: {_finished(cmd)}no partial file was kept; "
         f"resume with: {resume_command(prog, cmd.argv)}")
    return 128 + int(signum)


def _disk_error(exc: BaseException) -> OSError | None:
    """The disk error behind `exc`: itself, or the error a worker raised (a Ray task's error carries it as `cause`,
    re-raised errors as `__cause__`)."""
    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, OSError) and exc.errno in DISK_ERRNOS:
            return exc
        exc = getattr(exc, "cause", None) or exc.__cause__
        seen += 1
    return None


def _call(fn):
    if fn is None:
        return None
    try:
        return fn()
    except Exception:  # a status callback must never turn a clean stop into a traceback
        return None


def _finished(cmd: _Command, sep: str = "; ") -> str:
    text = _call(cmd.finished)
    return f"{text}{sep}" if text else ""


def _say(line: str) -> None:
    if sys.stderr.isatty():
        sys.stderr.write("\n")  # end a progress bar's line, which has no newline of its own
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
