"""The integrator contract (SciPy's OdeSolver idea: the contract written down, cost counted once).

An integrator plugin subclasses :class:`Integrator`, registers with
``@workbench.plugin.registry.integrator`` and:

1. sets ``name``, ``summary`` and ``Options`` (frozen dataclass with defaults);
2. sets ``accepts``: {form name: highest dae index accepted} — e.g. {"ode": 0},
   {"dae": 2} or {"mechanical": 3}; the runner pairs it only with equations offering one;
3. optionally overrides :meth:`Integrator.incompatibility` to refuse equations it cannot
   handle for a finer reason (e.g. a non-constant mass matrix), returning the reason;
4. implements :meth:`Integrator.integrate` (task, trajectory) filling
   ``trajectory.y``, ``trajectory.times`` for the output times reached and the counts it
   alone knows (steps, rejected steps, factorizations, Newton iterations).

:meth:`Integrator.solve` wraps it: it times the stages (setup, integrate), counts every
evaluation of the equations' right-hand sides and Jacobians (``FastFunction.n_calls``),
turns any exception, NaN or early stop into a failed :class:`Trajectory` carrying the
time reached and the reason, and never raises for a numerical failure.
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from workbench.equations import Equations
from workbench.errors import ConfigError, PluginError
from workbench.plugin.options import NoOptions, parse_options


@dataclass
class SolverStats:
    """Cost of one integration. -1 means "not known for this method"."""

    n_rhs: int = 0
    n_jac: int = 0
    n_steps: int = 0
    n_rejected: int = 0
    n_lu: int = -1
    n_newton: int = -1
    setup_s: float = 0.0
    integrate_s: float = 0.0
    cpu_s: float = 0.0


@dataclass
class Trajectory:
    """States at the requested output times that were reached.

    ``y`` is (n_times_reached, n) in the layout of ``form`` ([q, v, (lambda), (mu)]).
    """

    form: str
    times: np.ndarray
    y: np.ndarray
    success: bool = True
    message: str = ""
    t_reached: float = math.nan
    stats: SolverStats = field(default_factory=SolverStats)


@dataclass
class IntegrationTask:
    """What an integrator is asked to do; ``form`` is the form object it consumes."""

    equations: Equations
    form_name: str
    form: Any
    y0: np.ndarray
    yp0: np.ndarray
    times: np.ndarray
    rtol: float
    atol: float
    options: Any


class Integrator:
    """Base class of integrator plugins (see the module docstring)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    Options: ClassVar[type] = NoOptions
    accepts: ClassVar[dict[str, int]] = {}

    @classmethod
    def parse_options(cls, options: Any = None) -> Any:
        return parse_options(cls.Options, options, f"integrator {cls.name!r}")

    @classmethod
    def select_form(cls, forms: dict[str, int]) -> str | None:
        """The first accepted form that ``forms`` ({name: index}) offers at an accepted index."""
        for form, max_index in cls.accepts.items():
            if form in forms and forms[form] <= max_index:
                return form
        return None

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        """A reason these equations cannot be integrated by this method, or None."""
        return None

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        raise NotImplementedError

    def solve(
        self,
        equations: Equations,
        y0: np.ndarray,
        yp0: np.ndarray | None,
        times: np.ndarray,
        rtol: float,
        atol: float,
        options: Any = None,
        form: str | None = None,
    ) -> Trajectory:
        """Integrate from (times[0], y0) and return the states at ``times``.

        Bad arguments raise ConfigError/PluginError; numerical failures return a failed
        Trajectory (``success=False``) with ``t_reached`` and the reason in ``message``.
        """
        options = self.parse_options(options)
        offered = {
            name: getattr(obj, "index", 0) for name, obj in equations.forms.items()
        }
        form = form or self.select_form(offered)
        if form is None or form not in equations.forms:
            raise PluginError(
                f"integrator {self.name!r} accepts {self.accepts} but formalism "
                f"{equations.formalism!r} offers {offered}"
            )
        reason = self.incompatibility(equations, options)
        if reason:
            raise PluginError(f"integrator {self.name!r}: {reason}")
        times = np.asarray(times, dtype=float)
        if times.ndim != 1 or times.size < 2 or np.any(np.diff(times) <= 0):
            raise ConfigError("output times must be an increasing sequence of at least 2 values")
        if not (rtol > 0 and atol > 0):
            raise ConfigError(f"tolerances must be positive (rtol={rtol}, atol={atol})")
        form_object = equations.forms[form]
        y0 = np.asarray(y0, dtype=float)
        yp0 = np.zeros_like(y0) if yp0 is None else np.asarray(yp0, dtype=float)
        task = IntegrationTask(equations, form, form_object, y0, yp0, times, rtol, atol, options)
        trajectory = Trajectory(form, times[:1], y0[None, :].copy(), t_reached=times[0])
        counted = _counted_functions(equations)
        before = {key: f.n_calls for key, f in counted.items()}
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            self.integrate(task, trajectory)
        except Exception as error:  # noqa: BLE001 - a failed method is a result, not a crash
            trajectory.success = False
            last = traceback.format_exception_only(type(error), error)[-1].strip()
            trajectory.message = trajectory.message or last  # "Type: message"
        trajectory.stats.integrate_s = time.perf_counter() - wall - trajectory.stats.setup_s
        trajectory.stats.cpu_s = time.process_time() - cpu
        calls = {key: f.n_calls - before[key] for key, f in counted.items()}
        trajectory.stats.n_rhs = max(trajectory.stats.n_rhs, calls["rhs"])
        trajectory.stats.n_jac = max(trajectory.stats.n_jac, calls["jac"])
        _check_result(trajectory, times)
        return trajectory


def _counted_functions(equations: Equations) -> dict[str, Any]:
    """The FastFunctions whose calls count as right-hand-side and Jacobian evaluations."""
    rhs, jac = [], []
    if "ode" in equations.forms:
        rhs.append(equations.forms["ode"].rhs)
        jac.append(equations.forms["ode"].jacobian)
    if "dae" in equations.forms:
        rhs.append(equations.forms["dae"].residual)
        jac.append(equations.forms["dae"].jacobian)
    if "mechanical" in equations.forms:
        mech = equations.forms["mechanical"]
        rhs.append(mech.dynamics)
        rhs.append(mech.forces)
    return {"rhs": _Sum(rhs), "jac": _Sum(jac)}


class _Sum:
    def __init__(self, functions: list[Any]) -> None:
        self.functions = functions

    @property
    def n_calls(self) -> int:
        return sum(f.n_calls for f in self.functions)


def _check_result(trajectory: Trajectory, times: np.ndarray) -> None:
    """Mark NaN/inf states and early stops as failures, keeping what was reached."""
    y = np.atleast_2d(trajectory.y)
    finite = np.all(np.isfinite(y), axis=1)
    if not finite.all():
        first_bad = int(np.argmin(finite))
        trajectory.y = y[:first_bad]
        trajectory.times = trajectory.times[:first_bad]
        trajectory.success = False
        trajectory.message = trajectory.message or "the solution became NaN or infinite"
    if len(trajectory.times):
        trajectory.t_reached = float(trajectory.times[-1])
    if trajectory.success and (len(trajectory.times) < len(times)):
        trajectory.success = False
        trajectory.message = trajectory.message or (
            f"stopped at t = {trajectory.t_reached:g} before the end time {times[-1]:g}"
        )
