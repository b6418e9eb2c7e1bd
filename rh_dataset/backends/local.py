"""`rh-generate --backend local`: a `DatasetPlan` in, its frames rendered on this machine out.

One subject at a time in this process (`workers=1`), or one process per subject, `workers` at once, frames
reporting back through a queue. Stopping the run (Ctrl-C, SIGTERM, an error) stops every worker first.
"""
from __future__ import annotations

import os
import pickle
import sys
from dataclasses import dataclass

from rh_dataset.generate import DatasetPlan, GenerateError, OnFrame, run_subject, subject_source

__all__ = ["LocalBackend"]


@dataclass(frozen=True)
class LocalBackend:
    workers: int = 1
    """Processes rendering subjects in parallel (each with cores / workers render threads, at least 2)."""

    def check(self, plan: DatasetPlan) -> None:
        if self.workers < 1:
            raise GenerateError(f"--workers must be >= 1, got {self.workers}")

    def run(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        if self.workers == 1:
            from rh_dataset.variant import set_render_threads

            set_render_threads()  # this process's threads, at least 2 (on a 1-core machine too)
            source = subject_source(plan)
            for s in range(plan.spec.subjects):
                run_subject(plan, source, s, on_frame)
        else:
            self._run_parallel(plan, on_frame)

    def _run_parallel(self, plan: DatasetPlan, on_frame: OnFrame) -> None:
        """One spawned process per subject, `workers` at a time; frames and each worker's end come back on a
        queue. On an interruption (or another worker's error) the workers still running are sent SIGTERM, which
        unwinds them like Ctrl-C (rh_common.interrupt.worker_signals: no temporary file is left), then killed if
        they have not ended within `_STOP_GRACE_S`."""
        import multiprocessing as mp
        import queue as queue_mod

        ctx = mp.get_context("spawn")  # drjit's JIT state must not be forked
        q = ctx.Queue()
        waiting = list(range(plan.spec.subjects))
        running: dict[int, object] = {}
        try:
            while waiting or running:
                while waiting and len(running) < self.workers:
                    s = waiting.pop(0)
                    running[s] = ctx.Process(target=_worker, args=(plan, self.workers, s, q), daemon=True)
                    running[s].start()
                try:
                    kind, *rest = q.get(timeout=0.2)
                except queue_mod.Empty:
                    for s, proc in list(running.items()):
                        if not proc.is_alive() and proc.exitcode != 0:
                            raise GenerateError(f"worker of subject {s} died (exit code {proc.exitcode}); rerun to "
                                                "resume")
                    continue
                if kind == "frame":
                    on_frame(*rest)
                elif kind == "done":
                    running.pop(rest[0]).join()
                else:  # "error": a worker's exception, raised here as if the subject had run in this process
                    raise rest[1]
        finally:
            _stop(running.values())
            q.close()


_STOP_GRACE_S = 30.0


def _stop(procs) -> None:
    import time

    procs = [p for p in procs if p.is_alive()]
    for p in procs:
        p.terminate()  # SIGTERM: the worker unwinds through its atomic writes' clean-up
    deadline = time.monotonic() + _STOP_GRACE_S
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join()


def _worker(plan: DatasetPlan, workers: int, s: int, queue) -> None:
    from rh_common.interrupt import Stopped, worker_signals

    worker_signals()
    try:
        from rh_dataset.variant import set_render_threads

        set_render_threads((os.cpu_count() or 1) // workers)  # at least 2: one thread gives hair other bits
        run_subject(plan, subject_source(plan), s, lambda task, skipped: queue.put(("frame", task, skipped)))
    except Stopped as stop:
        # Stopped by the parent or by the terminal's Ctrl-C: its files are clean and the parent says so.
        sys.exit(128 + stop.signum)
    except BaseException as exc:  # noqa: BLE001 (handed to the parent, which raises it)
        try:
            pickle.dumps(exc)  # the queue pickles in a thread of its own, where a failure would be lost
        except Exception:
            exc = GenerateError(f"subject {s}: {type(exc).__name__}: {exc}")
        queue.put(("error", s, exc))
        # Handed over: the worker now only flushes its queue while the parent, raising the error, terminates it.
        # A stop from here on ends it quietly (the default action) instead of raising through multiprocessing's
        # exit hooks, which printed a traceback beside the parent's one-line error.
        import signal

        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_DFL)
        return
    queue.put(("done", s))
