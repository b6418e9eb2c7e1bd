"""`rh-generate --backend ray` on a real local Ray cluster: the same files as the local backend, and a worker
killed in the middle of a task is retried without leaving a broken dataset."""
from __future__ import annotations

import pytest

import ray

from rh_common.imageio import read_json  # noqa: E402
from rh_dataset.backends.ray_backend import CRASH_HOOK_ENV  # noqa: E402
from rh_dataset.cli import main as generate_main  # noqa: E402
from rh_dataset.cli import build_parser, options_from_args  # noqa: E402
from rh_dataset.verify import verify  # noqa: E402

SMALL = ["--protocol", "a", "--subjects", "1", "--frames", "2", "--resolution", "32", "--spp", "2", "--aov-spp", "1",
         "--max-depth", "2", "--drape", "coarse", "--no-progress"]
RAY = ["--backend", "ray", "--ray-frames-per-task", "2"]


def manifest(root):
    return read_json(root / "manifest.json")["files"]


@pytest.fixture(scope="module")
def crash_file(tmp_path_factory):
    return tmp_path_factory.mktemp("hook") / "crash_armed"


@pytest.fixture(scope="module")
def cluster(crash_file):
    # The crash hook only fires while `crash_file` exists; the workers learn its path from their environment.
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {CRASH_HOOK_ENV: str(crash_file)}})
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "ds"
    assert generate_main([*SMALL, "--out", str(out)]) == 0
    return out


def test_tasks_cover_every_frame_once():
    plan, backend = options_from_args(build_parser().parse_args([*SMALL, *RAY, "--out", "x", "--frames", "5"]))
    tasks = backend.tasks(plan)
    frames = [(s, split, i) for s, split, a, b in tasks for i in range(a, b)]
    assert len(frames) == len(set(frames)) == 10
    assert [b - a for s, split, a, b in tasks] == [2, 2, 1, 2, 2, 1]


def test_ray_backend_makes_the_same_files_as_the_local_one(cluster, local_run, tmp_path, capsys):
    out = tmp_path / "ray"
    assert generate_main([*SMALL, *RAY, "--out", str(out)]) == 0
    assert "4 frames rendered, 0 already complete" in capsys.readouterr().out
    assert manifest(out) == manifest(local_run)
    assert verify(out).problems == []
    # A rerun is a no-op, as with the local backend.
    assert generate_main([*SMALL, *RAY, "--out", str(out)]) == 0
    assert "0 frames rendered, 4 already complete" in capsys.readouterr().out


def test_a_worker_killed_mid_task_is_retried_and_the_dataset_verifies(cluster, local_run, crash_file, tmp_path,
                                                                      capsys):
    out = tmp_path / "crashed"
    crash_file.write_text("armed")  # the first task to finish a frame deletes this and os._exit()s its worker
    assert generate_main([*SMALL, *RAY, "--out", str(out)]) == 0
    assert not crash_file.exists(), "the crash hook did not fire"
    printed = capsys.readouterr().out
    # The frame finished before the crash is either reported as rendered or found complete by the retry.
    assert "frames rendered" in printed and "4 frames rendered, 0 already complete" in printed \
        or "3 frames rendered, 1 already complete" in printed
    assert verify(out).problems == []
    assert manifest(out) == manifest(local_run)
    assert not list(out.rglob("*.tmp"))


def test_workers_and_ray_are_exclusive(tmp_path, capsys):
    assert generate_main([*SMALL, *RAY, "--workers", "2", "--out", str(tmp_path / "x")]) == 2
    assert "--workers applies to the local backend" in capsys.readouterr().err
