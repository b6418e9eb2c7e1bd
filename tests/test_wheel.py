"""The package as a user installs it: a wheel in a fresh virtual environment, run from a folder outside the repository.

In: this checkout's pyproject.toml, README.md and package folders. Out: nothing kept (temporary folders). The wheel
is built, installed into a venv that borrows the heavy dependencies (torch, mitsuba, anny...) from this environment,
and its own console scripts run the chain a user runs: `rh-generate --protocol a` (the package-data scene files),
`rh-verify`, `rana-oracle` (the cheapest predictions) and `rh-eval`. About 40 s on 2 cores, most of it rendering
and loading the metrics' networks.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import site
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = [p.rstrip("*") for p in
            tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]["include"]]


def _run(cmd: list, *, cwd: Path, env: dict, timeout: float = 600) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))} exited {proc.returncode}:\n{proc.stdout}\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv folder, a work folder outside the repository, the environment to run the venv's commands in)."""
    tmp = tmp_path_factory.mktemp("wheel")
    # Build from a copy of exactly what goes into the wheel: an in-place build leaves build/ and *.egg-info in the
    # checkout, and setuptools reuses a stale build/lib, so a file deleted from the source could still ship.
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, src / name)
    for pkg in PACKAGES:
        shutil.copytree(REPO / pkg, src / pkg, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "RH_BLENDER_PYTHON")}
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", tmp / "dist", src],
         cwd=tmp, env=clean)
    (wheel,) = (tmp / "dist").glob("relighting_humans-*.whl")

    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", venv], cwd=tmp, env=clean)
    py = venv / "bin" / "python"
    if sys.prefix != sys.base_prefix:
        # This interpreter is itself a venv, whose packages --system-site-packages would not see (it means the
        # base interpreter's): add them after the new venv's own site-packages, .pth files and all.
        outer = [p for p in site.getsitepackages() if Path(p).is_dir()]
        site_dir = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             cwd=tmp, env=clean).stdout.strip())
        (site_dir / "_outer_env.pth").write_text(f"import site; [site.addsitedir(p) for p in {outer!r}]\n")
    # --force-reinstall: the checkout's editable install (same name and version) is visible through the system
    # site-packages, and pip would call the wheel already installed. pip leaves that one alone ("outside
    # environment") and installs the wheel's files into the venv.
    _run([sys.executable, "-m", "pip", "--python", py, "install", "-q", "--no-deps", "--force-reinstall", wheel],
         cwd=tmp, env=clean)

    # The wheel's copy must be the one that runs. The venv's site-packages precede the system ones on sys.path,
    # and the editable install's finder is appended to sys.meta_path, after the path finder, so a plain import
    # finds the wheel. What would still put the checkout first: PYTHONPATH (pytest runs may set it to the
    # checkout; removed above), the current folder (the work folder is outside the repository) and the user
    # site (PYTHONNOUSERSITE).
    env = dict(clean, PYTHONNOUSERSITE="1")
    work = tmp / "work"
    work.mkdir()
    return venv, work, env


def test_the_wheels_copy_runs_with_its_package_data(installed):
    venv, work, env = installed
    probe = (
        "import json, rh_common, rh_dataset, rh_eval, rana, rh_demo, rh_common.blender as rb\n"
        "from rh_dataset.spec import SCENES_DIR, available_protocols, load_protocol\n"
        "from rh_dataset.presets import load_presets\n"
        "print(json.dumps({'files': [m.__file__ for m in (rh_common, rh_dataset, rh_eval, rana, rh_demo)],\n"
        "  'scenes': str(SCENES_DIR), 'checkout': str(rb._source_checkout()),\n"
        "  'protocols': {n: load_protocol(n).to_json() for n in available_protocols()},\n"
        "  'presets': sorted(load_presets())}))\n"
    )
    got = json.loads(_run([venv / "bin" / "python", "-c", probe], cwd=work, env=env).stdout)
    for f in got["files"]:
        assert Path(f).is_relative_to(venv), f"{f} is not the wheel's copy (in {venv})"
    assert Path(got["scenes"]).is_relative_to(venv)
    assert got["checkout"] == "None"  # an installed package must not look for a repository's .blender-venv

    from rh_dataset.spec import available_protocols, load_protocol
    from rh_dataset.presets import load_presets
    here = {n: load_protocol(n).to_json() for n in available_protocols()}
    assert got["protocols"] == json.loads(json.dumps(here))  # the same descriptions, digests and all
    assert {"protocol_a", "protocol_b", "demo", "rana_pretrain"} <= set(got["protocols"])
    assert got["presets"] == sorted(load_presets())

    # Without the setting, Blender's absence is one line naming it and the fix.
    proc = subprocess.run([venv / "bin" / "python", "-m", "rh_common.blender"], cwd=work, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "RH_BLENDER_PYTHON" in proc.stderr and "bpy==5.0.1" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_generate_verify_and_eval_outside_the_repository(installed):
    venv, work, env = installed
    bin_ = venv / "bin"
    _run([bin_ / "rh-generate", "--protocol", "a", "--out", "ds", "--subjects", "1", "--frames", "2",
          "--resolution", "32", "--preset", "draft", "--no-progress"], cwd=work, env=env)
    test_dir = work / "ds" / "subject_000" / "protocol_a" / "test"
    assert (work / "ds" / "manifest.json").is_file() and len(list(test_dir.glob("frame_*.json"))) == 2

    verify = _run([bin_ / "rh-verify", "ds"], cwd=work, env=env)
    assert "4 frames checked: OK" in verify.stdout + verify.stderr

    _run([bin_ / "rana-oracle", "--dataset", "ds", "--protocol", "a", "--out", "pred"], cwd=work, env=env)
    _run([bin_ / "rh-eval", "pred", "--dataset", "ds", "--protocol", "a", "--out", "res/oracle.json"],
         cwd=work, env=env)
    result = json.loads((work / "res" / "oracle.json").read_text())
    assert result["complete"] and result["n_frames_evaluated"] == 2
    psnr, lpips = result["overall"]["image_psnr"]["mean"], result["overall"]["image_lpips"]["mean"]
    assert math.isfinite(psnr) and 10 < psnr < 60 and 0 <= lpips < 0.5  # the lighting bound on its own GT
