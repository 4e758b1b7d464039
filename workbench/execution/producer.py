"""What produced a result row, so a resumed sweep can tell a row made by other code.

A run's id hashes its configuration only; the code that ran it is recorded beside it:

- ``producer_problem``, ``producer_formalism``, ``producer_integrator``: for each plugin,
  the modules that define its class and its base classes (standard library aside):
  ``sha256:<16 hex>`` of their source files, for modules outside an installed
  distribution (a plugin in development, an editable install, the built-ins of a source
  checkout), and ``name==version`` of the distribution for modules installed in
  site-packages (a third-party plugin installed from a wheel);
- the key library versions, already columns of every row
  (:func:`workbench.execution.environment.environment`): :data:`LIBRARY_COLUMNS`.

:func:`stale_reason` compares a stored row with what this process would write for the
same run. Python's own version and the machine are not compared (a patch release of
Python is not other code of ours; rows name their machine). Rows written before
producers were recorded (schema < 4) have producer ``unknown``: reported on resume, not
stale (nothing says they differ). Known limit: a plugin's source hash covers the modules
of its class hierarchy, not every module they call; a change elsewhere in the workbench
shows through ``version_workbench`` only when its version changes; a source file is
read at a process's first row of that plugin, so a plugin edited while a long-lived
process (a notebook, a forkserver) holds its old module is hashed as edited.
"""

from __future__ import annotations

import functools
import hashlib
import sys
import sysconfig
from pathlib import Path
from typing import Any

from workbench.execution.environment import environment
from workbench.plugin import registry

UNKNOWN = "unknown"
PLUGIN_COLUMNS = {
    "producer_problem": "problem",
    "producer_formalism": "formalism",
    "producer_integrator": "integrator",
}
LIBRARY_COLUMNS = (
    "version_workbench",
    "version_numpy",
    "version_scipy",
    "version_casadi",
    "version_sksundae",
)
_INSTALLED = ("site-packages", "dist-packages")


def _standard_library() -> tuple[Path, ...]:
    paths = sysconfig.get_paths()
    return tuple(Path(paths[key]).resolve() for key in ("stdlib", "platstdlib"))


@functools.cache
def _distribution_of(top_level: str) -> str | None:
    from importlib import metadata

    names = metadata.packages_distributions().get(top_level, [])
    for name in names:
        try:
            return f"{name}=={metadata.version(name)}"
        except metadata.PackageNotFoundError:
            continue
    return None


@functools.cache
def plugin_producer(plugin: type) -> str:
    """``sha256:<16 hex>`` of the source of the plugin class's modules outside installed
    distributions, then ``name==version`` of each installed distribution they come from
    (space-separated); ``unknown`` if no module of it has a file (defined interactively)."""
    standard = _standard_library()
    digest, hashed, distributions = hashlib.sha256(), False, []
    for module_name in dict.fromkeys(klass.__module__ for klass in plugin.__mro__):
        module = sys.modules.get(module_name)
        file = getattr(module, "__file__", None)
        if not file:
            continue
        path = Path(file).resolve()
        if any(path.is_relative_to(root) for root in standard) and not any(
            part in _INSTALLED for part in path.parts
        ):
            continue  # the standard library (abc, typing): Python's, not the plugin's
        # only for a file in site-packages: the lookup of all distributions' files takes
        # seconds, once a process (a no-op resume's largest cost; an editable install's
        # plugins never need it)
        installed = any(part in _INSTALLED for part in path.parts) and _distribution_of(
            module_name.partition(".")[0]
        )
        if installed:
            distributions.append(installed)
            continue
        try:
            source = path.read_bytes()
        except OSError:
            continue
        digest.update(module_name.encode() + b"\0" + source + b"\0")
        hashed = True
    parts = ([f"sha256:{digest.hexdigest()[:16]}"] if hashed else []) + sorted(set(distributions))
    return " ".join(parts) or UNKNOWN


def producer_columns(problem: str, formalism: str, integrator: str) -> dict[str, str]:
    """The producer columns of a run of these plugins (``unknown`` for one not registered)."""
    names = {"problem": problem, "formalism": formalism, "integrator": integrator}
    columns = {}
    for column, kind in PLUGIN_COLUMNS.items():
        try:
            plugin = registry.REGISTRY.get(kind, names[kind])
        except Exception:  # noqa: BLE001 - not registered here: cannot say
            columns[column] = UNKNOWN
        else:
            columns[column] = plugin_producer(plugin)
    return columns


def current_producer(row: dict[str, Any]) -> dict[str, Any]:
    """What this process would record as the producer of ``row``'s run."""
    libraries = environment()
    current = producer_columns(row["problem"], row["formalism"], row["integrator"])
    return current | {column: libraries.get(column) for column in LIBRARY_COLUMNS}


def unknown_producer(row: dict[str, Any]) -> bool:
    """The row was written before producers were recorded (or by a plugin with no file)."""
    return any(row.get(column) in (None, UNKNOWN) for column in PLUGIN_COLUMNS)


def stale_reason(row: dict[str, Any], current: dict[str, Any] | None = None) -> str | None:
    """What differs between ``row``'s producer and this process's (``current``, default
    :func:`current_producer`), e.g. ``producer_formalism sha256:a1.. -> sha256:b2..``;
    None if nothing known differs (an unknown value on either side is never stale)."""
    current = current_producer(row) if current is None else current
    changes = []
    for column in (*PLUGIN_COLUMNS, *LIBRARY_COLUMNS):
        old, new = row.get(column), current.get(column)
        if old in (None, "", UNKNOWN) or new in (None, "", UNKNOWN) or old == new:
            continue
        if not isinstance(old, str):
            continue  # not a value this module wrote
        changes.append(f"{column} {old} -> {new}")
    return ", ".join(changes) or None


__all__ = [
    "LIBRARY_COLUMNS",
    "PLUGIN_COLUMNS",
    "UNKNOWN",
    "current_producer",
    "plugin_producer",
    "producer_columns",
    "stale_reason",
    "unknown_producer",
]
