"""The bpy subprocess bridge: arrays cross as .npz, failures come back as errors that quote Blender's stderr."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.blender import BlenderError, BlenderUnavailable, blender_python, run_blender_script


def test_round_trip_through_blender(tmp_path):
    script = tmp_path / "cube.py"
    out = tmp_path / "cube.npz"
    script.write_text(
        "import sys, bpy, numpy as np\n"
        "bpy.ops.wm.read_factory_settings(use_empty=True)\n"
        "bpy.ops.mesh.primitive_cube_add(size=2.0)\n"
        "me = bpy.context.active_object.data\n"
        "v = np.array([x.co[:] for x in me.vertices])\n"
        "np.savez(sys.argv[1], vertices=v, numpy=np.array(np.__version__))\n"
    )
    run_blender_script(script, [out], timeout=300)
    with np.load(out, allow_pickle=False) as z:
        v = z["vertices"]
        bpy_numpy = str(z["numpy"])
    # A size-2 cube centred at the origin: 8 corners at +-1.
    assert v.shape == (8, 3)
    np.testing.assert_array_equal(np.sort(np.abs(v).ravel()), np.ones(24))
    assert len({tuple(r) for r in np.sign(v)}) == 8
    assert bpy_numpy.startswith("1.26")  # bpy's pinned numpy, isolated from ours
    assert np.__version__.split(".")[0] == "2"


def test_failure_quotes_stderr(tmp_path):
    script = tmp_path / "bad.py"
    script.write_text("import sys\nsys.stderr.write('no armature in model.glb\\n')\nsys.exit(3)\n")
    with pytest.raises(BlenderError, match="no armature in model.glb"):
        run_blender_script(script, timeout=60)


def test_missing_interpreter_names_the_fix(monkeypatch, tmp_path):
    monkeypatch.setenv("RH_BLENDER_PYTHON", str(tmp_path / "nope" / "python"))
    with pytest.raises(BlenderUnavailable, match="setup.sh"):
        blender_python()


def test_the_setting_wins_and_errors_are_one_line(monkeypatch, tmp_path):
    import rh_common.blender as rb

    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\n")
    fake.chmod(0o755)
    monkeypatch.setenv("RH_BLENDER_PYTHON", str(fake))
    assert blender_python() == fake  # the setting comes before any checkout's .blender-venv

    # An installed wheel: no checkout to look in, so the setting is the only way, and the error says how.
    monkeypatch.delenv("RH_BLENDER_PYTHON")
    monkeypatch.setattr(rb, "_source_checkout", lambda: None)
    with pytest.raises(BlenderUnavailable) as exc:
        blender_python()
    msg = str(exc.value)
    assert "\n" not in msg and "RH_BLENDER_PYTHON" in msg and "bpy==5.0.1" in msg and "setup.sh" in msg

    # A checkout without .blender-venv: names the path it looked at and the same fix.
    monkeypatch.setattr(rb, "_source_checkout", lambda: tmp_path)
    with pytest.raises(BlenderUnavailable, match=r"\.blender-venv/bin/python.*RH_BLENDER_PYTHON") as exc:
        blender_python()
    assert "\n" not in str(exc.value)
