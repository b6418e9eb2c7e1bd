"""constraints.txt is the exact dependency closure that is installed, and pyproject's ranges admit every pin."""
from __future__ import annotations

import importlib.metadata as md
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def _pins() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, sep, version = line.partition("==")
            assert sep and version, f"constraints.txt: {line!r} is not an exact pin (name==version)"
            pins[canonicalize_name(name)] = version
    return pins


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _direct() -> list[Requirement]:
    p = _project()
    return [Requirement(r) for r in p["dependencies"] + p["optional-dependencies"]["dev"]]


def _closure() -> dict[str, str]:
    """Installed version of every package pyproject's dependencies (and dev extra) pull in, recursively."""
    todo, seen = _direct(), {}
    while todo:
        req = todo.pop()
        key = canonicalize_name(req.name)
        if key in seen:
            continue
        dist = md.distribution(req.name)
        seen[key] = dist.version
        todo += [q for q in map(Requirement, dist.requires or [])
                 if q.marker is None or q.marker.evaluate({"extra": ""})]
    return seen


def test_constraints_pin_exactly_the_installed_closure():
    pins, installed = _pins(), _closure()
    assert set(pins) == set(installed), (f"not pinned: {sorted(set(installed) - set(pins))}; "
                                         f"pinned but not a dependency: {sorted(set(pins) - set(installed))}")
    # A local build label (torch's "+cpu") is where the wheel came from, not another version.
    wrong = {k: (pins[k], v) for k, v in installed.items() if Version(v).public != Version(pins[k]).public}
    assert not wrong, f"installed versions differ from constraints.txt (pin, installed): {wrong}"


def test_pyproject_ranges_admit_every_pin():
    pins = _pins()
    for req in _direct():
        v = pins[canonicalize_name(req.name)]
        assert req.specifier.contains(v, prereleases=True), f"pyproject {req} excludes the pin {v}"


def test_frame_versions_record_every_pixel_package():
    from rh_dataset.generate.frames import PIXEL_PACKAGES, versions

    pins, rec = _pins(), versions()
    for pkg in PIXEL_PACKAGES:
        assert canonicalize_name(pkg) in pins, f"{pkg} changes pixels but is not pinned"
        assert Version(rec[pkg]).public == Version(pins[canonicalize_name(pkg)]).public
    assert rec["llvm"].count(".") == 2
