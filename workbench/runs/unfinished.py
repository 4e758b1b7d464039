"""The row of a run that did not finish by itself: its worker died or ran out of time.

Both pools (local and Dask) write these, so a killed or hung run is one honest row.
"""

from __future__ import annotations

import contextlib
import signal
from pathlib import Path

from workbench.runs import store
from workbench.runs.execute import RunSpec, status_row


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
    worker, it tells a row written by that attempt (a new file, renamed into place) from an
    older one (a re-run of a done row)."""
    try:
        stat = store.row_path(out, run_id).stat()
    except OSError:
        return None
    return stat.st_ino, stat.st_mtime_ns


def record_unfinished(
    out: Path, spec: RunSpec, status: str, message: str, before: tuple[int, int] | None = None
) -> str:
    """Write a row for a run that produced none (timeout, dead worker) and return its
    status; keep a row its attempt did write (the worker died after writing it), i.e. one
    whose :func:`row_stamp` differs from ``before``, the stamp taken at the attempt's start."""
    if row_stamp(out, spec.run_id) != before:
        existing = store.read_row(store.row_path(out, spec.run_id))
        if existing is not None:
            return existing.get("status", status)
    store.write_run(out, status_row(spec, status, message), None)
    return status
