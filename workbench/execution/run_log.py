"""A run's own output (its stdout and stderr) in a bounded per-run log file.

Plugins print, and so do the C libraries under them (SUNDIALS writes
``[IDAHandleFailure ...]`` lines straight to file descriptor 2): one noisy plugin once put
125 MB on a sweep's terminal (issue 18.16). While a worker executes a run,
:class:`CapturedOutput` points the process's file descriptors 1 and 2 at a file (a file,
not a pipe: C code that writes while holding the GIL would block on a full pipe whose
reader is a Python thread). Afterwards the first and last :data:`KEEP_BYTES` bytes are
kept in ``<out>/logs/<run_id>.log``, which the row names in its ``log`` column ('' when
the run printed nothing).

A run executed in a child process (Dask, ``workbench run``) returns the kept text inside
its row (:data:`LOG_TEXT`); :func:`store_log` writes it where the row is stored.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path
from typing import Any

from workbench.execution.periodic import Periodic
from workbench.files import RenamedFile, atomic_write, make_dirs, open_no_follow

LOG_DIR = "logs"
KEEP_BYTES = 64 * 1024  # kept from the start and from the end of a run's output
RAW_LIMIT_BYTES = 8 * 1024 * 1024  # the raw file is emptied (head and tail kept) past this
LOG_TEXT = "log_text"  # a row's key carrying the kept text from a child process


def log_path(out: Path, run_id: str) -> Path:
    return Path(out) / LOG_DIR / f"{run_id}.log"


def raw_path(out: Path, run_id: str) -> Path:
    """Where a run's whole output goes while it runs (removed once the log is kept)."""
    return Path(out) / LOG_DIR / f".{run_id}.raw"


