"""A run: a `DatasetPlan` and a `Backend` in; the dataset folder (dataset.json first, then every frame, then
manifest.json) and the counts of rendered and skipped frames out.

The backend decides where frames render (rh_dataset.backends: local processes, Ray tasks); it is passed in, so this
package never imports a backend and a backend may import all of this one.
"""
from __future__ import annotations

import time
from typing import Protocol

from rh_common import layout
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
    counts = {"rendered": 0, "skipped": 0}
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), unit="frame", disable=not progress, dynamic_ncols=True,
               desc=f"protocol {plan.spec.protocol}")

    def on_frame(task: FrameTask, skipped: bool) -> None:
        counts["skipped" if skipped else "rendered"] += 1
        where = f"{layout.subject_name(task.subject)}/{task.split}/{layout.frame_stem(task.index)}"
        bar.set_postfix_str(where, refresh=False)
        bar.update(1)

    t0 = time.perf_counter()
    backend.run(plan, on_frame)
    bar.close()
    layout.write_manifest(plan.out)
    counts["seconds"] = time.perf_counter() - t0
    return counts
