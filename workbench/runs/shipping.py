"""What a Dask worker without the client's file system needs, shipped with the work.

A sweep's local plugin modules (``name=FILE``, :mod:`workbench.plugin.local_modules`) and
its computed references (``OUT/references``) live in the client's folders, which another
host cannot see. So the client reads them and sends their bytes:

* :func:`pack_modules`: each local module's file (a package: its folder's files), with the
  stored references in a ``references/`` folder beside it; a worker that has not the very
  same files at the client's path (no shared file system) writes them under a folder of
  its own named by their content (:func:`unpack_modules`) and imports the module from
  there under the same name, so the runs are the same;
* :func:`pack_references`: the computed references of a problem already in
  ``OUT/references``; the worker writes them into its own reference folder
  (:func:`worker_reference_dir`, in the Dask worker's scratch folder), where the runs read
  them instead of computing them again; a reference a worker computed goes back to the
  client with the row (:func:`new_references`), which keeps it in ``OUT/references`` and
  ships it with the later runs.

A worker never reads the client's ``OUT``, shared file system or not. Workers have no
common folder to lock, so the client sends a problem's first run alone while its computed
reference is not in ``OUT/references`` (:class:`ReferenceGate`): the others follow with the
reference, which one worker computed.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections import deque
from pathlib import Path
from typing import Any

from workbench.execution.execute import RunSpec, canonical_json
from workbench.execution.references import (
    computed_reference_file,
    given_reference,
    reference_prefix,
)
from workbench.files import atomic_write
from workbench.plugin import registry
from workbench.plugin.local_modules import PluginModule

REFERENCE_FILES = "reference_files"  # a row's key carrying references a worker computed
_SUFFIXES = (".parquet", ".json")  # a computed reference's poses and description
_STORED = (".npz", ".json")  # a stored reference beside a plugin module
_SKIPPED = {"__pycache__", ".git"}
Packed = tuple[str, str, dict[str, bytes]]  # a module's file in its folder, digest, files
_RESOLVED: dict[tuple[str, str], str] = {}  # (plugin text, digest) -> the text used here


def _of_problem(name: str, problem_name: str) -> bool:
    stem, suffix = os.path.splitext(name)
    plain, _, digest = stem.rpartition("-")
    return (
        suffix in _SUFFIXES
        and plain == reference_prefix(problem_name)
        and re.fullmatch(r"[0-9a-f]{16}", digest) is not None
    )


def _files_of(module: PluginModule) -> dict[str, bytes]:
    """A local module's files by their path relative to the folder holding it."""
    file = Path(module.file)
    if file.name == "__init__.py":  # a package: its folder, all of it (not its caches)
        root = file.parent.parent
        paths = [
            p
            for p in file.parent.rglob("*")
            if p.is_file() and not _SKIPPED.intersection(p.relative_to(root).parts)
        ]
    else:
        root = file.parent
        references = file.parent / "references"
        paths = [file] + sorted(
            p for p in references.glob("*") if p.is_file() and p.suffix in _STORED
        )
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(paths)}


def pack_modules(plugins: list[str]) -> dict[str, Packed]:
    """For each local module of ``plugins`` (their text): its file relative to the shipped
    folder, the files' digest, the folder's files."""
    packed = {}
    for text in plugins:
        module = PluginModule.from_text(text)
        if module.local:
            file = Path(module.file)
            root = file.parent.parent if file.name == "__init__.py" else file.parent
            files = _files_of(module)
            packed[text] = (file.relative_to(root).as_posix(), _digest(files), files)
    return packed


def _digest(files: dict[str, bytes]) -> str:
    hashed = hashlib.sha256()
    for name in sorted(files):
        hashed.update(name.encode() + b"\0" + hashlib.sha256(files[name]).digest())
    return hashed.hexdigest()[:16]


