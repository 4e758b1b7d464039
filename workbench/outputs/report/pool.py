"""Where a report's figures are drawn: worker processes, or this one for a small report.

Drawing is most of a report's time (matplotlib, three formats a figure), and problems are
independent, so each problem's figures are one task. Workers are spawned, not forked (fork
is unsafe with the threads of rich and rerun), and cost about a second each to start.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from typing import Any


def figure_jobs(n_problems: int) -> int:
    """Worker processes worth starting for ``n_problems``: one per CPU (at most 8) from 4
    problems on, else none (1: draw in this process)."""
    return min(os.cpu_count() or 1, n_problems, 8) if n_problems >= 4 else 1


def figure_executor(jobs: int) -> Executor:
    """A spawn-based pool of ``jobs`` processes, or for ``jobs`` <= 1 an executor running
    each task at once in this process."""
    if jobs <= 1:
        return InlineExecutor()
    return ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"))


class InlineExecutor(Executor):
    """Runs each task when it is submitted, in the calling process."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as error:  # handed to the caller by future.result()
            future.set_exception(error)
        return future
