"""What produced a row: library versions and the machine, read once a process.

importlib.metadata scans the installed distributions on every call, so the answer is
cached; rows carry it as ``version_*``, ``machine`` and ``cpu_count`` columns.
"""

from __future__ import annotations

import functools
import os
from typing import Any


@functools.cache
def _environment() -> tuple[tuple[str, Any], ...]:
    return tuple(_read_environment().items())


def environment() -> dict[str, Any]:
    """Versions of the libraries used and the machine, as row columns (read once a
    process: importlib.metadata scans the installed distributions on every call)."""
    return dict(_environment())


def _read_environment() -> dict[str, Any]:
    import platform
    from importlib import metadata

    versions: dict[str, Any] = {"version_python": platform.python_version()}
    for column, distribution in [
        ("version_numpy", "numpy"),
        ("version_scipy", "scipy"),
        ("version_casadi", "casadi"),
        ("version_sksundae", "scikit-sundae"),
        ("version_workbench", "mbs-workbench"),
    ]:
        try:
            versions[column] = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            versions[column] = ""
    versions["machine"] = f"{platform.platform()} {platform.machine()}".strip()
    versions["cpu_count"] = os.cpu_count() or 0
    return versions
