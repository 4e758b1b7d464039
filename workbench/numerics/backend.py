"""One code path for NumPy and CasADi: pick the array namespace from the arguments.

Functions written with :func:`ops` and :func:`matrix`/:func:`vector` work on NumPy arrays
(returning NumPy arrays) and on CasADi SX/MX symbols (returning CasADi expressions).
"""

from __future__ import annotations

import warnings
from typing import Any

import casadi as ca
import numpy as np

# CasADi 3.8 warns (an 18-line FutureWarning, casadi issue #2959) when a NumPy function is
# called on a CasADi value; it announces a future change of the result type that our
# formulas do not meet (NumPy values go to NumPy, symbols through ops() to CasADi), and
# its lines reached the stderr of `workbench run` and `reference`. Only that warning is
# silenced; every other warning is shown as before.
warnings.filterwarnings(
    "ignore",
    message=r"\s*casadi: a numpy function was called on a casadi value",
    category=FutureWarning,
)

SYMBOLIC_TYPES = (ca.SX, ca.MX)


def is_symbolic(*values: Any) -> bool:
    """True if any value is a CasADi SX or MX expression."""
    return any(isinstance(v, SYMBOLIC_TYPES) for v in values)


def symbolic_type(*values: Any) -> type:
    """ca.MX if any value is MX, else ca.SX."""
    return ca.MX if any(isinstance(v, ca.MX) for v in values) else ca.SX


def ops(*values: Any) -> Any:
    """The module (``casadi`` or ``numpy``) whose sin, cos, sqrt, arctan2 ... fit ``values``."""
    return _CasadiOps if is_symbolic(*values) else np


class _CasadiOps:
    """The few NumPy names our formulas use, mapped to CasADi."""

    sin = staticmethod(ca.sin)
    cos = staticmethod(ca.cos)
    tan = staticmethod(ca.tan)
    sqrt = staticmethod(ca.sqrt)
    arctan2 = staticmethod(ca.atan2)
    arcsin = staticmethod(ca.asin)
    arccos = staticmethod(ca.acos)
    abs = staticmethod(ca.fabs)
    dot = staticmethod(ca.dot)
    cross = staticmethod(ca.cross)
    where = staticmethod(ca.if_else)  # where(condition, if_true, if_false)


def vector(items: list[Any]) -> Any:
    """A column of scalars: (n,) NumPy array or n x 1 CasADi expression."""
    if is_symbolic(*items):
        return ca.vertcat(*items)
    return np.array([float(i) if np.ndim(i) == 0 else np.asarray(i).item() for i in items])


def matrix(rows: list[list[Any]]) -> Any:
    """A matrix from nested rows: NumPy array or CasADi expression."""
    if any(is_symbolic(*row) for row in rows):
        return ca.vertcat(*[ca.horzcat(*row) for row in rows])
    return np.array(rows, dtype=float)


def entries(v: Any, n: int) -> list[Any]:
    """The first n scalar entries of a vector (NumPy or CasADi)."""
    return [v[i] for i in range(n)]


def transpose(a: Any) -> Any:
    return a.T


def matmul(a: Any, b: Any) -> Any:
    return ca.mtimes(a, b) if is_symbolic(a, b) else np.asarray(a) @ np.asarray(b)
