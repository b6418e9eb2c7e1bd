"""Stopping commands: SIGINT/SIGTERM and full or forbidden disks give one line, an exit code, no partial file, and a
resume command that finishes the same dataset an uninterrupted run makes (rh_common.interrupt)."""
from __future__ import annotations

import errno
import glob
import os
import shlex
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from rh_common import interrupt
from rh_common.imageio import atomic_path, read_json, write_exr, write_png

REPO = Path(__file__).resolve().parents[1]
TINY = ["--subjects", "1", "--frames", "2", "--resolution", "32", "--spp", "4", "--aov-spp", "2", "--max-depth", "3",
        "--drape", "coarse", "--no-progress"]
ENV = {**os.environ, "PYTHONPATH": str(REPO)}

# A command that writes files atomically forever, for the mechanism alone (no renderer: it starts in a fraction of
# a second). It prints READY once it is inside its loop.
TOY = textwrap.dedent("""
    import sys
    import numpy as np
    from rh_common.imageio import write_exr, write_png
    from rh_common.interrupt import command, on_stop

    @command("toy")
    def main(argv=None):
        out = (sys.argv[1:] if argv is None else argv)[0]
        n = [0]
        on_stop(lambda: f"{n[0]} files written")
        img = np.random.default_rng(0).random((256, 256, 3), dtype=np.float32)
        print("READY", flush=True)
        while True:
            write_exr(f"{out}/a.exr", img)
            write_png(f"{out}/b.png", (img * 255).astype(np.uint8))
            n[0] += 2

    sys.exit(main())
""")


def _lines(text: str, prefix: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(prefix)]


def _toy(tmp_path: Path) -> subprocess.Popen:
    script = tmp_path / "toy.py"
    script.write_text(TOY)
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV)
    assert proc.stdout.readline().strip() == "READY"
    time.sleep(0.3)
    return proc


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_stops_a_command_with_one_line_and_no_temporary_file(tmp_path, sig, code):
    proc = _toy(tmp_path)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    line = err.strip()
    assert line.startswith(f"toy: stopped by {signal.Signals(sig).name}: ") and "files written" in line
    assert "no partial file was kept" in line and line.endswith(f"resume with: toy {tmp_path}")
    assert not list(tmp_path.glob(".*.tmp"))


# A command whose stop lands inside a C library's callback (rtree's ctypes stream under trimesh does this): Python
# prints "Exception ignored" and the callback returns as if nothing happened. The command then computes a result
# that may be wrong and tries to keep it.
LOST = textwrap.dedent("""
    import ctypes, sys, time
    import numpy as np
    from rh_common.imageio import write_png
    from rh_common.interrupt import command

    def busy():
        print("READY", flush=True)
        while True:
            time.sleep(0.01)

    @command("lost")
    def main(argv=None):
        out = (sys.argv[1:] if argv is None else argv)[0]
        ctypes.CFUNCTYPE(None)(busy)()  # the stop is raised in here, and lost
        print("AFTER", flush=True)
        write_png(f"{out}/result.png", np.zeros((4, 4), np.uint8))
        return 0

    sys.exit(main())
""")


def test_a_stop_lost_in_a_c_callback_still_stops_before_anything_is_kept(tmp_path):
    script = tmp_path / "lost.py"
    script.write_text(LOST)
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV)
    assert proc.stdout.readline().strip() == "READY"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert "AFTER" in out  # the stop was indeed lost where it was raised
    assert proc.returncode == 130, err
    # One line: not Python's "Exception ignored ... Traceback" of the lost exception beside it.
    assert err.strip().splitlines() == [err.strip()] and "Traceback" not in err
    assert err.strip().startswith("lost: stopped by SIGINT: no partial file was kept")
    assert not (tmp_path / "result.png").exists() and not list(tmp_path.glob(".*.tmp"))


