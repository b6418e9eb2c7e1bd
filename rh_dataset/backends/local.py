"""`rh-generate --backend local`: a `DatasetPlan` in, its frames rendered on this machine out.

One subject at a time in this process (`workers=1`), or one process per subject, `workers` at once, frames
reporting back through a queue.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from rh_dataset.generate import DatasetPlan, GenerateError, OnFrame, run_subject, subject_source

__all__ = ["LocalBackend"]


@dataclass(frozen=True)
class LocalBackend:
    workers: int = 1
    """Processes rendering subjects in parallel (each with cores / workers render threads)."""

    def check(self, plan: DatasetPlan) -> None:
        if self.workers < 1:
            raise GenerateError(f"--workers must be >= 1, got {self.workers}")

    def run(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        if self.workers == 1:
            source = subject_source(plan)
            for s in range(plan.spec.subjects):
                run_subject(plan, source, s, on_frame)
        else:
            self._run_parallel(plan, on_frame)

    def _run_parallel(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        import multiprocessing as mp
        import queue as queue_mod
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

        def drain(q) -> None:
            while True:
                try:
                    on_frame(*q.get_nowait())
                except queue_mod.Empty:
                    return

        ctx = mp.get_context("spawn")  # drjit's JIT state must not be forked
        with ctx.Manager() as manager:
            q = manager.Queue()
            with ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx) as pool:
                pending = {pool.submit(_worker, plan, self.workers, s, q) for s in range(plan.spec.subjects)}
                while pending:
                    done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                    for f in done:
                        f.result()  # re-raise a worker's error here
                    drain(q)
                drain(q)


def _worker(plan: DatasetPlan, workers: int, s: int, queue) -> None:
    import drjit as dr

    dr.set_thread_count(max(1, (os.cpu_count() or 1) // workers))
    run_subject(plan, subject_source(plan), s, lambda task, skipped: queue.put((task, skipped)))
