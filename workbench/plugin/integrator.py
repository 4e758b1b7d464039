"""The integrator contract (SciPy's OdeSolver idea: the contract written down, cost counted once).

An integrator plugin subclasses :class:`Integrator`, registers with
``@workbench.plugin.registry.integrator`` and:

1. sets ``name``, ``summary`` and ``Options`` (frozen dataclass with defaults);
2. sets ``accepts``: {form name: highest dae index accepted} — e.g. {"ode": 0},
   {"dae": 2} or {"mechanical": 3}; the runner pairs it only with equations offering one;
3. sets ``contacts = True`` only if it integrates the unilateral contacts of
   ``Equations.contacts`` (impacts, friction); a smooth method is never paired with a
   model that has contacts (it would silently pass through the floor);
   optionally overrides :meth:`Integrator.incompatibility` to refuse equations it cannot
   handle for a finer reason (e.g. a non-constant mass matrix), returning the reason;
4. implements :meth:`Integrator.integrate` (task, trajectory) filling
   ``trajectory.y``, ``trajectory.times`` for the output times reached and the counts it
   alone knows (steps, rejected steps, factorizations, Newton iterations).

:meth:`Integrator.solve` wraps it: it times the stages (setup, integrate), counts every
evaluation of the equations' right-hand sides and Jacobians (``FastFunction.n_calls``),
turns any exception, NaN or early stop into a failed :class:`Trajectory` carrying the
time reached and the reason, and never raises for a numerical failure. It also checks
what ``integrate`` returned: ``times`` (k,) equal to the first k requested output times
and ``y`` (k, n_states of the form); anything else fails the run with a one-line reason
naming the plugin and the shapes. ``trajectory.message`` always ends up one line.

A fixed-step method does not ignore the tolerance: without a ``step`` option set by the
user, it takes its step from rtol by :func:`step_for_tolerance` (the one documented rule,
anchored at 1 ms for rtol 1e-6 and scaled by the method's order), and records the step it
used in ``trajectory.stats.fixed_step`` (s; NaN for an adaptive method), which the result
row carries as ``fixed_step_s``.
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from workbench.equations import Equations
from workbench.errors import ConfigError, PluginError, one_line, one_line_text
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
    fixed_step: float = math.nan  # s; the step of a fixed-step method, NaN if adaptive


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
    warnings: list[str] = field(default_factory=list)  # for the row's ``warnings``
    # what a contact integrator measured between output times (workbench.execution.contact_metrics):
    # "event_times" (impacts, stick/slip switches; s), "penetration_max" (m),
    # "complementarity_max" (the worst residual of its contact problems)
    contact: dict[str, Any] = field(default_factory=dict)


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


REFERENCE_STEP = 1e-3  # s: the fixed step at REFERENCE_RTOL
REFERENCE_RTOL = 1e-6


def step_for_tolerance(rtol: float, order: int) -> float:
    """The step (s) of a fixed-step method of global order ``order`` at tolerance ``rtol``:

        h = 1e-3 s * (rtol / 1e-6) ** (1 / order)

    A global error C h^p follows rtol proportionally (10x smaller rtol, 10x smaller error)
    when h scales as rtol^(1/p); the constant is anchored at 1 ms for rtol 1e-6, the step
    these methods used before they read rtol, which suits mechanisms whose fastest motion
    has periods of a tenth of a second and more. For a faster mechanism, or to study
    convergence in the step itself, set the method's ``step`` option (then rtol is unused,
    and the row's ``fixed_step_s`` says which step ran).
    """
    if not (order >= 1 and 0 < rtol < 1):
        raise ConfigError(
            f"step_for_tolerance needs order >= 1 and 0 < rtol < 1, got {order}, {rtol}"
        )
    return REFERENCE_STEP * (rtol / REFERENCE_RTOL) ** (1.0 / order)


MAX_STEPS = 1e9
"""The most steps a run's options may force over the problem's time span."""


def tolerance_problem(name: str, value: Any) -> str | None:
    """Why ``value`` is not a valid tolerance ``name`` ("rtol": 0 < rtol < 1; "atol": > 0,
    both finite numbers), or None. The one check of ``workbench run`` and sweep specs."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"must be a number, not {type(value).__name__}"
    try:
        number = float(value)
    except OverflowError:
        return "must be a finite number"
    if not math.isfinite(number) or number <= 0:
        return f"must be a finite number > 0, not {number!r}"
    if name == "rtol" and number >= 1:
        return f"a relative tolerance must be < 1, not {number!r}"
    return None


