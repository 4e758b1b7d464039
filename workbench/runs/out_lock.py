"""One command at a time on an output folder: a lock that dies with its holder.

Two sweeps on one OUT used to both run every run (issue 31.4). A command that writes
into OUT (``workbench sweep``, ``report``, ``run --out``) holds :func:`out_lock`: a POSIX
record lock (``fcntl.lockf``) on ``OUT/.workbench.lock``. The kernel releases it when its
holder exits, however it exits (SIGKILL included), so a lock left by a killed sweep is
never stale: the next command takes it over at once and says whose it was. Forked
workers do not inherit it. The holder writes who it is into the file (pid, host, start
time, command); a second command reads that and exits 2 naming it, or waits for it with
``--wait``. The file is emptied, not deleted, on release (deleting it would let two
processes lock two different files).

Taking the lock also checks OUT for symbolic links (:func:`workbench.files.refuse_links`):
nothing the command writes afterwards goes through one.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import fcntl
import json
import os
import socket
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from workbench.errors import ConfigError
from workbench.files import check_folder_target, open_no_follow, refuse_links

LOCK_FILE = ".workbench.lock"
_HELD: dict[str, int] = {}  # OUT (real path) -> depth: this process holds it already


class OutputBusyError(ConfigError):
    """Another process holds the output folder's lock."""


def holder_text(info: dict) -> str:
    """``pid 123 on host h since 2026-11-26 15:40:12 UTC (workbench sweep ...)``."""
    if not info:
        return "another process"
    return (
        f"pid {info.get('pid', '?')} on host {info.get('host', '?')} since "
        f"{info.get('started', '?')} ({info.get('command', '?')})"
    )


def _read_holder(fd: int) -> dict:
    try:
        text = os.pread(fd, 64 * 1024, 0).decode("utf-8", "replace")
        info = json.loads(text) if text.strip() else {}
    except (OSError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}


def _me(command: str | None) -> dict:
    started = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": started,
        "command": command or " ".join(["workbench", *sys.argv[1:]]),
    }


@contextlib.contextmanager
def out_lock(
    out: str | os.PathLike[str],
    *,
    wait: bool = False,
    say: Callable[[str], None] | None = None,
    command: str | None = None,
) -> Iterator[None]:
    """Hold the lock of the output folder ``out`` (created if missing) while inside.

    OutputBusyError naming the holder if another process holds it, unless ``wait``:
    then ``say`` once that we wait, and wait (Ctrl-C stops). A holder's record left by
    a killed process is taken over, ``say``-ing so. Re-entrant within a process (a sweep
    that writes its report holds it once). LinkRefusedError if ``out`` holds a link.
    """
    out = Path(out)
    check_folder_target(out)  # a file there: one line now, not ENOTDIR / EEXIST later
    out.mkdir(parents=True, exist_ok=True)
    key = os.path.realpath(out)
    if key in _HELD:
        _HELD[key] += 1
        try:
            yield
        finally:
            _HELD[key] -= 1
        return
    tell = say or (lambda line: print(line, file=sys.stderr, flush=True))
    refuse_links(out)
    try:
        fd = open_no_follow(out / LOCK_FILE, os.O_RDWR | os.O_CREAT, out)
    except OSError as error:
        if error.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        fd = None  # a folder we may not write (a report of it goes elsewhere): no lock
    try:
        if fd is not None and _lock(fd, out, wait, tell, command):
            _HELD[key] = 1
        yield
    finally:
        if _HELD.pop(key, None) is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)  # released cleanly: no holder to report
        if fd is not None:
            os.close(fd)  # releases the lock


def _lock(fd: int, out: Path, wait: bool, tell: Callable[[str], None], command: str | None) -> bool:
    """Take the lock on ``fd`` and write who holds it (see :func:`out_lock`); False on a
    file system without locks (some network or FUSE ones), said as a warning."""
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno not in (errno.EAGAIN, errno.EACCES):  # held: those two only
            tell(f"warning: cannot lock {out} ({error.strerror}); nothing stops a second "
                 "command on it meanwhile")  # fmt: skip
            return False
        holder = holder_text(_read_holder(fd))
        if not wait:
            raise OutputBusyError(
                f"{out} is in use by {holder}; wait until it ends, or run again with "
                "--wait (in Python wait=True) to start when it does"
            ) from None
        tell(f"waiting for {out}: in use by {holder}")
        fcntl.lockf(fd, fcntl.LOCK_EX)
    left = _read_holder(fd)
    if left and left.get("pid") != os.getpid():  # the kernel freed it: its holder is gone
        tell(f"taking over the lock of {out} left by {holder_text(left)}, no longer running")
    refuse_links(out)  # (again: the folder may have changed while we waited)
    os.ftruncate(fd, 0)
    os.pwrite(fd, json.dumps(_me(command)).encode(), 0)
    return True


__all__ = ["LOCK_FILE", "OutputBusyError", "holder_text", "out_lock"]
