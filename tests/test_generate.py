"""The generator end to end on tiny settings: layout, metadata, determinism, resume after kill -9, bad input."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rh_common import sh
from rh_common.imageio import read_exr, read_json, read_png, write_exr
from rh_dataset.cli import main as generate_main
from rh_dataset.verify import verify

# --drape coarse: subject 0 of seed 0 wears a draped dress; the coarse drape is seconds, the full one a minute or more.
TINY = ["--subjects", "1", "--frames", "2", "--resolution", "32", "--spp", "4", "--aov-spp", "2", "--max-depth", "3",
        "--drape", "coarse", "--no-progress"]


def run(out: Path, *extra: str, protocol: str = "a") -> int:
    return generate_main(["--protocol", protocol, "--out", str(out), *TINY, *extra])


@pytest.fixture(scope="module")
def dataset_a(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("a") / "ds"
    assert run(out) == 0
    return out


def manifest(root: Path) -> dict:
    return read_json(root / "manifest.json")["files"]


def test_layout_and_metadata_follow_the_architecture_doc(dataset_a):
    root = dataset_a
    assert read_json(root / "dataset.json")["format"] == "rh-dataset/1"
    assert (root / "subject_000" / "character.json").is_file()
    train = root / "subject_000" / "protocol_a" / "train"
    test = root / "subject_000" / "protocol_a" / "test"
    assert sorted(p.name for p in train.glob("frame_000000*")) == [
        "frame_000000.json", "frame_000000_image.exr", "frame_000000_image.png", "frame_000000_mask.png"]
    assert {p.name for p in test.glob("frame_000001*")} == {
        f"frame_000001{s}" for s in (".json", "_image.exr", "_image.png", "_mask.png", "_albedo.exr", "_albedo.png",
                                     "_normal.exr", "_normal.png", "_depth.exr")}
    assert (train / "contact_sheet.png").is_file() and (test / "contact_sheet.png").is_file()
    meta = read_json(test / "frame_000001.json")
    for key in ("camera", "body", "light", "exposure", "render", "versions", "files"):
        assert key in meta
    K = np.array(meta["camera"]["K"])
    assert K.shape == (3, 3) and K[0, 2] == 16 and K[1, 2] == 16
    # sh_camera is sh_world seen from the camera (OpenGL axes).
    w2c = np.array(meta["camera"]["world_to_camera"])
    R = np.diag([1.0, -1.0, -1.0]) @ w2c[:3, :3]
    np.testing.assert_allclose(meta["light"]["sh_camera"], sh.rotate(np.array(meta["light"]["sh_world"]), R),
                               atol=1e-9)
    assert meta["body"]["model"] == "anny" and meta["body"]["phenotype"]
    assert verify(root).problems == []


def test_ground_truth_layers_are_consistent(dataset_a):
    test = dataset_a / "subject_000" / "protocol_a" / "test"
    for i in range(2):
        s = f"frame_{i:06d}"
        mask = read_png(test / f"{s}_mask.png") / 255.0
        n = read_exr(test / f"{s}_normal.exr")
        img = read_exr(test / f"{s}_image.exr")
        inside = mask > 0.5
        assert inside.sum() > 20, "the person must be in the frame"
        np.testing.assert_allclose(np.linalg.norm(n[inside], axis=-1), 1.0, atol=1e-4)
        assert np.all(np.isfinite(img)) and img.min() >= 0


def test_turntable_train_frames_have_the_a_pose_and_one_light(dataset_a):
    train = dataset_a / "subject_000" / "protocol_a" / "train"
    m0, m1 = (read_json(train / f"frame_{i:06d}.json") for i in range(2))
    assert m0["light"] == m1["light"] and m0["exposure"] == m1["exposure"]
    assert m0["body"]["pose"]["bones"] == {} and m1["body"]["turntable_deg"] == pytest.approx(180.0)


def test_same_seed_is_bit_identical_and_a_rerun_renders_nothing(dataset_a, tmp_path, capsys):
    other = tmp_path / "again"
    assert run(other) == 0
    assert manifest(other) == manifest(dataset_a)
    capsys.readouterr()
    assert run(other) == 0
    assert "0 frames rendered, 4 already complete" in capsys.readouterr().out


def test_each_run_appends_its_log_beside_the_dataset_outside_the_manifest(dataset_a, tmp_path):
    """logs/rh-generate.log: start, the plan, each subject as it completes, the end; a rerun appends its own block.
    The log is a record of runs, not data: the manifest (and so the identity) does not list it."""
    out = tmp_path / "logged"
    assert run(out) == 0 and run(out) == 0
    lines = (out / "logs" / "rh-generate.log").read_text().splitlines()
    words = [ln.split(" ", 2)[1] for ln in lines]  # after the UTC stamp
    assert words == ["start:", "plan:", "render:", "subject_000:", "done:"] * 2
    assert "4 frames (4 rendered, 0 already complete)" in lines[3]
    assert "4 frames (0 rendered, 4 already complete)" in lines[8]
    assert manifest(out) == manifest(dataset_a)
    assert not any(k.startswith("logs/") for k in manifest(out))


def test_a_run_killed_mid_way_resumes_to_the_same_files(dataset_a, tmp_path):
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "rh_dataset.cli", "--protocol", "a", "--out", str(out), *TINY]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 300
    first = out / "subject_000" / "protocol_a" / "train" / "frame_000000.json"
    while not first.exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert run(out) == 0
    assert manifest(out) == manifest(dataset_a)
    assert not list(out.rglob("*.tmp"))


def test_protocol_b_tests_the_training_poses_under_other_lights(tmp_path):
    out = tmp_path / "b"
    assert run(out, protocol="b") == 0
    split = out / "subject_000" / "protocol_b"
    for i in range(2):
        tr = read_json(split / "train" / f"frame_{i:06d}.json")
        te = read_json(split / "test" / f"frame_{i:06d}.json")
        assert tr["body"]["pose"] == te["body"]["pose"]
        assert tr["light"]["sh_world"] != te["light"]["sh_world"]


@pytest.mark.parametrize("args, message", [
    (["--protocol", "z"], "unknown protocol"),  # a, b and c exist
    (["--resolution", "0"], "resolution"),
    (["--spp", "0"], "spp"),
    (["--subjects", "0"], "subjects"),
])
def test_bad_input_gives_one_line_error_and_writes_nothing(tmp_path, capsys, args, message):
    out = tmp_path / "bad"
    with pytest.raises(SystemExit) if args[0] == "--resolution" else _no_raise():
        rc = generate_main(["--out", str(out), *TINY, *args])
        assert rc == 2
    err = capsys.readouterr().err
    # One line names the problem (argparse puts its usage line above it).
    assert message in err.strip().splitlines()[-1]
    assert not out.exists()


def test_an_unreadable_hdri_is_named_and_nothing_is_written(tmp_path, capsys):
    folder = tmp_path / "maps"
    folder.mkdir()
    (folder / "broken.exr").write_bytes(b"not an exr")
    out = tmp_path / "ds"
    assert generate_main(["--out", str(out), "--hdri-folder", str(folder), *TINY]) == 2
    err = capsys.readouterr().err
    assert "broken.exr" in err
    assert not out.exists()


def test_a_folder_holding_another_dataset_is_refused(dataset_a, tmp_path, capsys):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(dataset_a, out)
    assert run(out, "--seed", "5") == 2
    assert "other settings" in capsys.readouterr().err
    assert manifest(out) == manifest(dataset_a)
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    assert run(stranger) == 2
    assert "not an rh dataset" in capsys.readouterr().err


class _no_raise:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_parallel_workers_make_the_same_files_as_one_process(tmp_path):
    small = ["--subjects", "2", "--frames", "1", "--resolution", "16", "--spp", "2", "--aov-spp", "1",
             "--max-depth", "2", "--drape", "coarse", "--no-progress"]
    one, two = tmp_path / "one", tmp_path / "two"
    assert generate_main(["--protocol", "a", "--out", str(one), *small]) == 0
    assert generate_main(["--protocol", "a", "--out", str(two), "--workers", "2", *small]) == 0
    assert manifest(one) == manifest(two)