def check_tolerances(rtol: Any, atol: Any) -> None:
    """ConfigError naming the tolerance unless 0 < rtol < 1 and atol > 0, both finite."""
    for name, value in (("rtol", rtol), ("atol", atol)):
        problem = tolerance_problem(name, value)
        if problem:
            raise ConfigError(f"{name}: {problem}")


class LastEvaluation:
    """The latest evaluation of an integrator's equations (its time and value: a reference
    is enough where the value is copied or the array reused), kept so that a failure can say
    the equations had turned NaN or infinite; solvers name only their own symptom (step
    size underflow, too much work). A reference costs no check a call."""

    def __init__(self, what: str) -> None:
        self.what, self.t, self.value = what, math.nan, None

    def note(self, probe: Any = None, t: float = math.nan, t_end: float = math.nan) -> str:
        """" (the WHAT was NaN or infinite at t = ...)" for the latest evaluation; else,
        given ``probe(t')`` (the equations at the state reached), :func:`nonfinite_after`;
        else ""."""
        if self.value is not None and not np.isfinite(self.value).all():
            return f" (the {self.what} was NaN or infinite at t = {self.t:.6g})"
        return nonfinite_after(self.what, probe, t, t_end) if probe is not None else ""


def nonfinite_after(what: str, evaluate: Any, t: float, t_end: float) -> str:
    """After a failed integration: whether the equations are NaN or infinite just after the
    time ``t`` reached, which an adaptive solver reports only as its own symptom (step size
    underflow, too much work). ``evaluate(t')`` gives the equations' values at the state
    reached; they are probed at 13 times from t + 1e-12 (t_end - t) to t_end. Returns
    " (the WHAT is NaN or infinite after t = ...: at t = ... + ..., from the state
    reached)" to append to the failure's message, or "" where every probe is finite."""
    for step in (t_end - t) * np.logspace(-12, 0, 13):
        if not np.isfinite(np.asarray(evaluate(t + step), dtype=float)).all():
            return (
                f" (the {what} is NaN or infinite after t = {t:g}: at t = {t:g} + "
                f"{step:.2g}, from the state reached)"
            )
    return ""


class Integrator:
    """Base class of integrator plugins (see the module docstring)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    Options: ClassVar[type] = NoOptions
    accepts: ClassVar[dict[str, int]] = {}
    contacts: ClassVar[bool] = False

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

    @classmethod
    def min_steps(cls, options: Any, span: float) -> float:
        """The fewest steps ``options`` force over ``span`` seconds (0: not known).

        The default reads an option ``step`` (a fixed step) or ``max_step`` (a bound on the
        step; 0 or inf meaning none); a plugin with other step options overrides this.
        """
        fewest = 0.0
        for name in ("step", "max_step"):
            step = getattr(options, name, None)
            if isinstance(step, int | float) and not isinstance(step, bool) and step > 0:
                fewest = max(fewest, span / float(step))
        return fewest

    @classmethod
    def check_step_count(cls, options: Any, span: float) -> None:
        """ConfigError when ``options`` would need more than MAX_STEPS steps over ``span``,
        or give a negative or non-finite ``step`` (-1 ran as if unset; 0 is left to the
        plugin, which may read it as "from rtol")."""
        step = getattr(options, "step", None)
        if isinstance(step, int | float) and not isinstance(step, bool):
            if not (math.isfinite(step) and step >= 0):
                raise ConfigError(
                    f"integrator {cls.name!r}: option step must be a positive number of "
                    f"seconds, not {step!r}"
                )
        steps = cls.min_steps(options, span)
        if steps > MAX_STEPS:
            raise ConfigError(
                f"integrator {cls.name!r}: its step options need {steps:.3g} steps over the "
                f"problem's {span:g} s, more than {MAX_STEPS:.0e}; give a larger step"
            )

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        """A reason these equations cannot be integrated by this method, or None."""
        return None

    def contact_mismatch(self, equations: Equations) -> str | None:
        """Why this method cannot take these equations' unilateral contacts, or None."""
        if getattr(equations, "contacts", None) is not None and not self.contacts:
            return (
                f"a smooth method; model {equations.model.name!r} has unilateral contacts "
                "(impacts, friction): use an integrator for contacts (docs/nonsmooth.md; "
                "`workbench list integrators`)"
            )
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
        offered = {name: getattr(obj, "index", 0) for name, obj in equations.forms.items()}
        form = form or self.select_form(offered)
        if form is None or form not in equations.forms:
            raise PluginError(
                f"integrator {self.name!r} accepts {self.accepts} but formalism "
                f"{equations.formalism!r} offers {offered}"
            )
        reason = self.contact_mismatch(equations) or self.incompatibility(equations, options)
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
        for name, key in (("n_rhs", "rhs"), ("n_jac", "jac")):
            reported = getattr(trajectory.stats, name)
            if reported >= 0 or calls[key] > 0:  # -1 (not known) stays if none were counted
                setattr(trajectory.stats, name, max(reported, calls[key]))
        _check_shapes(self.name, trajectory, times, y0, _state_widths(equations, form, y0))
        _check_result(trajectory, times)
        trajectory.message = one_line_text(trajectory.message)
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