def test_a_ctrl_c_after_a_console_script_finished_changes_nothing(tmp_path):
    """Between a finished main and the process's end (libraries shutting down) a Ctrl-C is ignored: no traceback,
    exit status 0."""
    script = tmp_path / "done.py"
    script.write_text(textwrap.dedent("""
        import sys, time
        from rh_common.interrupt import command

        @command("done")
        def main(argv=None):
            return 0

        rc = main()
        print("DONE", flush=True)
        time.sleep(1.0)  # a library's teardown
        sys.exit(rc)
    """))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV)
    assert proc.stdout.readline().strip() == "DONE"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and err == ""


def test_a_second_ctrl_c_while_stopping_leaves_no_temporary_file(tmp_path):
    for _ in range(5):  # different moments inside the writes
        proc = _toy(tmp_path)
        proc.send_signal(signal.SIGINT)
        for _ in range(20):
            try:
                proc.send_signal(signal.SIGINT)
            except ProcessLookupError:
                break
            time.sleep(0.001)
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 130 and "Traceback" not in err, (proc.returncode, err)
        assert len(_lines(err, "toy: stopped by SIGINT")) == 1, err
        assert not list(tmp_path.glob(".*.tmp")), (list(tmp_path.iterdir()), err)


def test_debug_shows_the_traceback(tmp_path):
    @interrupt.command("toy")
    def main(argv=None):
        raise KeyboardInterrupt

    assert main([]) == 130
    with pytest.raises(KeyboardInterrupt):
        main(["--debug"])


@pytest.mark.parametrize("code, words", [
    (errno.ENOSPC, ["no space left on device", "free in", "free space there"]),
    (errno.EACCES, ["permission denied", "ls -ld", "choose a folder you can write to"]),
    (errno.EROFS, ["read-only file system", "writable file system"]),
])
def test_disk_and_permission_errors_are_one_line_naming_the_file_and_the_fix(tmp_path, capsys, code, words):
    target = tmp_path / "ds" / "frame_000000_image.png"
    calls = []

    @interrupt.command("toy")
    def main(argv=None):
        calls.append(argv)
        interrupt.on_stop(lambda: "3 of 8 frames finished and kept", lambda: 5_000_000)
        write_png(target, np.zeros((4, 4), np.uint8))
        raise OSError(code, os.strerror(code), str(target))

    assert main(["--out", str(tmp_path / "ds")]) == interrupt.EXIT_DISK
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(target) in err
    for w in words:
        assert w in err
    assert "3 of 8 frames finished and kept" in err and err.endswith(f"resume with: toy --out {tmp_path / 'ds'}")
    if code == errno.ENOSPC:
        assert "about 5.0 MB still to write" in err
    # An error that is not about the disk is not ours to word: it propagates.
    @interrupt.command("toy")
    def other(argv=None):
        raise OSError(errno.EIO, "I/O error")

    with pytest.raises(OSError):
        other([])


def test_an_encoder_that_fills_the_disk_names_the_file_and_keeps_nothing(tmp_path, monkeypatch):
    """OpenEXR says "No space left on device" in a RuntimeError and PIL names no file: both become OSError(ENOSPC)
    naming the file being written, and the temporary file is gone."""
    import OpenEXR

    def full(self, *a, **k):
        raise RuntimeError('Failed to write pixel data to image file "x.tmp". No space left on device.')

    monkeypatch.setattr(OpenEXR.File, "write", full)
    with pytest.raises(OSError) as info:
        write_exr(tmp_path / "a.exr", np.zeros((4, 4, 3), np.float32))
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "a.exr")
    with pytest.raises(OSError) as info:
        with atomic_path(tmp_path / "b.png") as tmp:
            tmp.write_bytes(b"half")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert info.value.filename == str(tmp_path / "b.png")
    assert list(tmp_path.iterdir()) == []


def test_every_command_stops_through_the_shared_mechanism():
    """Each console script's main is wrapped by rh_common.interrupt.command and takes --debug."""
    import importlib
    import tomllib

    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    for name, target in scripts.items():
        module, func = target.split(":")
        main = getattr(importlib.import_module(module), func)
        assert getattr(main, "__wrapped__", None) is not None, f"{name}: main is not decorated with interrupt.command"
        src = Path(importlib.import_module(module).__file__).read_text()
        assert "add_debug_flag" in src, f"{name}: no --debug flag"


