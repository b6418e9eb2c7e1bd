"""A run: a `DatasetPlan` and a `Backend` in; the dataset folder (dataset.json first, then every frame, then
manifest.json) and the counts of rendered and skipped frames out. The run also appends its block to
`<out>/logs/rh-generate.log` (start, settings, each subject as it completes, warnings, end or stop), which is not
part of the dataset (neither in the manifest nor in the content identity).

The backend decides where frames render (rh_dataset.backends: local processes, Ray tasks); it is passed in, so this
package never imports a backend and a backend may import all of this one.
"""
from __future__ import annotations

import sys
import time
from collections import Counter
from typing import Protocol

from rh_common import layout
from rh_common.runlog import RunLog
from rh_dataset.generate.folder import prepare_out
from rh_dataset.generate.frames import OnFrame
from rh_dataset.generate.plan import DatasetPlan, FrameTask, frame_tasks, resolve_plan
from rh_dataset.generate.subjects import subject_source
from rh_dataset.variant import select_variant

__all__ = ["Backend", "generate"]


class Backend(Protocol):
    def check(self, plan: DatasetPlan) -> None:
        """Raise GenerateError for settings this backend cannot run, before anything is read or written."""

    def run(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        """Render every missing frame of the plan (and the contact sheets); `on_frame` once per frame."""


def generate(plan: DatasetPlan, backend: Backend, *, progress: bool = True) -> dict:
    """Generate (or resume) a dataset; returns counts. Writes dataset.json first and manifest.json last."""
    backend.check(plan)
    plan = resolve_plan(plan)
    subject_source(plan).check()
    select_variant(plan.variant)
    prepare_out(plan)
    tasks = frame_tasks(plan.spec)
    with RunLog(plan.out / layout.LOG_DIR / "rh-generate.log") as log:
        _log_start(log, plan, backend, len(tasks))
        try:
            counts = _run(plan, backend, tasks, log, progress)
        except BaseException as exc:  # Ctrl-C, SIGTERM (as KeyboardInterrupt), disk full, a failed frame
            log.line(f"stopped: {type(exc).__name__}: {exc}".rstrip(": "))
            raise
        log.line(f"done: {counts['rendered']} frames rendered, {counts['skipped']} already complete, "
                 f"{counts['seconds']:.1f} s; manifest written")
    return counts


def _log_start(log: RunLog, plan: DatasetPlan, backend: Backend, n_frames: int) -> None:
    spec, st = plan.spec, plan.settings
    log.line(f"start: {' '.join(sys.argv)}")
    splits = ", ".join(f"{s.name} {s.frames}" for s in spec.splits)
    log.line(f"plan: protocol {spec.protocol}, {spec.subjects} subjects, frames per split: {splits} "
             f"({n_frames} in all), {spec.width}x{spec.height}, seed {plan.seed}, out {plan.out}")
    log.line(f"render: {st}; backend {type(backend).__name__}")


def _run(plan: DatasetPlan, backend: Backend, tasks: list[FrameTask], log: RunLog, progress: bool) -> dict:
    counts = {"rendered": 0, "skipped": 0}
    per_subject = Counter(t.subject for t in tasks)
    seen: Counter = Counter()
    rendered: Counter = Counter()
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), unit="frame", disable=not progress, dynamic_ncols=True,
               desc=f"protocol {plan.spec.protocol}")
    t0 = time.perf_counter()

    def on_frame(task: FrameTask, skipped: bool) -> None:
        counts["skipped" if skipped else "rendered"] += 1
        seen[task.subject] += 1
        rendered[task.subject] += not skipped
        if seen[task.subject] == per_subject[task.subject]:
            done = sum(seen[s] == n for s, n in per_subject.items())
            log.line(f"{layout.subject_name(task.subject)}: {seen[task.subject]} frames ({rendered[task.subject]} "
                     f"rendered, {seen[task.subject] - rendered[task.subject]} already complete); {done} of "
                     f"{len(per_subject)} subjects done, {time.perf_counter() - t0:.0f} s")
        where = f"{layout.subject_name(task.subject)}/{task.split}/{layout.frame_stem(task.index)}"
        bar.set_postfix_str(where, refresh=False)
        bar.update(1)

    backend.run(plan, on_frame)
    bar.close()
    layout.write_manifest(plan.out)
    counts["seconds"] = time.perf_counter() - t0
    return counts
