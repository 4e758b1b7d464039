"""Where a report's figures are drawn: worker processes, or this one for a small report.

Drawing is most of a report's time (matplotlib, three formats a figure), and problems are
independent, so each problem's figures are one task. Workers are spawned, not forked (fork
is unsafe with the threads of rich and rerun), and cost about a second each to start.
They leave Ctrl-C to the parent (which says what was kept, once) and exit when it dies,
so an interrupted or killed report leaves no process drawing for nobody. A worker killed
from outside (SIGKILL, the OOM killer) breaks the pool: :func:`results_or_redone` draws the
problems it took with it again in this process, so the report is still whole.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from workbench.runs.parent_watch import exit_with_parent

PROBLEMS_PER_WORKER = 6  # a worker's start (spawn, imports) costs about 3 problems' drawing


def figure_jobs(n_problems: int) -> int:
    """Worker processes worth starting for ``n_problems``: one per CPU (at most 8) with
    at least PROBLEMS_PER_WORKER problems each, else none (1: draw in this process).
    Measured on the quick suite (6 problems, 2 cores, load 4): 2 workers took 24 s, 15.9 s
    CPU and 604 MiB (PSS, all processes); drawing here 16 s, 10.3 s CPU and 263 MiB."""
    jobs = min(os.cpu_count() or 1, n_problems // PROBLEMS_PER_WORKER, 8)
    return jobs if jobs >= 2 else 1


def figure_executor(jobs: int) -> Executor:
    """A spawn-based pool of ``jobs`` processes, or for ``jobs`` <= 1 an executor running
    each task at once in this process."""
    if jobs <= 1:
        return InlineExecutor()
    return FigurePool(
        jobs, mp_context=multiprocessing.get_context("spawn"), initializer=_start_worker
    )


def _start_worker() -> None:
    """In each worker: ignore Ctrl-C (the terminal sends it to the whole process group;
    the parent handles it) and exit when the parent dies."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent()


class FigurePool(ProcessPoolExecutor):
    """A process pool whose ``with`` block, left by an exception (Ctrl-C, an error),
    kills its workers at once instead of waiting for every submitted figure."""

    def __exit__(self, kind: Any, error: Any, traceback: Any) -> bool:
        if kind is None:
            return bool(super().__exit__(kind, error, traceback))
        for process in list((self._processes or {}).values()):
            with contextlib.suppress(Exception):
                process.kill()
        self.shutdown(wait=False, cancel_futures=True)
        return False


class InlineExecutor(Executor):
    """Runs each task in the calling process when its result is first asked for, so a
    progress bar stepped after each result moves while the tasks run (run at submission,
    a small report's bar stood still for its 30 s and then jumped to the end)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return _Deferred(fn, args, kwargs)


class _Deferred(Future):
    """A future whose task runs in :meth:`result`, the first time it is called."""

    def __init__(self, fn: Callable[..., Any], args: tuple, kwargs: dict) -> None:
        super().__init__()
        self._task: tuple | None = (fn, args, kwargs)

    def result(self, timeout: float | None = None) -> Any:
        if self._task is not None:
            fn, args, kwargs = self._task
            self._task = None
            try:
                self.set_result(fn(*args, **kwargs))
            except BaseException as error:  # handed to the caller by result() below
                self.set_exception(error)
        return super().result(timeout)


def submit_or_none(executor: Executor, fn: Callable[..., Any], *args: Any) -> Future | None:
    """``executor.submit(fn, *args)``, or None when its pool is broken (a worker died):
    :func:`results_or_redone` then runs the task here."""
    try:
        return executor.submit(fn, *args)
    except BrokenProcessPool:
        return None


def results_or_redone(
    tasks: Sequence[tuple[str, Future | None, tuple]],
    fn: Callable[..., Any],
    done: Callable[[str], None] = lambda name: None,
) -> list[Any]:
    """The results of ``tasks`` ((name, future, arguments of ``fn``)) in order, calling
    ``done(name)`` after each. A task whose worker died (BrokenProcessPool: every task
    still in the pool then fails so) is run again here, ``fn(*arguments)``, and one
    warning names them: a killed figure worker costs time, not the report."""
    results, redone = [], []
    for name, future, arguments in tasks:
        try:
            if future is None:
                raise BrokenProcessPool("the pool was broken before the task was submitted")
            result = future.result()
        except BrokenProcessPool:
            redone.append(name)
            result = fn(*arguments)
        results.append(result)
        done(name)
    if redone:
        shown = ", ".join(redone[:3]) + (f" and {len(redone) - 3} more" if len(redone) > 3 else "")
        warnings.warn(
            "a report worker process died (killed from outside or out of memory); the "
            f"figures of {len(redone)} problem(s) ({shown}) were drawn again in this process",
            stacklevel=2,
        )
    return results
