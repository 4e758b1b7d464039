"""Where a sweep's ``plugins = ["my_module"]`` is looked for: the Python path, then the
current directory, then the specification's own directory.

``python -m workbench`` puts the current directory on ``sys.path`` and the ``workbench``
console script does not (its ``sys.path[0]`` is the script's ``bin/`` directory), so without
this a module beside the user worked with one command and not the other. The directories
are appended, not prepended: an installed package of the same name keeps precedence. Worker
processes receive the parent's ``sys.path``, so they find the module too.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from pathlib import Path


def _resolved(entry: str) -> str:
    return str(Path(entry or os.getcwd()).resolve())


def make_importable(directories: Iterable[str | os.PathLike[str]]) -> list[str]:
    """Append each existing directory of ``directories`` to ``sys.path`` unless it (or an
    entry resolving to it) is there already; returns the directories appended."""
    present = {_resolved(entry) for entry in sys.path if isinstance(entry, str)}
    appended = []
    for directory in directories:
        path = _resolved(os.fspath(directory))
        if path not in present and os.path.isdir(path):
            sys.path.append(path)
            present.add(path)
            appended.append(path)
    return appended


def plugin_directories(spec_path: str | os.PathLike[str] | None = None) -> list[str]:
    """The current directory, then the directory of the specification file (if any)."""
    directories = [os.getcwd()]
    if spec_path is not None:
        directories.append(str(Path(spec_path).resolve().parent))
    return directories
