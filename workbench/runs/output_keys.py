"""Keys of what an output was made from: a resume remakes an output (the results table,
the merged recording, the report) only when its inputs changed.

A key is a SHA-256 over the inputs' content: the row files' bytes (:func:`rows_key`; a
row is rewritten whenever its run is redone, and names what produced it), or the names,
sizes and modification times of files that are only ever replaced whole
(:func:`files_key`, e.g. the per-run recordings), with the source of the code that makes
the output (:func:`source_key`). It is kept in ``<output>.inputs`` beside the output,
written once the output is whole and removed before the output is remade (:func:`remake`),
so an interrupted remake is remade by the next resume.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from workbench.execution import row_schema
from workbench.files import atomic_write
from workbench.runs import store

KEY_SUFFIX = ".inputs"


def key_of(*parts: str) -> str:
    """One key of several parts (each a key or a short text)."""
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part.encode("utf-8", "surrogateescape") + b"\0")
    return digest.hexdigest()


def rows_key(out: str | os.PathLike[str]) -> str:
    """The content of the row files of ``out`` (``runs/*.json``, names and bytes) and the
    row schema this code reads."""
    digest = hashlib.sha256(f"schema {row_schema.SCHEMA_VERSION}\0".encode())
    for path in sorted((Path(out) / store.RUNS_DIR).glob("*.json")):
        with contextlib.suppress(OSError):  # gone meanwhile: left out, so the key differs
            data = path.read_bytes()
            digest.update(f"{path.name} {len(data)}\0".encode() + data)
    return digest.hexdigest()


def files_key(paths: Iterable[str | os.PathLike[str]]) -> str:
    """The names, sizes and modification times of ``paths`` (files replaced whole, never
    edited in place, so a new version has a new time)."""
    digest = hashlib.sha256()
    for path in sorted(Path(p) for p in paths):
        try:
            stat = path.stat()
        except OSError:
            continue
        digest.update(f"{path.name} {stat.st_size} {stat.st_mtime_ns}\0".encode())
    return digest.hexdigest()


def source_key(module: str) -> str:
    """The source of ``module`` (an imported module; for a package, its .py files): a
    change of the code that makes an output remakes it."""
    found = sys.modules.get(module)
    file = getattr(found, "__file__", None)
    if file is None:
        return module
    path = Path(file)
    files = sorted(path.parent.glob("*.py")) if path.name == "__init__.py" else [path]
    digest = hashlib.sha256()
    for each in files:
        with contextlib.suppress(OSError):
            digest.update(each.name.encode() + b"\0" + each.read_bytes())
    return digest.hexdigest()


def key_path(output: str | os.PathLike[str]) -> Path:
    output = Path(output)
    return output.with_name(output.name + KEY_SUFFIX)


def is_current(output: str | os.PathLike[str], key: str) -> bool:
    """True if ``output`` exists and was made from the inputs of ``key``."""
    try:
        return Path(output).exists() and key_path(output).read_text(encoding="utf-8") == key
    except (OSError, UnicodeDecodeError):
        return False


def remake(
    output: str | os.PathLike[str],
    key: str,
    make: Callable[[], Any],
    root: str | os.PathLike[str] | None = None,
) -> tuple[Any, bool]:
    """``(make(), True)``, or ``(output, False)`` if ``output`` is current for ``key``.

    ``root``: the output folder the key file is in (no link followed below it)."""
    if is_current(output, key):
        return Path(output), False
    forget(output)
    made = make()
    remember(output, key, root)
    return made, True


def forget(output: str | os.PathLike[str]) -> None:
    """Remove the key of ``output`` (before it is remade)."""
    with contextlib.suppress(FileNotFoundError):
        key_path(output).unlink()


def remember(
    output: str | os.PathLike[str], key: str, root: str | os.PathLike[str] | None = None
) -> None:
    """Store ``key`` beside ``output`` (once ``output`` is whole)."""
    write = lambda name: Path(name).write_text(key, encoding="utf-8")  # noqa: E731
    atomic_write(key_path(output), write, durable=False, root=root)


__all__ = [
    "files_key",
    "forget",
    "is_current",
    "key_of",
    "remake",
    "remember",
    "rows_key",
    "source_key",
]