# --- rh-generate, for real -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    from rh_dataset.cli import main as generate_main

    out = tmp_path_factory.mktemp("ref") / "ds"
    assert generate_main(["--protocol", "a", "--out", str(out), *TINY]) == 0
    return read_json(out / "manifest.json")["files"]


def _generate(out: Path, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "rh_dataset.cli", "--protocol", "a", "--out", str(out), *TINY, *extra]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=ENV,
                            start_new_session=True)


def _wait_for_first_frame(proc: subprocess.Popen, out: Path) -> None:
    deadline = time.time() + 600
    while not glob.glob(f"{out}/subject_*/protocol_a/train/frame_000000.json"):
        assert proc.poll() is None, proc.stderr.read()
        assert time.time() < deadline
        time.sleep(0.05)


def _alive(pid: str) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] not in ("Z", "X")
    except OSError:
        return False


def _resume(line: str) -> int:
    """Run the command the stop line prints, as `python -m rh_dataset.cli` (the console script is /work/main's)."""
    argv = shlex.split(line.split("resume with: ", 1)[1])
    assert argv[0] == "rh-generate"
    return subprocess.run([sys.executable, "-m", "rh_dataset.cli", *argv[1:]], env=ENV,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode


def test_ctrl_c_stops_rh_generate_and_the_printed_command_resumes_to_the_same_dataset(tmp_path, reference):
    out = tmp_path / "ds"
    proc = _generate(out)
    _wait_for_first_frame(proc, out)
    os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C does: the whole foreground process group
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130 and "Traceback" not in err
    [line] = _lines(err, "rh-generate: ")
    assert line.startswith("rh-generate: stopped by SIGINT: ") and "of 4 frames finished and kept" in line
    assert not list(out.rglob("*.tmp")) and not (out / "manifest.json").exists()
    assert _resume(line) == 0
    assert read_json(out / "manifest.json")["files"] == reference


@pytest.mark.slow
def test_sigterm_stops_rh_generate_workers_and_resumes(tmp_path, reference):
    """SIGTERM to the parent alone (as a batch scheduler sends it): its worker processes stop too."""
    out = tmp_path / "ds"
    proc = _generate(out, "--workers", "2")
    _wait_for_first_frame(proc, out)
    children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 143 and "Traceback" not in err
    [line] = _lines(err, "rh-generate: ")
    assert line.startswith("rh-generate: stopped by SIGTERM: ")
    assert children  # the worker (and multiprocessing's resource tracker, which ends once its parent has)
    deadline = time.time() + 30
    while any(_alive(pid) for pid in children) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in children)
    assert not list(out.rglob("*.tmp"))
    assert _resume(line) == 0
    assert read_json(out / "manifest.json")["files"] == reference


def test_a_full_disk_mid_run_is_one_line_and_resumes_to_the_same_dataset(tmp_path, reference, capsys, monkeypatch):
    """The disk fills at the third PNG: the line names that file and the space still needed, nothing partial is
    kept, and once there is room the printed command finishes the dataset bit-identically."""
    from rh_common.layout import frames
    from rh_dataset.cli import main as generate_main

    real = frames.write_png
    count = [0]

    def fills_up(path, image):
        count[0] += 1
        if count[0] == 3:
            with atomic_path(path) as tmp:
                tmp.write_bytes(b"part of a PNG")
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(path, image)

    monkeypatch.setattr(frames, "write_png", fills_up)
    out = tmp_path / "ds"
    assert generate_main(["--protocol", "a", "--out", str(out), *TINY]) == interrupt.EXIT_DISK
    err = capsys.readouterr().err
    [line] = _lines(err, "rh-generate: ")
    assert "no space left on device writing " in line and "frame_000001" in line
    assert "1 of 4 frames finished and kept" in line and "still to write" in line
    assert not list(out.rglob("*.tmp"))
    monkeypatch.setattr(frames, "write_png", real)
    argv = shlex.split(line.split("resume with: ", 1)[1])
    assert generate_main(argv[1:]) == 0
    assert read_json(out / "manifest.json")["files"] == reference


