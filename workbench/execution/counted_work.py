"""Counted work: a run's cost as the evaluations it counted, weighted by their unit costs.

``work_s = n_rhs * rhs + n_jac * jacobian + n_lu * lu``, where ``rhs`` and ``jacobian``
are the CPU seconds of one call of the form's own functions (the ODE right-hand side or
the DAE residual, and its Jacobian) and ``lu`` that of one dense LU factorization
(:func:`scipy.linalg.lu_factor`) of a matrix of the Jacobian's size. Each unit cost is
timed in batches at the run's last state (:meth:`FastFunction.cpu_per_call
<workbench.equations.evaluate.FastFunction.cpu_per_call>`), once per built equations and
form (the worker keeps both between runs). ``work_s`` weights the counts with each unit's
least batch (the least is the least disturbed, as with :mod:`timeit`), ``work_s_max``
with its greatest: the interval of the measure (``work_s_min`` = ``work_s``).

Why: an integration's CPU time moves with the machine's load (a busy core's caches and
clock), the counts do not, and unit costs timed in short batches move little. What it
leaves out: the integrator's own work between evaluations (step-size control, a
Python loop, Newton updates), sparse or banded factorizations (counted as dense), and
evaluations of functions other than the form's right-hand side and Jacobian. So it ranks
pairs by how much they ask of the equations, not by what the integration costs on a
machine. Rows of the ``mechanical`` form (whose counts mix functions) and of integrators
that count no evaluations have it NaN.
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import numpy as np
import scipy.linalg

from workbench.equations.evaluate import cpu_per_call

COLUMNS = ("work_s", "work_s_min", "work_s_max")
_UNITS: dict[int, dict[tuple[str, int], tuple[float, float]]] = {}  # id(form) -> costs


def unit_cost(equations: Any, form: str, unit: str) -> tuple[float, float]:
    """CPU seconds of one ``unit`` ('rhs', 'jac' or 'lu': one dense LU of the Jacobian's
    size) of ``form`` (least, greatest over the batches), timed once while the form object
    lives and its function runs the same code (compile=auto moves it from the VM to C
    between runs: then it is timed again)."""
    form_object = equations.forms[form]
    key = id(form_object)
    if key not in _UNITS:
        _UNITS[key] = {}
        weakref.finalize(form_object, _UNITS.pop, key, None)
    known = _UNITS[key]
    running = (unit, id(getattr(_function(form_object, unit), "evaluated", None)))
    if running not in known:
        known[running] = _measure(form_object, unit)
    return known[running]


def _function(form: Any, unit: str) -> Any:
    """The function a unit times (None for 'lu' and an unbuilt Jacobian)."""
    if unit == "rhs":
        return form.rhs if hasattr(form, "rhs") else form.residual
    return getattr(form.jacobian, "_fast", form.jacobian) if unit == "jac" else None


def _measure(form: Any, unit: str) -> tuple[float, float]:
    rhs = form.rhs if hasattr(form, "rhs") else form.residual
    if unit == "rhs":
        return rhs.cpu_per_call()
    jacobian = getattr(form.jacobian, "fast", form.jacobian)  # (built now if lazy)
    if unit == "jac":
        return jacobian.cpu_per_call()
    if not jacobian.n_calls:  # its outputs are not a Jacobian yet
        jacobian.cpu_per_call(batches=1, batch_s=0.0)
    matrix = np.array(jacobian.outputs[0], dtype=float)
    n = matrix.shape[0]
    matrix = matrix + n * np.eye(n)  # (a singular last Jacobian still factors)
    return cpu_per_call(lambda: scipy.linalg.lu_factor(matrix), 5, 1e-3)


def counted_work(equations: Any, form: str, row: dict[str, Any]) -> dict[str, float]:
    """The row's ``work_s`` and its interval from its counts (``n_rhs``, ``n_jac``,
    ``n_lu``; a count of -1, unknown, counts as 0 beside a known ``n_rhs``); NaN when
    the form has no unit costs or the integrator counted no right-hand side."""
    nan = dict.fromkeys(COLUMNS, math.nan)
    n_rhs = row.get("n_rhs", -1)
    if form not in ("ode", "dae") or not n_rhs or n_rhs < 0:
        return nan
    counts = {"rhs": n_rhs, "jac": max(row.get("n_jac", 0), 0), "lu": max(row.get("n_lu", 0), 0)}
    units = {unit: unit_cost(equations, form, unit) for unit, count in counts.items() if count}
    least = sum(counts[k] * units[k][0] for k in units)
    greatest = sum(counts[k] * units[k][1] for k in units)
    return {"work_s": least, "work_s_min": least, "work_s_max": greatest}
