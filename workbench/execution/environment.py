"""What produced a result: library versions, the machine and its thread settings.

Two records, read here only:

- :func:`environment`, a few columns of every row (``version_*``, ``machine``,
  ``cpu_count``), read once a process (importlib.metadata scans the installed
  distributions on every call, and a worker writes many rows);
- :func:`sweep_environment`, the full environment, written once a sweep to
  ``<out>/environment.json`` by :func:`workbench.runs.sweep.run_sweep`: every installed
  distribution, Python, the platform, the CPU model and count, and the BLAS/OpenMP
  thread settings (what makes timings comparable, as asv records with its results).

:func:`distribution_versions` answers "which version of these libraries" for anyone
(e.g. a report's footer).
"""

from __future__ import annotations

import functools
import os
import platform
import sys
from collections.abc import Iterable
from typing import Any

# distributions recorded in every row: column -> distribution name
ROW_DISTRIBUTIONS = {
    "version_numpy": "numpy",
    "version_scipy": "scipy",
    "version_casadi": "casadi",
    "version_sksundae": "scikit-sundae",
    "version_workbench": "mbs-workbench",
}
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def distribution_versions(names: Iterable[str], missing: str = "not installed") -> dict[str, str]:
    """name -> installed version of each distribution in ``names`` (in that order);
    ``missing`` for one that is not installed. Not cached: reads the metadata now."""
    from importlib import metadata

    versions = {}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = missing
    return versions


@functools.cache
def _environment() -> tuple[tuple[str, Any], ...]:
    return tuple(_read_environment().items())


def environment() -> dict[str, Any]:
    """Versions of the libraries used and the machine, as row columns (read once a
    process: importlib.metadata scans the installed distributions on every call)."""
    return dict(_environment())


def _read_environment() -> dict[str, Any]:
    versions: dict[str, Any] = {"version_python": platform.python_version()}
    installed = distribution_versions(ROW_DISTRIBUTIONS.values(), missing="")
    versions.update({column: installed[name] for column, name in ROW_DISTRIBUTIONS.items()})
    versions["machine"] = f"{platform.platform()} {platform.machine()}".strip()
    versions["cpu_count"] = os.cpu_count() or 0
    return versions


# ---- the full environment, once a sweep ----------------------------------------------


def sweep_environment() -> dict[str, Any]:
    """The environment of this process as plain JSON data (see the module docstring).

    Keys: ``recorded_at`` (UTC, ISO 8601), ``python`` (version, implementation,
    executable), ``platform`` (platform, system, release, machine, node), ``cpu_model``,
    ``cpu_count``, ``threads`` (:func:`thread_settings`) and ``distributions`` (name ->
    version of every installed distribution, sorted by name).
    """
    from datetime import UTC, datetime

    return {
        "recorded_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "python": {
            "version": platform.python_version(),
            "implementation": platform.python_implementation(),
            "executable": sys.executable,
        },
        "platform": {
            "platform": platform.platform(),
            "system": platform.system(),
            "release": platform.release(),
            "machine": platform.machine(),
            "node": platform.node(),
        },
        "cpu_model": cpu_model(),
        "cpu_count": os.cpu_count() or 0,
        "threads": thread_settings(),
        "distributions": installed_distributions(),
    }


def installed_distributions() -> dict[str, str]:
    """name -> version of every installed distribution, sorted by name (case-insensitive).

    A distribution found twice on ``sys.path`` is given as the first one, the one that
    ``import`` uses."""
    from importlib import metadata

    versions: dict[str, str] = {}
    for distribution in metadata.distributions():
        name = distribution.metadata["Name"]
        if name and name not in versions:
            versions[name] = distribution.version
    return dict(sorted(versions.items(), key=lambda item: item[0].lower()))


def cpu_model(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The CPU's model name: ``model name`` of ``/proc/cpuinfo`` where the file has one
    (Linux on x86), with its family and model numbers where given (a virtual machine's
    "AMD EPYC" names several generations with different caches), else
    :func:`platform.processor` (else the machine type)."""
    fields: dict[str, str] = {}
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as lines:
            for line in lines:
                key, _, value = line.partition(":")
                if not key.strip() and fields:
                    break  # the first processor's block
                fields.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    if not fields.get("model name"):
        return platform.processor() or platform.machine()
    if "cpu family" in fields and "model" in fields:
        return f"{fields['model name']} (family {fields['cpu family']}, model {fields['model']})"
    return fields["model name"]


def thread_settings() -> dict[str, Any]:
    """How many threads BLAS and OpenMP may use.

    ``environment``: the ``OMP/OPENBLAS/MKL_NUM_THREADS`` variables (None when unset).
    With threadpoolctl installed, ``threadpools``: its ``threadpool_info()`` (each
    loaded BLAS/OpenMP library, its version and thread count); without it,
    ``numpy_config``: NumPy's build configuration (which BLAS and LAPACK)."""
    variables = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    settings: dict[str, Any] = {"environment": variables}
    try:
        import threadpoolctl
    except ImportError:
        settings["numpy_config"] = _numpy_config()
    else:
        settings["threadpools"] = _plain(threadpoolctl.threadpool_info())
    return settings


def _numpy_config() -> Any:
    import numpy as np

    try:
        return _plain(np.show_config(mode="dicts"))
    except Exception as error:  # noqa: BLE001 - older NumPy, or an odd build: say so
        return f"not available: {error}"


def _plain(value: Any) -> Any:
    """``value`` as plain JSON data (anything else as its text)."""
    import json

    return json.loads(json.dumps(value, default=str))


__all__ = [
    "cpu_model",
    "distribution_versions",
    "environment",
    "installed_distributions",
    "sweep_environment",
    "thread_settings",
]
