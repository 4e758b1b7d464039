"""Runs that did not finish by themselves: their worker died, ran out of time, or was lost.

Two kinds, told apart because only one is a result of the run:

- **the run's own**: it ran out of its time limit (row ``timeout``) or its worker crashed
  (a crash signal such as SIGSEGV or SIGABRT, or an exit code: the plugin's or a library's
  code in that process ended it): a ``failed`` row "worker process died (...)";
- **the infrastructure's**: the worker was killed from outside (:data:`KILL_SIGNALS`:
  an operator, the OOM killer, a lost node) or the Dask worker or scheduler was lost.
  That is no result: the pools retry such a run once within the sweep and, if it fails
  so again, leave it without a row (:class:`InfrastructureError` names why), so a resumed
  sweep redoes it; the sweep's exit status says runs could not be completed.
"""

from __future__ import annotations

import contextlib
import signal
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.execution.execute import RunSpec, status_row
from workbench.execution.run_log import salvage_log
from workbench.execution.run_progress import progress_columns, progress_path, read_progress
from workbench.runs import store

# signals that end a process from outside (not a crash of the code it was running)
KILL_SIGNALS = (signal.SIGKILL, signal.SIGTERM, signal.SIGHUP, signal.SIGINT)
RETRIES = 1  # infrastructure failures retried within a sweep, per run


class InfrastructureError(WorkbenchError):
    """A run could not be completed for a reason outside it (its worker killed from
    outside or lost); not a result of the run: run it again."""


def killed_from_outside(exit_code: int | None) -> bool:
    """The worker's exit code says a kill signal (:data:`KILL_SIGNALS`) ended it."""
    return exit_code is not None and exit_code < 0 and -exit_code in set(KILL_SIGNALS)


def died_message(exit_code: int | None) -> str:
    message = f"worker process died (exit code {exit_code}"
    if exit_code is not None and exit_code < 0:
        with contextlib.suppress(ValueError):
            message += f", {signal.Signals(-exit_code).name}"
    return message + ")"


def timeout_message(limit: float) -> str:
    return f"time limit of {limit:g} s exceeded; the run's worker process was killed"


def row_stamp(out: Path, run_id: str) -> tuple[int, int] | None:
    """(inode, mtime in ns) of the run's row file, or None: taken when a run is handed to a
    worker, it tells a row written by that attempt (a new file, written after the old one
    is removed, which may free its inode for it: the time tells them apart) from an older
    one (a re-run of a done row)."""
    try:
        stat = store.row_path(out, run_id).stat()
    except OSError:
        return None
    return stat.st_ino, stat.st_mtime_ns


def written_status(out: Path, run_id: str, before: tuple[int, int] | None) -> str | None:
    """The status of the row this attempt wrote (its :func:`row_stamp` differs from
    ``before``, taken at the attempt's start: the worker died after writing it), or None."""
    if row_stamp(out, run_id) == before:
        return None
    existing = store.read_row(store.row_path(out, run_id))
    return None if existing is None else str(existing.get("status", "failed"))


def record_unfinished(
    out: Path, spec: RunSpec, status: str, message: str, before: tuple[int, int] | None = None
) -> str:
    """Write a row for a run that produced none (timeout, crashed worker) and return its
    status; keep the row its attempt did write (:func:`written_status`)."""
    written = written_status(out, spec.run_id, before)
    if written is not None:
        return written
    log = salvage_log(out, spec.run_id)  # what the killed run printed, bounded
    where, clause = progress_columns(read_progress(progress_path(out, spec.run_id)))
    message = f"{message}; {clause}" if clause else message
    store.write_run(out, status_row(spec, status, message, log=log, **where), None)
    return status