def bounded(data_file: Path, keep: int = KEEP_BYTES) -> bytes:
    """The first and last ``keep`` bytes of ``data_file`` (all of it if it is shorter),
    with a line saying how many bytes were left out between them. A symbolic link is not
    followed (OSError): a planted link must not copy another file into a log."""
    fd = os.open(data_file, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    try:
        return _bounded_fd(fd, keep)
    finally:
        os.close(fd)


def _bounded_fd(fd: int, keep: int) -> bytes:
    size = os.fstat(fd).st_size
    if size <= 2 * keep:
        return os.pread(fd, size, 0)
    head, tail = os.pread(fd, keep, 0), os.pread(fd, keep, size - keep)
    return _joined(head, size - 2 * keep, tail)


def _joined(head: bytes, omitted: int, tail: bytes) -> bytes:
    return head + f"\n[... {omitted} bytes of output left out ...]\n".encode() + tail


class CapturedOutput:
    """``with CapturedOutput(raw_file): ...`` sends fds 1 and 2 (and so Python's and C's
    stdout and stderr) to ``raw_file``; :meth:`kept` then gives the bounded bytes.

    The raw file itself stays bounded too: a thread checks it every ``interval`` seconds
    and, past ``raw_limit`` bytes, keeps its head (once) and its latest tail in memory
    and empties it (it is open for appending, so writes go on at its new end).

    ``raw_file`` is ``<out>/logs/.<run_id>.raw`` (:func:`raw_path`): it is opened without
    following a link (:func:`workbench.files.open_no_follow`, below ``<out>``), and read,
    emptied and removed through that open file, never through its name again.
    ``reuse``: the file is not removed by :meth:`kept` but kept open and renamed to the
    next run's raw file (a worker's runs: no file made and deleted a run, see
    :class:`workbench.files.RenamedFile`; :func:`release_raw_file` deletes it)."""

    def __init__(
        self,
        raw_file: Path,
        keep: int = KEEP_BYTES,
        raw_limit: int = RAW_LIMIT_BYTES,
        interval: float = 0.5,
        reuse: bool = False,
    ) -> None:
        self.raw_file = Path(raw_file)
        self.reuse = reuse
        self.keep, self.raw_limit, self.interval = keep, raw_limit, interval
        self._saved: list[int] = []
        self._head: bytes | None = None  # set at the first emptying
        self._tail = b""
        self._emptied = 0  # bytes removed from the raw file so far
        self._fd: int | None = None  # the raw file, open for reading and truncating

    def __enter__(self) -> CapturedOutput:
        _flush()
        out = self.raw_file.parent.parent
        flags = os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
        try:  # (its folder made when missing: not checked and made again every run)
            target = self._open(flags, out)
        except FileNotFoundError:
            make_dirs(self.raw_file.parent, out)
            target = self._open(flags, out)
        self._fd = os.dup(target)
        try:
            self._saved = [os.dup(1), os.dup(2)]
            os.dup2(target, 1)
            os.dup2(target, 2)
        finally:
            os.close(target)
        _TRIMMER.follow(self)
        return self

    def _open(self, flags: int, out: Path) -> int:
        """A descriptor of the raw file, opened without following a link below ``out``."""
        if self.reuse:  # the process's raw file of its last run, renamed (RenamedFile)
            return os.dup(_RAW_FILE.open(self.raw_file, flags, out))
        return open_no_follow(self.raw_file, flags, out)

    def __exit__(self, *exc: Any) -> None:
        _flush()
        _TRIMMER.follow(None)  # (waits for a check under way)
        for fd, saved in zip((1, 2), self._saved, strict=True):
            os.dup2(saved, fd)
            os.close(saved)
        self._saved = []

    def _trim(self) -> None:
        with contextlib.suppress(OSError):
            if self.raw_file.stat().st_size > self.raw_limit:
                self._empty()

    def _empty(self) -> None:
        """Keep the head (the first time) and the tail of the raw file, then empty it;
        what is written between the read and the truncation is lost (and counted)."""
        fd = self._fd
        if self._head is None:
            self._head = os.pread(fd, self.keep, 0)
        size = os.fstat(fd).st_size
        start = max(0, size - self.keep)
        self._tail = (self._tail + os.pread(fd, size - start, start))[-self.keep :]
        size = os.fstat(fd).st_size
        os.ftruncate(fd, 0)
        self._emptied += size

    def kept(self) -> bytes:
        """The bounded output, and the raw file removed."""
        fd, self._fd = self._fd, None
        if fd is None:
            return b""
        try:
            if self._head is None:
                return _bounded_fd(fd, self.keep)
            rest = os.pread(fd, os.fstat(fd).st_size, 0)
            total = self._emptied + len(rest)
            tail = (self._tail + rest)[-self.keep :]
            return _joined(self._head, total - len(self._head) - len(tail), tail)
        except OSError:
            return b""
        finally:
            os.close(fd)
            if not self.reuse:  # (kept for the next run: emptied and renamed there)
                with contextlib.suppress(OSError):
                    self.raw_file.unlink()  # (unlink removes a link, never its target)


_RAW_FILE = RenamedFile()  # this process's raw file, reused run after run (reuse=True)


def release_raw_file() -> None:
    """Delete the raw file this process kept for its next run (a worker that stops)."""
    _RAW_FILE.remove()


# the thread of a process that keeps the raw file of the capture under way bounded
_TRIMMER = Periodic(
    "run-log-trim", lambda capture: capture._trim(), lambda c: 0.5 if c is None else c.interval
)


def raw_text(out: Path, run_id: str) -> str:
    """What a killed run's raw file holds, bounded, as text ('' if there is none)."""
    try:
        return bounded(raw_path(out, run_id)).decode("utf-8", "replace")
    except OSError:
        return ""


def salvage_log(out: Path, run_id: str) -> str:
    """The log of a run whose worker was killed (timeout, crash): what its raw file
    holds, bounded; the name for the row's ``log`` column ('' if there is none)."""
    raw = raw_path(out, run_id)
    try:
        data = bounded(raw)
    except OSError:
        return ""
    name = write_log(Path(out), run_id, data)
    with contextlib.suppress(OSError):
        raw.unlink()
    return name


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__):
        with contextlib.suppress(Exception):
            stream.flush()


def write_log(out: Path, run_id: str, data: bytes) -> str:
    """Write ``data`` as the run's log under ``out``; the name for the row's ``log``
    column (relative to ``out``), '' when there is nothing to write or it cannot be."""
    if not data:
        return ""
    path = log_path(out, run_id)
    try:  # no link followed below out (workbench.files)
        atomic_write(path, lambda name: Path(name).write_bytes(data), False, root=Path(out))
    except OSError:
        return ""
    return path.relative_to(out).as_posix()


def store_log(out: Path | None, row: dict[str, Any]) -> None:
    """Write the text a child process returned in ``row`` (:data:`LOG_TEXT`) to the
    run's log under ``out`` and name it in ``row['log']``; without ``out`` the text is
    dropped and the row says so."""
    text = row.pop(LOG_TEXT, "") or ""
    if not text:
        row.setdefault("log", "")
        return
    if out is None:
        row["log"] = f"not kept ({len(text.encode())} bytes of output; give --out to keep it)"
        return
    row["log"] = write_log(Path(out), str(row.get("run_id", "run")), text.encode())
