"""Run a script inside Blender's Python (`bpy`), which lives in its own virtual environment.

Why a subprocess: `bpy==5.0.1` (the newest for Python 3.11) pins numpy 1.26, and this environment needs numpy >= 2
(colour-science 0.4.7).

Which interpreter (`blender_python`): the `RH_BLENDER_PYTHON` environment variable, the path of a Python 3.11 that
can `import bpy` (bpy==5.0.1), comes first. Without it, a source checkout uses `<repo>/.blender-venv/bin/python`,
which `bash setup.sh` creates. An installed wheel has no repository to look in, so there the variable is the only
way; when neither is found, `BlenderUnavailable` says so in one line, with the fix.

The contract with a Blender-side script: arguments on its command line, results as files it writes (`.npz` arrays
without pickles, JSON, PNG/EXR images), nothing else. Only plain numpy arrays cross, so the two numpy versions never
meet. The script exits non-zero on failure and says why on stderr; `run_blender_script` turns that into a
`BlenderError` that quotes it.
"""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

__all__ = ["BlenderError", "BlenderUnavailable", "BlenderRun", "blender_python", "run_blender_script"]

ENV_VAR = "RH_BLENDER_PYTHON"
_FIX = (f"set {ENV_VAR} to a Python 3.11 interpreter that has bpy==5.0.1 (`python3.11 -m venv DIR && "
        f"DIR/bin/pip install bpy==5.0.1`), or run `bash setup.sh` in a source checkout (it creates .blender-venv)")


class BlenderError(RuntimeError):
    """A Blender-side script failed; the message carries the script, its arguments and the end of its stderr."""


class BlenderUnavailable(BlenderError):
    """No Python with `bpy` was found; the message says how to install one."""


@dataclasses.dataclass(frozen=True)
class BlenderRun:
    stdout: str
    stderr: str
    seconds: float


def _source_checkout() -> Path | None:
    """The repository root when this package runs from a source checkout (editable install or PYTHONPATH), else None.

    A checkout is recognised by the files that only it has next to the packages (setup.sh, pyproject.toml); an
    installed wheel sits in site-packages, where neither is."""
    root = Path(__file__).resolve().parents[1]
    return root if (root / "setup.sh").is_file() and (root / "pyproject.toml").is_file() else None


def blender_python() -> Path:
    """The interpreter that has `bpy`: $RH_BLENDER_PYTHON, else `<repo>/.blender-venv/bin/python` in a source
    checkout; BlenderUnavailable (one line: what was looked for, and the fix) when there is none."""
    env = os.environ.get(ENV_VAR)
    if env:
        path, where = Path(env), f"{ENV_VAR}={env}"
    elif (repo := _source_checkout()) is not None:
        path = repo / ".blender-venv" / "bin" / "python"
        where = f"{path} ({ENV_VAR} is not set)"
    else:
        raise BlenderUnavailable(f"no Blender Python: {ENV_VAR} is not set and this is no source checkout; {_FIX}")
    if not path.is_file() or not os.access(path, os.X_OK):
        raise BlenderUnavailable(f"no Blender Python at {where}: not an executable file; {_FIX}")
    return path


def run_blender_script(script: str | Path, args: list[str] | tuple[str, ...] = (), *,
                       timeout: float | None = 3600.0, threads: int | None = None) -> BlenderRun:
    """Run `script` with Blender's Python and return its output; raise BlenderError if it fails or times out.

    `threads` caps the threads Blender's own code may use (Cycles reads its own setting; this sets the OpenMP/TBB
    environment so imports and evaluation stay within the budget too)."""
    import time

    script = Path(script)
    if not script.is_file():
        raise BlenderError(f"Blender script {script} does not exist")
    py = blender_python()
    env = dict(os.environ)
    # Our environment's site-packages must not leak into Blender's interpreter (numpy 2 vs 1.26).
    env.pop("PYTHONPATH", None)
    env.pop("PYTHONHOME", None)
    if threads is not None:
        for k in ("OMP_NUM_THREADS", "TBB_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
            env[k] = str(int(threads))
    cmd = [str(py), str(script), *[str(a) for a in args]]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout, check=False)
    except subprocess.TimeoutExpired as e:
        raise BlenderError(f"{script.name} timed out after {timeout} s: {' '.join(cmd)}") from e
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-25:])
        raise BlenderError(f"{script.name} failed (exit {proc.returncode}): {' '.join(cmd)}\n{tail}")
    return BlenderRun(proc.stdout, proc.stderr, seconds)


if __name__ == "__main__":  # `python -m rh_common.blender`: say which Blender would run, and its version
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        probe = Path(d) / "probe.py"
        probe.write_text("import bpy, numpy; print(bpy.app.version_string, numpy.__version__)\n")
        try:
            run = run_blender_script(probe, timeout=120)
        except BlenderError as exc:
            sys.exit(f"python -m rh_common.blender: {exc}")
    print(f"{blender_python()}: Blender {run.stdout.split()[0]}, numpy {run.stdout.split()[1]}", file=sys.stdout)
