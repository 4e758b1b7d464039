"""Where a running run is: its stage and the time it has reached, for a killed run's row.

A run killed at its time limit writes no row itself; the pool writes a ``timeout`` row for
it. So that this row says where the time went (reference, build, initial state or
integration, and how far the integration got), a worker keeps a small progress file beside
the run's raw log, rewritten in place by a daemon thread every
:data:`WRITE_EVERY` seconds: ``{"stage", "t_reached", "t_end", "wall_s"}``. The pool reads it
when it kills the worker (:func:`read_progress`).

The time reached is read, without touching the hot loop, from the input buffer of the
first argument (the time) of the equations' compiled functions
(:class:`~workbench.equations.evaluate.FastFunction`): the latest time at which the
integrator evaluated them. An integrator that evaluates elsewhere (CasADi's own) leaves it
unknown (NaN); the stage is still known.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from pathlib import Path
from typing import Any

from workbench.execution.periodic import Periodic
from workbench.files import LinkRefusedError, RenamedFile

WRITE_EVERY = 0.25  # s between two writes of the progress file


class RunProgress:
    """The stage of the run in this process and the time buffers it watches."""

    def __init__(self) -> None:
        self.stage = ""
        self.started = time.perf_counter()
        self.t_end = math.nan
        self._time_buffers: list[Any] = []

    def begin_run(self) -> None:
        self.stage, self.started, self.t_end = "pairing", time.perf_counter(), math.nan
        self._time_buffers = []

    def enter(self, stage: str) -> None:
        self.stage = stage

    def watch_times(self, equations: Any, form: str, t_end: float) -> None:
        """Watch the time inputs of the compiled functions of ``equations``' form ``form``."""
        from workbench.equations.evaluate import FastFunction

        self.t_end = float(t_end)
        found = equations.forms.get(form)
        members = vars(found).values() if found is not None and hasattr(found, "__dict__") else []
        self._time_buffers = [
            f._inputs[0]
            for f in members
            if isinstance(f, FastFunction) and f._inputs and f._inputs[0].size == 1
        ]
        for buffer in self._time_buffers:  # equations built for an earlier run keep its
            buffer[0] = math.nan  # last time there; every call sets it before evaluating

    def t_reached(self) -> float:
        """The latest time the equations were evaluated at in this run (NaN before the
        first evaluation, or where the integrator evaluates them elsewhere)."""
        values = [float(buffer[0]) for buffer in self._time_buffers]
        return max((v for v in values if math.isfinite(v)), default=math.nan)

    def snapshot(self) -> dict[str, Any]:
        return {
            "stage": self.stage,
            "t_reached": self.t_reached() if self.stage == "integrate" else math.nan,
            "t_end": self.t_end,
            "wall_s": time.perf_counter() - self.started,
        }


PROGRESS = RunProgress()  # the run of this process (a worker runs one at a time)


# the thread of a process that writes PROGRESS every WRITE_EVERY s to the file it follows
_WRITER = Periodic(
    "run-progress", lambda writer: writer.write(PROGRESS.snapshot()), lambda _: WRITE_EVERY
)
_FILE = RenamedFile()  # this process's progress file, reused run after run


class ProgressWriter:
    """Has this process's progress thread write :data:`PROGRESS` to ``path`` (below
    ``<out>/logs``, no link followed) until :meth:`stop`; nothing is written to it afterwards.

    The file is not deleted at the stop: the process keeps it open, and the next run's
    writer renames it to its own path and rewrites it in place (no file made and deleted
    a run: :class:`workbench.files.RenamedFile`); :func:`release_progress_file` deletes it.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._size = 0  # bytes written last: a shorter text is padded to it

    def write(self, snapshot: dict[str, Any]) -> None:
        """The snapshot as JSON, over the file's whole content in one write (padded with
        spaces, which JSON ignores): a reader after a kill finds the last whole one."""
        text = json.dumps(snapshot, allow_nan=True).encode()
        data, self._size = text.ljust(self._size), max(self._size, len(text))
        with contextlib.suppress(OSError, TypeError):  # (TypeError: no file open)
            os.pwrite(_FILE.fd, data, 0)

    def stop(self) -> None:
        _WRITER.follow(None)

    def __enter__(self) -> ProgressWriter:
        with contextlib.suppress(OSError, LinkRefusedError):  # (then none: not written)
            _FILE.open(self.path, os.O_RDWR, self.path.parent.parent)
        self.write(PROGRESS.snapshot())
        _WRITER.follow(self)
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def release_progress_file() -> None:
    """Delete the progress file this process kept for its next run (a worker that stops)."""
    _FILE.remove()


def progress_path(out: Path, run_id: str) -> Path:
    """Where a running run's progress is kept (beside its raw log)."""
    from workbench.execution.run_log import raw_path

    raw = raw_path(Path(out), run_id)
    return raw.with_name(raw.name.replace(".raw", ".progress"))


def read_progress(path: Path) -> dict[str, Any]:
    """The last progress written to ``path`` ({} if none), and the file removed."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    with contextlib.suppress(OSError):
        Path(path).unlink()
    return data if isinstance(data, dict) else {}


def progress_columns(progress: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """(row columns stage, t_reached, wall_s; a clause for the message) of a killed run."""
    if not progress.get("stage"):
        return {}, ""
    stage = str(progress["stage"])
    t, t_end = float(progress.get("t_reached", math.nan)), float(progress.get("t_end", math.nan))
    wall = float(progress.get("wall_s", math.nan))
    clause = f"killed in stage {stage!r} after {wall:.3g} s"
    if math.isfinite(t):
        clause += f", at t = {t:.6g} s" + (f" of {t_end:g} s" if math.isfinite(t_end) else "")
    return {"stage": stage, "t_reached": t, "wall_s": wall}, clause
