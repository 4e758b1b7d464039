"""A worker's recordings written a batch of runs a file, and the runs a killed worker left
unwritten (issue 35.4).

A file a run cost the worker and the merge 0.75-1.5 ms a run (the file, Rerun's flush
of its stream, the reader opening it: docs/performance.md), so a worker of the local pool
records several finished runs into one file (:class:`RecordingBatch`): it writes the file
after :data:`BATCH_RUNS` runs or :data:`BATCH_SECONDS`, when the recorder says the next
run cannot join it (``recorder.fits(spec)``), and when it stops. A file is written to a
temporary name and renamed, so the merge never reads half a batch.

Nothing lost: before a run's row is written, its id is appended to the worker's journal
(``recordings/<token>.pending``; a run that fills its batch has the batch's file written
instead), which is emptied once the batch holding the run is on disk and deleted when
the worker stops. So a run with a row whose recording was never
written (its worker killed: a time limit, a crash, from outside) is listed in a journal
left behind. The pool records such runs again (the run alone, its row kept:
:func:`workbench.runs.local_pool.run_local`'s ``rebuild``), and a resumed sweep does so
for the journals of a sweep killed as a whole (:func:`unwritten_runs`).
"""

from __future__ import annotations

import contextlib
import os
import time
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from workbench.files import make_dirs, remove_file

RECORDINGS_DIR = "recordings"
JOURNAL_SUFFIX = "pending"
BATCH_RUNS = 64
"""Runs a worker records into one file at most."""
BATCH_SECONDS = 1.0
"""A batch's file is written at the end of the first run that ends this long (wall s)
after the batch began: a worker killed loses at most about this much work to redo."""


def new_token() -> str:
    """A worker's journal name: unique across the workers of all sweeps of a folder."""
    return uuid.uuid4().hex


def journal_path(out: Path, token: str) -> Path:
    return out / RECORDINGS_DIR / f"{token}.{JOURNAL_SUFFIX}"


class RecordingBatch:
    """The recording of a worker's runs, a file a batch (see the module docstring).

    ``recorder``: a class as :func:`workbench.runs.sweep.run_sweep` takes it (made once,
    at the first run); ``out``: the sweep's folder; ``token``: the worker's journal name;
    ``most``: runs a file at most (a Dask worker's child: 1, its file goes with the row).
    A recording is a view of the results, never a failure: a recorder that raises leaves
    the runs unrecorded, as before batches."""

    def __init__(self, recorder: Any, out: Path, token: str, most: int = BATCH_RUNS) -> None:
        self.recorder, self.out, self.token, self.most = recorder, out, token, most
        self.sink: Any = None
        self.runs = 0  # runs logged to the file begun (0: none begun)
        self.started = 0.0  # when it began (time.monotonic)
        self._journal: int | None = None  # its file descriptor, opened at the first run

    def begin_run(self, spec: Any) -> Any:
        """The sink to log ``spec``'s run to (None: not recorded); the file begun is
        written first if the run cannot join it."""
        try:
            if self.sink is None:
                self.sink = self.recorder()
            if self.runs and not self.sink.fits(spec):
                self.write()
            if not self.runs:
                directory = self.out / RECORDINGS_DIR
                make_dirs(directory, self.out)  # no link below out (workbench.files)
                name = f"{time.time_ns()}-{self.token}.{self.recorder.suffix}"
                self.sink.begin_file(directory / name)
                self.started = time.monotonic()
            return self.sink
        except Exception:  # noqa: BLE001
            return None

    def logged(self, run_id: str) -> None:
        """Note the run as recorded: called before its row is written. Its id goes to the
        journal, or, the run filling the batch, the batch's file is written now (a Dask
        worker's child, a run a file, then never returns a row without its recording)."""
        if self.sink is None:
            return
        self.runs += 1
        if self.runs >= self.most:  # full: its file on disk before the row, no journal
            self.write()
            return
        try:
            if self._journal is None:
                path = journal_path(self.out, self.token)
                flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW
                self._journal = os.open(path, flags, 0o644)
            os.write(self._journal, f"{run_id}\n".encode())
        except OSError:  # no journal: the run's file is written now, as before batches
            self.write()

    def end_run(self) -> None:
        """After a run's row: write the batch if it is old enough (or full)."""
        if self.runs >= self.most or time.monotonic() - self.started >= BATCH_SECONDS:
            self.write()

    def write(self) -> None:
        """Write the file begun and empty the journal (kept if the file could not be
        written: the pool or a resume then records those runs again)."""
        if not self.runs:
            return
        self.runs = 0
        try:
            self.sink.end_file()
        except Exception:  # noqa: BLE001 - a view: its runs are left in a journal
            self._keep_journal()
            return
        if self._journal is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self._journal, 0)

    def close(self) -> None:
        """Write the last batch and delete the journal: the worker stops."""
        self.write()
        if self._journal is not None:
            os.close(self._journal)
            self._journal = None
            with contextlib.suppress(OSError):
                remove_file(journal_path(self.out, self.token), self.out)

    def _keep_journal(self) -> None:
        if self._journal is None:
            return
        os.close(self._journal)
        self._journal = None
        path = journal_path(self.out, self.token)
        with contextlib.suppress(OSError):
            os.rename(path, path.with_name(f"{self.token}-{new_token()}.{JOURNAL_SUFFIX}"))


def journals(out: Path, token: str = "") -> list[Path]:
    """The journals in ``out`` (of the worker ``token`` only, if given)."""
    directory = out / RECORDINGS_DIR
    if not directory.is_dir():
        return []
    return sorted(directory.glob(f"{token}*.{JOURNAL_SUFFIX}"))


JOURNAL_MAX_BYTES = 1 << 20
"""A journal lists at most a batch's run ids (about 17 bytes each): a larger file in a
results folder is no journal of ours and is not read."""


def listed_runs(paths: Iterable[Path]) -> set[str]:
    """The run ids the journals ``paths`` list (an unreadable or oversized one lists none)."""
    runs: set[str] = set()
    for path in paths:
        with contextlib.suppress(OSError, UnicodeDecodeError):
            with path.open("rb") as file:
                data = file.read(JOURNAL_MAX_BYTES + 1)
            if len(data) <= JOURNAL_MAX_BYTES:
                runs.update(data.decode().split())
    return runs


def unwritten_runs(out: Path) -> set[str]:
    """The runs whose recording a killed worker left unwritten (journals left behind)."""
    return listed_runs(journals(out))


def forget_journals(out: Path, written: set[str], scope: set[str]) -> None:
    """Delete the journals left behind whose every run is now recorded (in ``written``)
    or is no run of this sweep (not in ``scope``); the others stay for the next resume."""
    for path in journals(out):
        if not (listed_runs([path]) & scope) - written:
            with contextlib.suppress(OSError):
                remove_file(path, out)