def _mount_tmpfs(path: Path, size: str) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True).returncode == 0


def test_a_real_full_tmpfs_then_more_room_resumes(tmp_path, reference):
    mnt = tmp_path / "small"
    if not _mount_tmpfs(mnt, "120k"):
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        out = mnt / "ds"
        proc = subprocess.run([sys.executable, "-m", "rh_dataset.cli", "--protocol", "a", "--out", str(out), *TINY,
                               "--no-space-check"], env=ENV, capture_output=True, text=True)
        assert proc.returncode == interrupt.EXIT_DISK and "Traceback" not in proc.stderr
        [line] = _lines(proc.stderr, "rh-generate: ")
        assert "no space left on device writing " + str(out) in line
        assert not list(out.rglob("*.tmp"))
        subprocess.run(["mount", "-o", "remount,size=20m", str(mnt)], check=True)
        assert _resume(line) == 0
        assert read_json(out / "manifest.json")["files"] == reference
    finally:
        subprocess.run(["umount", str(mnt)])


def test_a_run_that_cannot_fit_is_refused_before_anything_is_written(tmp_path, capsys, monkeypatch):
    import shutil

    from rh_dataset import space
    from rh_dataset.cli import main as generate_main

    monkeypatch.setattr(space.shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(10**9, 10**9 - 500, 500))
    out = tmp_path / "ds"
    assert generate_main(["--protocol", "a", "--out", str(out), *TINY]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--no-space-check" in err[0] and "500 B free" in err[0]
    assert not out.exists()


def test_the_estimate_counts_only_what_is_left(tmp_path, reference):
    from rh_dataset import space
    from rh_dataset.cli import build_parser, options_from_args

    plan, _ = options_from_args(build_parser().parse_args(["--protocol", "a", "--out", str(tmp_path / "x"), *TINY]))
    est = space.remaining_bytes(plan)
    # 2 train frames (image, mask) and 2 test frames (every layer) at 32x32, and two contact sheets.
    px = 32 * 32
    train = sum(space.BYTES_PER_PIXEL[k] for k in ("image.exr", "image.png", "mask.png")) * px
    test = sum(space.BYTES_PER_PIXEL.values()) * px
    want = 2 * (train + test) + 4 * space.FIXED_BYTES["json"] + 2 * space.FIXED_BYTES["contact_sheet"]
    assert abs(est - want) <= 4  # whole bytes per frame
    assert space.frames_finished(plan) == (0, 4)


def test_a_read_only_out_is_one_line_before_any_render(tmp_path, capsys):
    from rh_dataset.cli import main as generate_main

    mnt = tmp_path / "ro"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        assert generate_main(["--protocol", "a", "--out", str(mnt / "ds"), *TINY]) == interrupt.EXIT_DISK
        [line] = capsys.readouterr().err.strip().splitlines()
        assert line.startswith(f"rh-generate: error: read-only file system: {mnt / 'ds'}")
        assert "0 of 4 frames finished and kept" in line and "resume with: rh-generate " in line
    finally:
        subprocess.run(["umount", str(mnt)])


@pytest.mark.slow
def test_sigterm_stops_the_ray_driver_and_its_tasks_and_resumes(tmp_path, reference):
    pytest.importorskip("ray")
    out = tmp_path / "ds"
    proc = _generate(out, "--backend", "ray", "--ray-frames-per-task", "1")
    _wait_for_first_frame(proc, out)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 143 and "Traceback" not in err
    [line] = _lines(err, "rh-generate: ")
    assert line.startswith("rh-generate: stopped by SIGTERM: ") and "--backend ray" in line
    assert not list(out.rglob("*.tmp"))
    assert _resume(line) == 0
    assert read_json(out / "manifest.json")["files"] == reference
