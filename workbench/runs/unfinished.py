"""The row of a run that did not finish by itself: its worker died or ran out of time.

Both pools (local and Dask) write these, so a killed or hung run is one honest row.
"""

from __future__ import annotations

import contextlib
import signal
from pathlib import Path

from workbench.runs import store
from workbench.runs.execute import RunSpec, status_row
from workbench.runs.run_log import salvage_log


def died_message(exit_code: int | None) -> str:
    message = f"worker process died (exit code {exit_code}"
    if exit_code is not None and exit_code < 0:
        with contextlib.suppress(ValueError):
            message += f", {signal.Signals(-exit_code).name}"
    return message + ")"


def timeout_message(limit: float) -> str:
    return f"time limit of {limit:g} s exceeded; the run's worker process was killed"


def record_unfinished(out: Path, spec: RunSpec, status: str, message: str) -> str:
    """Write a row for a run that produced none (timeout, dead worker); keep a real one."""
    existing = store.read_row(store.row_path(out, spec.run_id))
    if existing is not None:
        return existing.get("status", status)
    log = salvage_log(out, spec.run_id)  # what the killed run printed, bounded
    store.write_run(out, status_row(spec, status, message, log=log), None)
    return status
