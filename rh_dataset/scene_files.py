"""What the scene files share (rh_dataset/scenes/: protocol and preset JSON): their folder, their error, the key
check. In: nothing. Out: `SCENES_DIR`, `SpecError`, `_check_keys`, for `spec.py` (protocols) and `presets.py`."""
from __future__ import annotations

from pathlib import Path

__all__ = ["SCENES_DIR", "SpecError"]

# Package data (pyproject.toml's package-data), so a wheel carries it: a folder next to the package, as the repo
# once had, is not installed and `rh-generate --protocol a` found no protocols outside a source checkout.
SCENES_DIR = Path(__file__).resolve().parent / "scenes"


class SpecError(ValueError):
    """An invalid scene/protocol description; the message names the file or field and the fix."""


def _check_keys(where: str, data: dict, allowed: set[str], required: set[str]) -> None:
    if not isinstance(data, dict):
        raise SpecError(f"{where}: expected an object, got {type(data).__name__}")
    unknown = set(data) - allowed
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
    missing = required - set(data)
    if missing:
        raise SpecError(f"{where}: missing key(s) {sorted(missing)}")
