"""Writing a file atomically: one implementation for every layer (foundation: no imports
from the workbench).

A reader never sees half a file: the content goes to a temporary file beside the target,
which is then renamed over it (:func:`os.replace` is atomic within a file system).
Temporary files are named ``.<name>.<pid>-<random>.tmp``, so a writer killed mid-write
leaves a hidden ``.tmp`` file that the results store removes on resume.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any


def atomic_write(
    path: str | os.PathLike[str], write: Callable[[str], Any], durable: bool = True
) -> None:
    """Call ``write(temp_name)`` to create a temporary file, then rename it over ``path``.

    ``write`` creates the file itself (so it gets the usual permissions, and a compiler
    or a library can write it like any output file). ``durable``: fsync the file before
    the rename, so that after a crash of the machine (not only of the process: a rename
    alone covers that) the file is whole if present. On any error the temporary file is
    removed and the error raised (an OSError naming no file, as a full disk's, is raised
    again naming ``path``); ``path`` is then untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temp_name = str(path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp"))
    try:
        write(temp_name)
        if durable:
            with open(temp_name, "rb+") as written:
                os.fsync(written.fileno())
        os.replace(temp_name, path)
    except BaseException as error:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp_name)
        if isinstance(error, OSError) and error.filename is None and error.errno:
            # a write's ENOSPC names no file: name the one that could not be written
            raise OSError(error.errno, error.strerror, str(path)) from error
        raise


def user_cache_dir() -> Path:
    """The workbench's cache directory: ``$WORKBENCH_CACHE`` or ~/.cache/mbs-workbench
    (compiled libraries, the verdicts of plugin import probes)."""
    configured = os.environ.get("WORKBENCH_CACHE")
    return Path(configured) if configured else Path.home() / ".cache" / "mbs-workbench"


@contextlib.contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """An exclusive advisory lock on ``path`` (created if missing), released by the OS if
    the holder dies, so a killed process never leaves a lock behind."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock, at worst the work is done twice
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


__all__ = ["atomic_write", "file_lock", "user_cache_dir"]