def _write_missing(folder: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        path = folder / name
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(path, lambda temp, data=data: Path(temp).write_bytes(data), False)


def unpack_modules(plugins: list[str], packed: dict[str, Packed]) -> list[str]:
    """``plugins`` with each shipped module's file replaced by this worker's copy (written
    once, in a folder named by the files' content), unless this host has the very same
    files at the client's path (a shared file system, the client's host)."""
    unpacked = []
    for text in plugins:
        if text in packed:
            relative, digest, files = packed[text]
            if (text, digest) not in _RESOLVED:
                _RESOLVED[text, digest] = _resolve(text, relative, digest, files)
            text = _RESOLVED[text, digest]
        unpacked.append(text)
    return unpacked


def _same_files(root: Path, files: dict[str, bytes]) -> bool:
    try:
        return all((root / name).read_bytes() == data for name, data in files.items())
    except OSError:
        return False


def _resolve(text: str, relative: str, digest: str, files: dict[str, bytes]) -> str:
    module = PluginModule.from_text(text)
    file = Path(module.file)
    if _same_files(Path(*file.parts[: len(file.parts) - len(Path(relative).parts)]), files):
        return text
    folder = scratch() / f"workbench-plugins-{digest}"
    _write_missing(folder, files)
    return PluginModule(module.name, str(folder / relative), module.attribute).text()


def reference_names(reference_dir: Path, problem_name: str) -> list[str]:
    """The files of the computed references of ``problem_name`` in ``reference_dir``."""
    try:
        return sorted(n for n in os.listdir(reference_dir) if _of_problem(n, problem_name))
    except OSError:
        return []


def pack_references(reference_dir: Path, problem_name: str) -> dict[str, bytes]:
    """The computed references of ``problem_name`` in ``reference_dir`` (file name -> bytes)."""
    names = reference_names(reference_dir, problem_name)
    packed = {}
    for name in names:
        try:
            packed[name] = (reference_dir / name).read_bytes()
        except OSError:  # removed meanwhile: the worker computes it
            continue
    # a reference is whole with its description: the poses alone are not used
    return {n: d for n, d in packed.items() if _pair(n) in packed}


def _pair(name: str) -> str:
    stem, suffix = os.path.splitext(name)
    return stem + (".json" if suffix == ".parquet" else ".parquet")


def scratch() -> Path:
    """This Dask worker's own folder (removed with the worker), else the temporary folder."""
    try:
        from distributed import get_worker

        return Path(get_worker().local_directory)
    except (ImportError, ValueError):  # not in a Dask worker
        return Path(tempfile.gettempdir())


def worker_reference_dir(client_reference_dir: str) -> Path:
    """This worker's folder for the computed references of the client's ``OUT/references``."""
    digest = hashlib.sha256(client_reference_dir.encode()).hexdigest()[:16]
    folder = scratch() / f"workbench-references-{digest}"
    folder.mkdir(exist_ok=True)
    return folder


def unpack_references(folder: Path, packed: dict[str, bytes]) -> None:
    """Write the shipped references this worker does not have yet."""
    _write_missing(folder, packed)


def new_references(folder: Path, problem_name: str, shipped: dict[str, bytes]) -> dict[str, bytes]:
    """The references of ``problem_name`` in this worker's ``folder`` that were not
    shipped (computed here): the client keeps them."""
    found = pack_references(folder, problem_name)
    return {name: data for name, data in found.items() if name not in shipped}


def keep_references(reference_dir: Path, returned: dict[str, bytes]) -> None:
    """Write the references a worker returned into the client's ``OUT/references``."""
    reference_dir.mkdir(parents=True, exist_ok=True)
    _write_missing(reference_dir, returned)


def _computes_reference(spec: RunSpec, reference_dir: Path) -> bool:
    """Whether ``spec``'s runs will compute a reference: its problem has none of its own
    (analytic, stored) and ``reference_dir`` has none of these options (another option
    set's reference is another file); False if the client cannot tell (the runs say why)."""
    try:
        problem = registry.get_problem(spec.problem)(spec.problem_options)
        if given_reference(problem) is not None or getattr(problem, "no_reference", ""):
            return False
        name = computed_reference_file(problem, spec.problem, spec.problem_options,
                                       problem.sample_times())  # fmt: skip
        return not (reference_dir / name).is_file()
    except Exception:  # noqa: BLE001 - a problem that fails here fails in its runs
        return False


class ReferenceGate:
    """Holds back the runs of a problem (and its options) whose computed reference the
    client does not have, while its first run (the pilot: the loosest tolerance, the
    quickest) is out; they are let go once a row of it comes back having looked for the
    reference, which then comes with them. Without it, every worker starting a run of
    the problem computed the reference itself (seconds, with heyoka tens of seconds)."""

    def __init__(self, queue: deque, reference_dir: Path) -> None:
        """Take from ``queue`` (of (key, spec)) the runs to hold back."""
        self.queue, self.reference_dir = queue, reference_dir
        self.held: dict[tuple[str, str], deque] = {}
        self.pilots: dict[tuple[str, str], str] = {}  # group -> its pilot's run id
        groups: dict[tuple[str, str], list] = {}
        for item in queue:
            groups.setdefault(self._group(item[1]), []).append(item)
        for group, items in groups.items():
            if len(items) < 2 or not _computes_reference(items[0][1], reference_dir):
                continue
            pilot = max(items, key=lambda item: item[1].rtol)
            self.pilots[group] = pilot[1].run_id
            self.held[group] = deque(item for item in items if item is not pilot)
        held_ids = {spec.run_id for items in self.held.values() for _key, spec in items}
        kept = [item for item in queue if item[1].run_id not in held_ids]
        queue.clear()
        queue.extend(kept)

    @staticmethod
    def _group(spec: RunSpec) -> tuple[str, str]:
        return spec.problem, canonical_json(spec.problem_options)

    def returned(self, spec: RunSpec, row: dict[str, Any] | None) -> None:
        """A run ended: its ``row``, or None when it was given up (no row). The pilot lets
        its group go, unless it was skipped (a pairing that cannot run, said at once):
        then the next run takes its place."""
        group = self._group(spec)
        if self.pilots.get(group) != spec.run_id:
            return
        if row is None or row.get("status") != "skipped":
            self.queue.extend(self.held.pop(group))
            del self.pilots[group]
            return
        nxt = self.held[group].popleft()
        self.queue.appendleft(nxt)
        self.pilots[group] = nxt[1].run_id
        if not self.held[group]:
            del self.held[group], self.pilots[group]

    def take_all(self) -> list:
        """Every run held back (the scheduler is lost: they are left unfinished)."""
        items = [item for items in self.held.values() for item in items]
        self.held.clear()
        self.pilots.clear()
        return items
