"""Writing files safely: one implementation for every layer (foundation: imports only
workbench.errors).

A reader never sees half a file: :func:`atomic_write` sends the content to a temporary
file beside the target, which is then renamed over it (:func:`os.replace` is atomic within
a file system). Temporary files are named ``.<name>.<pid>-<8 hex digits>.tmp``
(:data:`TEMPORARY_NAME`), so a writer killed mid-write leaves a hidden ``.tmp`` file that
the results store removes on resume (:func:`remove_temporaries`, which removes nothing
else).

Nothing written, replaced or deleted inside an output folder goes through a symbolic link
(docs/architecture.md, "Trust model"): a results folder is data that may come from someone
else, and a link planted in it (``OUT/logs/.x.raw -> ~/.bashrc``, ``OUT/runs ->
/elsewhere``) must not make the workbench write outside it. Callers name the folder
(``root``); every path below it is checked with ``lstat`` (:func:`check_no_links`), files
are opened with ``O_NOFOLLOW`` (:func:`open_no_follow`), and :func:`refuse_links` finds a
link anywhere under a folder before a command writes into it. A link refused is a
:class:`LinkRefusedError` (one line, exit 2 at the command line).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from workbench.errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

TEMPORARY_NAME = re.compile(r"^\..+\.\d+-[0-9a-f]{8}\.tmp$")  # what atomic_write creates


class LinkRefusedError(ConfigError):
    """A symbolic link where the workbench writes, replaces or deletes a file."""


def _refused(link: Path, root: Path) -> LinkRefusedError:
    try:
        target = os.readlink(link)
    except OSError:
        target = "?"
    return LinkRefusedError(
        f"{link} is a symbolic link (to {target}) inside {root}: the workbench never "
        "writes, replaces or deletes through a link in an output folder; remove the link "
        "(it may have come with a results folder from someone else) or choose another "
        "output folder"
    )


def check_no_links(path: str | os.PathLike[str], root: str | os.PathLike[str]) -> None:
    """LinkRefusedError if ``path`` or a folder between ``root`` and it is a symbolic link
    (``root`` itself may be one: the user chose it). ``path`` need not exist yet."""
    fast = _relative_parts(os.fspath(path), os.fspath(root))
    if fast is not None:  # a plain path below root (most calls: a run's files)
        current = os.fspath(root)
        for part in fast:
            current = os.path.join(current, part)
            try:
                if stat.S_ISLNK(os.lstat(current).st_mode):
                    raise _refused(Path(current), Path(root))
            except FileNotFoundError:
                return
        return
    root, path = Path(root), Path(path)
    try:
        parts = path.relative_to(root).parts
    except ValueError:
        raise LinkRefusedError(f"{path} is not inside the output folder {root}") from None
    current = root
    for part in parts:
        if part == "..":
            raise LinkRefusedError(f"{path} leaves the output folder {root} ('..')")
        current = current / part
        try:
            if stat.S_ISLNK(os.lstat(current).st_mode):
                raise _refused(current, root)
        except FileNotFoundError:
            return  # the rest does not exist yet: nothing there to follow


def _relative_parts(path: str, root: str) -> list[str] | None:
    """The names between ``root`` and ``path`` when ``path`` is ``root/a/b...`` spelt
    plainly (no empty, ``.`` or ``..`` name, no trailing separator), else None: then
    :func:`check_no_links` takes pathlib's way (the same answer, 3x the time a run's file)."""
    if not root or not path.startswith(root) or path[len(root) : len(root) + 1] != os.sep:
        return None
    if root.endswith(os.sep) or (os.altsep and os.altsep in path):
        return None
    parts = path[len(root) + 1 :].split(os.sep)
    if any(part in ("", ".", "..") for part in parts):
        return None
    return parts


def check_folder_target(path: str | os.PathLike[str]) -> None:
    """ConfigError when ``path``, a folder to write into, or the nearest existing folder
    above it is a file: said before any work, not as an OS error after it."""
    target = Path(path)
    for existing in (target, *target.parents):
        if existing.is_dir():
            return
        if existing.exists() or existing.is_symlink():
            raise ConfigError(
                f"cannot write into {target}: {existing} is a file, not a folder; "
                "name a folder (it is created if missing) or move the file away"
            )


def check_writable(folder: str | os.PathLike[str]) -> None:
    """ConfigError when no file can be made in ``folder`` (read-only, immutable, not
    ours): said before the work whose results would go there, not after it."""
    try:
        descriptor, name = tempfile.mkstemp(prefix=".writable-", dir=folder)
    except OSError as error:
        raise ConfigError(
            f"cannot write into {folder}: {error.strerror or error}; make it writable or "
            "work on a copy"
        ) from None
    os.close(descriptor)
    os.unlink(name)


def make_dirs(directory: str | os.PathLike[str], root: str | os.PathLike[str]) -> None:
    """Create ``directory`` and the folders between ``root`` and it, none a link."""
    Path(root).mkdir(parents=True, exist_ok=True)
    check_no_links(directory, root)
    Path(directory).mkdir(parents=True, exist_ok=True)
    check_no_links(directory, root)  # (a folder made meanwhile by another process)


def refuse_links(root: str | os.PathLike[str]) -> None:
    """LinkRefusedError naming the first symbolic link anywhere under ``root`` (not
    followed; ``root`` itself may be one). A command calls it before writing into a folder
    that may have come from someone else: the workbench itself never makes links."""
    root = Path(root)
    if not root.is_dir():
        return
    pending = [root]
    while pending:
        with os.scandir(pending.pop()) as entries:
            for entry in entries:
                if entry.is_symlink():
                    raise _refused(Path(entry.path), root)
                if entry.is_dir(follow_symlinks=False):
                    pending.append(Path(entry.path))


def open_no_follow(
    path: str | os.PathLike[str], flags: int, root: str | os.PathLike[str], mode: int = 0o644
) -> int:
    """``os.open(path, flags | O_NOFOLLOW)`` after :func:`check_no_links` (a link planted as
    ``path`` itself is refused by the kernel: ELOOP, reported as LinkRefusedError)."""
    check_no_links(path, root)
    try:
        return os.open(path, flags | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
    except OSError as error:
        if os.path.islink(path):
            raise _refused(Path(path), Path(root)) from None
        raise error


class RenamedFile:
    """One open file that a process reuses for a series of runs, renamed to each run's name
    (:meth:`open`) and emptied, rather than a file made and deleted a run.

    Why: on ext4 without a journal, a new file skips every inode deleted in the last
    60-360 s (``recently_deleted`` in the kernel's inode allocator), so a sweep deleting
    files at a high rate made each file it created cost 0.1-0.6 ms of kernel time
    (docs/performance.md). A rename makes and frees no inode. Used for a run's raw output
    and its progress file, which the pool reads under the run's name if it kills the run.
    """

    def __init__(self) -> None:
        self.fd: int | None = None
        self.path: Path | None = None

    def open(self, path: str | os.PathLike[str], flags: int, root: str | os.PathLike[str]) -> int:
        """The file's descriptor, now named ``path`` (below ``root``, no link followed) and
        empty: the kept file renamed if there is one in the same folder, else a new one
        (``open_no_follow(path, flags)``)."""
        path = Path(path)
        try:
            check_no_links(path, root)
            if self.fd is not None and self.path is not None and self.path.parent == path.parent:
                with contextlib.suppress(OSError):  # (removed or replaced: a new file)
                    os.rename(self.path, path)
                    if os.lstat(path).st_ino == os.fstat(self.fd).st_ino:  # still ours
                        os.ftruncate(self.fd, 0)
                        self.path = path
                        return self.fd
            self.close()
            self.fd = open_no_follow(path, flags | os.O_CREAT | os.O_TRUNC, root)
            self.path = path
            return self.fd
        except BaseException:
            self.close()  # nothing written to a file of another name
            raise

    def close(self) -> None:
        """Forget the file (left where it is)."""
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
        self.fd = self.path = None

    def remove(self) -> None:
        """Delete the file (if it is still the one this process holds) and forget it."""
        if self.fd is not None and self.path is not None:
            with contextlib.suppress(OSError):
                if os.lstat(self.path).st_ino == os.fstat(self.fd).st_ino:
                    os.unlink(self.path)
        self.close()


def remove_file(path: str | os.PathLike[str], root: str | os.PathLike[str]) -> bool:
    """Delete the regular file ``path`` below ``root``; a link (or anything else that is
    not a regular file) is refused. False if there was nothing to delete."""
    check_no_links(path, root)
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            raise LinkRefusedError(f"{path} is not a regular file: not deleted")
        os.unlink(path)
    except FileNotFoundError:
        return False
    return True


def remove_temporaries(root: str | os.PathLike[str]) -> list[Path]:
    """Delete the temporary files :func:`atomic_write` left under ``root`` (writers killed
    mid-write): regular files named as it names them (:data:`TEMPORARY_NAME`), found
    without entering a linked folder. Returns them."""
    root = Path(root)
    if not root.is_dir():
        return []
    removed, pending = [], [root]
    while pending:
        with os.scandir(pending.pop()) as entries:
            for entry in entries:
                if entry.is_dir(follow_symlinks=False):
                    pending.append(Path(entry.path))
                elif entry.is_file(follow_symlinks=False) and TEMPORARY_NAME.match(entry.name):
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(entry.path)
                    removed.append(Path(entry.path))
    return removed


def atomic_write(
    path: str | os.PathLike[str],
    write: Callable[[str], Any],
    durable: bool = True,
    *,
    root: str | os.PathLike[str] | None = None,
) -> None:
    """Call ``write(temp_name)`` to create a temporary file, then rename it over ``path``.

    ``write`` creates the file itself (so it gets the usual permissions, and a compiler
    or a library can write it like any output file). ``durable``: fsync the file before
    the rename, so that after a crash of the machine (not only of the process: a rename
    alone covers that) the file is whole if present. ``root``: the output folder ``path``
    is in; no folder between it and ``path``, nor ``path``, may be a symbolic link
    (:func:`check_no_links`, checked before the write and again before the rename). On
    any error the temporary file is removed and the error raised (an OSError naming no
    file, as a full disk's, is raised again naming ``path``); ``path`` is then untouched.
    """
    path = Path(path)
    if root is None:
        path.parent.mkdir(parents=True, exist_ok=True)
    else:  # its folders are made when the write finds them missing (make_dirs: 0.03 ms)
        check_no_links(path, root)
    temp_name = str(path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp"))
    try:
        try:
            write(temp_name)
        except FileNotFoundError:
            if root is None or path.parent.is_dir():
                raise
            make_dirs(path.parent, root)
            check_no_links(path, root)
            write(temp_name)
        if durable:
            with open(temp_name, "rb+") as written:
                os.fsync(written.fileno())
        if root is not None:
            check_no_links(path, root)
        os.replace(temp_name, path)
    except BaseException as error:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp_name)
        _raise_naming(error, path)


def _raise_naming(error: BaseException, path: Path) -> None:
    """Raise ``error`` again; an OSError naming no file (a write's ENOSPC) as one naming
    ``path``, the file that could not be written."""
    if isinstance(error, OSError) and error.filename is None and error.errno:
        raise OSError(error.errno, error.strerror, str(path)) from error
    raise error


def write_new_file(
    path: str | os.PathLike[str], data: bytes, root: str | os.PathLike[str]
) -> None:
    """``data`` as the file ``path`` below the output folder ``root``, written in place: a
    new file (an existing one at ``path``, or a link there, is removed first, never written
    through), no folder between ``root`` and it a link (checked before and after the write).
    Not atomic: a process killed mid-write leaves a part of the file, so only for files
    whose readers tell a whole one from a part (a run's row: JSON that does not parse; its
    series: Parquet without its footer; :func:`workbench.execution.row_check`). It costs a
    tiny run's two files 0.05 ms against 0.2-0.8 ms for a temporary file renamed into place
    (docs/performance.md). On an error the part written is removed and the error raised
    (naming ``path``, as :func:`atomic_write` does)."""
    path = Path(path)
    check_no_links(path, root)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_BINARY", 0)
    try:
        descriptor = os.open(path, flags, 0o644)
    except FileExistsError:  # a run done again: a new file, not the old one's inode
        os.unlink(path)
        descriptor = os.open(path, flags, 0o644)
    except FileNotFoundError:
        make_dirs(path.parent, root)
        descriptor = os.open(path, flags, 0o644)
    try:
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(descriptor, view) :]
        finally:
            os.close(descriptor)
        check_no_links(path, root)  # a folder on the way made a link meanwhile
    except BaseException as error:
        with contextlib.suppress(OSError):
            os.unlink(path)
        _raise_naming(error, path)


def sync_file_system(path: str | os.PathLike[str]) -> None:
    """Write to disk what the file system holding ``path`` has in memory (Linux
    ``syncfs``; elsewhere ``sync``, all file systems): one sync for many files written
    without one each (a sweep's rows and series)."""
    import ctypes

    descriptor = os.open(path, os.O_RDONLY)
    try:
        syncfs = getattr(ctypes.CDLL(None, use_errno=True), "syncfs", None)
        if syncfs is None or syncfs(descriptor) != 0:
            os.sync()
    finally:
        os.close(descriptor)


def user_cache_dir() -> Path:
    """The workbench's cache directory: ``$WORKBENCH_CACHE`` or ~/.cache/mbs-workbench
    (compiled libraries, the verdicts of plugin import probes)."""
    configured = os.environ.get("WORKBENCH_CACHE")
    return Path(configured) if configured else Path.home() / ".cache" / "mbs-workbench"


def usable_cache_dir() -> Path:
    """:func:`user_cache_dir`; ConfigError when it is not a folder and cannot be made one
    (a file in its place or above it: WORKBENCH_CACHE names something else). Checked before
    runs start: every run of a sweep failed with it, one by one."""
    directory = user_cache_dir()
    blocking = next(
        (p for p in (directory, *directory.parents) if p.exists() and not p.is_dir()), None
    )
    if blocking is not None:
        raise ConfigError(
            f"the cache {directory} cannot be a folder: {blocking} is not one "
            "(set WORKBENCH_CACHE to a folder, or unset it for ~/.cache/mbs-workbench)"
        )
    return directory


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


# ---- whole files of JSON, Parquet or text (the results store, references) --------------


def write_json_atomic(
    data: dict[str, Any],
    path: Path,
    durable: bool = True,
    root: Path | None = None,
    indent: int | None = 1,
    renamed: bool = True,
) -> None:
    """``data`` as one whole JSON file (NumPy scalars as numbers, inf and NaN kept);
    ``root``: the output folder ``path`` is in (no link followed below it); ``indent``:
    None writes one line, by Python's C encoder (an indented file takes its pure-Python
    one: a run's row 0.09 ms against 0.02); ``renamed`` False (with ``root``, not
    ``durable``): written in place by :func:`write_new_file`, for a reader that tells a
    part from the whole."""
    text = _json_text(data, indent)
    if not renamed and root is not None:
        write_new_file(path, text.encode("utf-8"), root)
        return
    write = lambda name: Path(name).write_text(text, encoding="utf-8")  # noqa: E731
    atomic_write(path, write, durable, root=root)


def write_parquet_atomic(
    frame: pd.DataFrame | dict[str, Any],
    path: Path,
    root: Path | None = None,
    durable: bool = True,
    lean: bool = False,
    renamed: bool = True,
) -> None:
    """``frame`` (a pandas DataFrame, index dropped) as one whole Parquet file: the bytes
    of ``frame.to_parquet(index=False)``, made by pyarrow in memory and written by Python
    (pandas' call opened the file through pyarrow's file system layer: 0.2-0.4 ms more,
    a third of a tiny run's series write; docs/performance.md). ``frame`` may also be the
    columns of one (name -> NumPy values, or a text for every row): the file of
    ``pd.DataFrame(frame)`` without making it (:func:`_columns_table`).

    ``lean``: no column statistics (min/max a column, for readers that filter: a run's
    series is read whole) and a dictionary for the columns of text only (one of a float
    column's distinct values is all of them): a tiny run's series file 14.0 -> 12.1 KB,
    its encoding 0.15 -> 0.11 ms; read back the same. ``renamed``: as
    :func:`write_json_atomic`'s (a Parquet file without its footer is not read)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if isinstance(frame, dict):
        table = _columns_table(frame)
    else:
        table = _arrow_table(frame)
    if getattr(frame, "attrs", None):  # as pandas keeps them
        metadata = {**table.schema.metadata, b"PANDAS_ATTRS": json.dumps(frame.attrs)}
        table = table.replace_schema_metadata(metadata)
    options: dict[str, Any] = {}
    if lean:
        text = [
            f.name
            for f in table.schema
            if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)
        ]
        options = {"write_statistics": False, "use_dictionary": text}
    encoded = pa.BufferOutputStream()
    pq.write_table(table, encoded, compression="snappy", **options)
    data = encoded.getvalue()
    if not renamed and root is not None:
        write_new_file(path, data, root)
        return

    def write(name: str) -> None:
        with open(name, "wb") as out:
            out.write(data)

    atomic_write(path, write, durable, root=root)


_ARROW_SCHEMAS: dict[tuple[Any, ...], Any] = {}  # (columns, dtypes) -> pyarrow schema
_NUMPY_KINDS = frozenset("fiub")  # columns pyarrow takes from NumPy as they are


def _arrow_table(frame: pd.DataFrame) -> Any:
    """``pa.Table.from_pandas(frame, preserve_index=False)``, the same table: its schema
    (with pandas' metadata) made once per column layout of numbers and strings (other
    columns' types are inferred from their values), NumPy columns handed over directly:
    pandas' conversion of a whole frame was a third of a tiny run's series write
    (docs/performance.md)."""
    import pandas as pd
    import pyarrow as pa

    dtypes = tuple(frame.dtypes)
    if frame.columns.has_duplicates or not all(
        dtype.kind in _NUMPY_KINDS or isinstance(dtype, pd.StringDtype) for dtype in dtypes
    ):  # (an object column's type is inferred from its values: not from no rows)
        return pa.Table.from_pandas(frame, preserve_index=False)
    key = (tuple(frame.columns), dtypes)
    schema = _ARROW_SCHEMAS.get(key)
    if schema is None:
        schema = pa.Table.from_pandas(frame.iloc[:0], preserve_index=False).schema
        if len(_ARROW_SCHEMAS) < 256:  # a sweep has a few layouts (a model's state names)
            _ARROW_SCHEMAS[key] = schema
    arrays = []
    for (_, column), field in zip(frame.items(), schema, strict=True):
        values = column.to_numpy() if column.dtype.kind in _NUMPY_KINDS else column
        arrays.append(pa.array(values, type=field.type, from_pandas=True))  # NaN -> null
    return pa.Table.from_arrays(arrays, schema=schema)


def _columns_table(columns: dict[str, Any]) -> Any:
    """``_arrow_table(pd.DataFrame(columns))``, the same table, without the frame: each
    NumPy column handed to pyarrow as it is, a text (a run's id) repeated by pyarrow, the
    schema the frame's (made once per layout from a frame of no rows). Columns of any other
    kind take the frame. A tiny run's frame made and taken apart again cost more than its
    Parquet encoding (docs/performance.md)."""
    import numpy as np
    import pandas as pd
    import pyarrow as pa

    n = next((len(v) for v in columns.values() if isinstance(v, np.ndarray)), None)
    kinds = tuple(
        (name, value.dtype.str if isinstance(value, np.ndarray) else "text")
        for name, value in columns.items()
    )
    if n is None or not all(
        (isinstance(v, np.ndarray) and v.ndim == 1 and len(v) == n and v.dtype.kind in _NUMPY_KINDS)
        or isinstance(v, str)
        for v in columns.values()
    ):
        return _arrow_table(pd.DataFrame(columns))
    schema = _ARROW_SCHEMAS.get(kinds)
    if schema is None:
        schema = _arrow_table(pd.DataFrame(columns).iloc[:0]).schema
        if len(_ARROW_SCHEMAS) < 256:
            _ARROW_SCHEMAS[kinds] = schema
    arrays = [
        pa.array(value, type=field.type, from_pandas=True)  # NaN -> null, as from a frame
        if isinstance(value, np.ndarray)
        else pa.repeat(pa.scalar(value, type=field.type), n)
        for value, field in zip(columns.values(), schema, strict=True)
    ]
    return pa.Table.from_arrays(arrays, schema=schema)


def _json_text(data: dict[str, Any], indent: int | None) -> str:
    """``json.dumps(_jsonable(data), indent=indent, allow_nan=True)``, the same text; a flat
    object of text keys (a run's row) is encoded by the C encoder directly, NumPy scalars
    by their ``item()`` as :func:`_jsonable` takes them (its pass over a row in Python was
    a third of a tiny run's row file: docs/performance.md)."""
    if (
        indent is None
        and all(type(key) is str for key in data)
        and not any(isinstance(value, dict | list | tuple) for value in data.values())
    ):
        return json.dumps(data, allow_nan=True, default=_json_item)
    return json.dumps(_jsonable(data), indent=indent, allow_nan=True)


def _json_item(value: Any) -> Any:
    """A value the JSON encoder does not know: a NumPy scalar's Python value."""
    if hasattr(value, "item") and callable(value.item):
        return value.item()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def _jsonable(value: Any) -> Any:
    """Plain JSON values (NumPy scalars to Python; inf and NaN kept, JSON5 style)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "item") and callable(value.item):
        return value.item()
    return value


def write_text_atomic(text: str, path: Path, root: Path | None = None) -> None:
    """``text`` as one whole UTF-8 file."""

    def write(name: str) -> None:
        with open(name, "w", encoding="utf-8") as out:
            out.write(text)

    atomic_write(path, write, root=root)


__all__ = [
    "TEMPORARY_NAME",
    "LinkRefusedError",
    "RenamedFile",
    "atomic_write",
    "check_no_links",
    "file_lock",
    "make_dirs",
    "open_no_follow",
    "refuse_links",
    "remove_file",
    "remove_temporaries",
    "sync_file_system",
    "user_cache_dir",
    "write_json_atomic",
    "write_parquet_atomic",
    "write_text_atomic",
]
