"""Deprecated module names: kept for one release, forwarding every name to the new module."""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import Any


def moved_module(old: str, new: str) -> Callable[[str], Any]:
    """Warn that ``old`` is deprecated and return a module ``__getattr__`` that forwards
    every name to ``new`` (``from old import name`` keeps working)."""
    module = importlib.import_module(new)
    warnings.warn(f"{old} is deprecated: import from {new}", DeprecationWarning, stacklevel=3)
    return lambda name: getattr(module, name)