def _state_widths(equations: Equations, form: str, y0: np.ndarray) -> list[int]:
    """The widths a state row of ``form`` may have: [q, v], then its multipliers if any."""
    base = equations.nq + equations.nv
    widths = {y0.size, base, base + equations.n_holonomic, base + equations.n_constraints}
    n = getattr(equations.forms[form], "n", None)
    if isinstance(n, int):
        widths.add(n)
    if form != "mechanical":  # ode and dae states are exactly the form's n (or y0's size)
        widths = {y0.size} | ({n} if isinstance(n, int) else set())
    return sorted(widths)


def _check_shapes(
    name: str, trajectory: Trajectory, times: np.ndarray, y0: np.ndarray, widths: list[int]
) -> None:
    """Fail a trajectory whose times and states are not (k,) and (k, n_states) at the first k
    requested output times, keeping only the initial state (metrics need the shapes right).
    ``widths``: the accepted n_states (the form's [q, v, (lambda), (mu)] layouts)."""
    n_states = y0.size
    try:
        got_times = np.asarray(trajectory.times, dtype=float)
        got_y = np.asarray(trajectory.y, dtype=float)
    except (TypeError, ValueError) as error:
        problem = f"times and y are not float arrays ({one_line(error)})"
    else:
        k = got_times.shape[0] if got_times.ndim == 1 else -1
        if k == 0 and got_y.size == 0:  # nothing reached, not even the start
            got_y = got_y.reshape(0, n_states)
        problem = ""
        if (
            got_times.ndim == 1 and got_y.ndim == 2 and got_y.shape[1] in widths
            and got_y.shape[0] != k
        ):  # fmt: skip  (most often: trajectory.times never set, holding only t0)
            problem = (
                f"returned {k} output time(s) for {got_y.shape[0]} rows of y: set "
                f"trajectory.times to the times of y's rows (task.times[:{got_y.shape[0]}])"
            )
        elif (
            got_times.ndim != 1
            or got_y.ndim != 2
            or got_y.shape[0] != k
            or got_y.shape[1] not in widths
        ):
            rows = k if k >= 0 else "n_times"
            width = " or ".join(map(str, widths))
            problem = (
                f"returned times of shape {got_times.shape} and y of shape {got_y.shape}; "
                f"expected ({rows},) and ({rows}, {width}) (n_times x the states of its form)"
            )
        elif k > times.size:
            problem = f"returned {k} output times, more than the {times.size} requested"
        elif k and not np.allclose(got_times, times[:k], rtol=1e-12, atol=0.0):
            bad = int(np.argmax(~np.isclose(got_times, times[:k], rtol=1e-12, atol=0.0)))
            order = "not increasing" if np.any(np.diff(got_times) <= 0) else "not the requested"
            problem = (
                f"returned output times {order}: times[{bad}] = {got_times[bad]:g}, "
                f"requested {times[bad]:g}"
            )
        if not problem:
            trajectory.times, trajectory.y = got_times, got_y
            return
    trajectory.success = False
    trajectory.message = f"integrator {name!r}: {problem}" + (
        f" (its own message: {trajectory.message})" if trajectory.message else ""
    )
    trajectory.times, trajectory.y = times[:1].copy(), y0[None, :].copy()


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
