"""CasADi's own integrators (``casadi.integrator``) on the symbolic equations.

The equations' CasADi Functions (``FastFunction.function``) are called on fresh
symbols to rebuild expressions, and ``casadi.integrator(name, plugin, dae, t0, tout,
opts)`` returns the states at every output time.

* ``casadi-cvodes``: CVODES (BDF or Adams, option ``method``) on the ``ode`` form.
* ``casadi-idas``: IDAS on the ``dae`` form of index 0 or 1, rewritten as the
  semi-explicit index-1 system CasADi requires: with the differential components
  x = y_d and z = [w, y_a],

      x' = w,    0 = F(t, y(x, y_a), y'(w, 0)),

  whose Jacobian with respect to z, [dF/dy_d' dF/dy_a], is nonsingular exactly when
  F has index <= 1 (for the mechanical index-1 form it is [I 0 0; 0 M W^T; 0 W 0]).
  The multipliers come out at every output time with the state.
* ``casadi-collocation``: Radau IIA collocation (``collocation`` plugin, order
  p = 2 ``degree`` - 1) on the ``ode`` form, one output interval at a time (the interval
  mapped to [0, 1], its start and length as parameters). Its steps per output interval are
  ``intervals_per_output``, or, when that is 0, refined until rtol is met: m steps, then
  2m, accepted when the estimate |y_2m - y_m| / (2^p - 1) is within atol + rtol |y| at
  every output (the steps reported count every march). The rootfinder's residual
  tolerance follows the tolerances (a hundredth of atol + rtol |y0|, at least 1e-10)
  instead of CasADi's fixed 1e-12. A step that fails ends the run at the start of its
  output interval, with the trajectory up to there.

A built CVODES or IDAS integrator is kept (:func:`built_integrator`, the last
BUILT_LIMIT) and called again by a solve of the same equations function, options and
output times: building it (``casadi.integrator``) cost 0.34 ms of a 1.6 ms UR5 solve.

Statistics come from ``Function.stats()``: CVODES/IDAS steps, right-hand-side
evaluations, error-test failures (rejected steps), Newton iterations and linear setups
(CasADi re-evaluates the Jacobian at each setup, so that is also ``n_jac``); the
collocation plugin reports only its steps.

Failures: the SUNDIALS plugins raise on a failed step; the last output time reached is
taken from the stats, and the integration is repeated on the output times before it to
return them (cheap, and only on failure). CasADi reads SUNDIALS' statistics only after an
output interval completes, so a failed call's are not known: the row shows -1, and the
message names the output interval where it failed (``sundials-cvode-c`` reports CVODE's
statistics and time at the failure). A failed implicit step of the fixed-step plugins may
also pass unreported (CasADi keeping the last state and returning success), so a stalled
state — unchanged over an output interval although its derivative is not zero, or a
non-finite derivative at an output — is reported as the failure.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import casadi as ca
import numpy as np

from workbench.errors import ConfigError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    Trajectory,
    nonfinite_after,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator


def _symbols_for(*functions: ca.Function) -> type:
    """SX when every function is an SXFunction (expressions stay small), else MX."""
    return ca.SX if all(f.is_a("SXFunction") for f in functions) else ca.MX


def _ode_function(task: IntegrationTask) -> ca.Function:
    """The ode form's right-hand side: compiled when the formalism's compile option asked
    for it and the compile succeeded (its derivatives for Newton iterations by finite
    differences), else CasADi's."""
    rhs = task.form.rhs
    return rhs.evaluated if hasattr(rhs, "compile") and rhs.compile() else rhs.function


def _ode_dae(task: IntegrationTask) -> tuple[dict[str, Any], int]:
    """{t, x, ode} from the ode form; the number of differential states."""
    function = _ode_function(task)
    sym = _symbols_for(function)
    t, y = sym.sym("t"), sym.sym("y", task.form.n)
    return {"t": t, "x": y, "ode": function(t, y)}, task.form.n


def _semi_explicit_dae(task: IntegrationTask) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """{t, x, z, ode, alg} from the dae form (index <= 1): x' = w, 0 = F(t, y, y')."""
    form = task.form
    function = form.residual.function
    sym = _symbols_for(function)
    differential = np.flatnonzero(~form.algebraic)
    algebraic = np.flatnonzero(form.algebraic)
    t = sym.sym("t")
    x, w, y_a = (
        sym.sym("x", differential.size),
        sym.sym("w", differential.size),
        sym.sym("y_a", algebraic.size),
    )
    y_parts: list[Any] = [None] * form.n
    yp_parts: list[Any] = [sym(0)] * form.n
    for i, j in enumerate(differential):
        y_parts[j], yp_parts[j] = x[i], w[i]
    for i, j in enumerate(algebraic):
        y_parts[j] = y_a[i]
    residual = function(t, ca.vertcat(*y_parts), ca.vertcat(*yp_parts))
    dae = {"t": t, "x": x, "z": ca.vertcat(w, y_a), "ode": w, "alg": residual}
    return dae, differential, algebraic


BUILT_LIMIT = 8  # built integrators kept, least recently used out
_built: OrderedDict[tuple, tuple[ca.Function, ca.Function]] = OrderedDict()


def built_integrator(source: ca.Function, key: tuple, build: Callable[[], ca.Function]):
    """The integrator ``build()`` makes, made once for the equations function ``source``
    (compared by identity, kept alive with the entry so its id is not reused) and ``key``
    (plugin, options, output times). Solves that differ only in their initial state, the
    rounds of a benchmark or the repeats of a timed run, share it."""
    full = (id(source), *key)
    if full in _built:
        _built.move_to_end(full)
        return _built[full][1]
    function = build()
    _built[full] = (source, function)
    while len(_built) > BUILT_LIMIT:
        _built.popitem(last=False)
    return function


def _error_line(error: Exception) -> str:
    """The informative line of a CasADi exception ('... returned "CV_TOO_MUCH_WORK" ...')."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    for line in reversed(lines):
        if "returned" in line or "failed" in line.lower():
            return line.split(": ", 1)[-1] if ".cpp:" in line else line
    return lines[-1] if lines else type(error).__name__


class CasadiBase(Integrator):
    """Builds the dae dictionary, calls casadi.integrator and fills the trajectory."""

    plugin: ClassVar[str] = ""

    def dae(self, task: IntegrationTask) -> tuple[dict[str, Any], Any]:
        """CasADi's dae dict and the state layout; by default the ode form as x' = f."""
        return _ode_dae(task)

    def source(self, task: IntegrationTask) -> ca.Function:
        """The equations function :meth:`dae` is built from (the key of a built integrator)."""
        return _ode_function(task)

    def layout(self, task: IntegrationTask) -> Any:
        """The state layout :meth:`dae` returns, without building the dae."""
        return task.form.n

    def plugin_options(self, task: IntegrationTask) -> dict[str, Any]:
        raise NotImplementedError

    def initial(self, task: IntegrationTask, layout: Any) -> dict[str, np.ndarray]:
        return {"x0": task.y0}

    def states(self, result: dict[str, Any], layout: Any, n: int) -> np.ndarray:
        """(n_times, n) states from the integrator's xf (and zf) columns."""
        return np.asarray(result["xf"]).reshape(n, -1).T

    def run(self, task: IntegrationTask, layout: Any, times: np.ndarray) -> Any:
        options = self.plugin_options(task)
        grid = list(map(float, times))

        def build() -> ca.Function:
            dae, _ = self.dae(task)
            name = self.name.replace("-", "_")
            return ca.integrator(name, self.plugin, dae, grid[0], grid, options)

        key = (self.plugin, repr(sorted(options.items())), tuple(grid))
        function = built_integrator(self.source(task), key, build)
        try:
            return function, function(**self.initial(task, layout)), None
        except RuntimeError as error:
            return function, None, error

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        layout = self.layout(task)
        n = task.y0.size
        function, result, error = self.run(task, layout, task.times)
        stats = function.stats()
        self.fill_stats(trajectory, stats)
        times = task.times
        if error is not None:
            # CasADi reads SUNDIALS' statistics after each output interval it completes:
            # those of the failed one are lost, and its time is the last completed one's
            times, n_out = times[times <= float(stats.get("tcur", times[0]))], times.size - 1
            failed_in = f"between t = {times[-1]:g} and {task.times[min(times.size, n_out)]:g}"
            trajectory.success = False
            trajectory.message = f"{self.name}: {failed_in}: {_error_line(error)}"
            self.unknown_stats(trajectory)
            result = None
            if times.size >= 2:  # repeat up to the last output time reached
                _, result, _ = self.run(task, layout, times)
        if result is None:
            trajectory.times, trajectory.y = task.times[:1], task.y0[None, :].copy()
        else:
            trajectory.times, trajectory.y = times, self.states(result, layout, n)
        if error is not None and hasattr(task.form, "rhs"):  # an ode: y' = f(t, y) to probe
            reached, rhs = trajectory.y[-1], task.form.rhs.function  # no solver cost counted
            end = float(task.times[min(trajectory.times.size, task.times.size - 1)])
            trajectory.message += nonfinite_after(
                "right-hand side", lambda t: rhs(t, reached), float(trajectory.times[-1]), end
            )

    @staticmethod
    def unknown_stats(trajectory: Trajectory) -> None:
        """A failed call's statistics, which CasADi does not keep: -1 (not known), not
        those of the output intervals before the failure (0 if it failed in the first)."""
        s = trajectory.stats
        s.n_steps = s.n_rhs = s.n_rejected = s.n_newton = s.n_lu = s.n_jac = -1

    def fill_stats(self, trajectory: Trajectory, stats: dict[str, Any]) -> None:
        s = trajectory.stats
        s.n_steps = int(stats.get("nsteps", 0))
        s.n_rhs = int(stats.get("nfevals", 0))
        s.n_rejected = int(stats.get("netfails", -1))
        s.n_newton = int(stats.get("nniters", -1))
        s.n_lu = int(stats.get("nlinsetups", -1))
        s.n_jac = max(s.n_lu, 0)


@dataclass(frozen=True)
class SundialsOptions:
    max_num_steps: int = 10_000  # steps towards each output time
    max_step: float = with_unit(0.0, "s")  # 0 = unbounded

    def __post_init__(self) -> None:
        if self.max_num_steps < 1:
            raise ConfigError(f"max_num_steps must be >= 1, not {self.max_num_steps}")
        if self.max_step < 0:
            raise ConfigError(f"max_step must be >= 0 s (0 = unbounded), not {self.max_step}")


def _sundials_options(task: IntegrationTask) -> dict[str, Any]:
    options = {
        "reltol": task.rtol,
        "abstol": task.atol,
        "max_num_steps": task.options.max_num_steps,
        "disable_internal_warnings": True,
        "show_eval_warnings": False,  # one line per failed evaluation costs more than it
    }
    if task.options.max_step:
        options["max_step_size"] = task.options.max_step
    return options


@dataclass(frozen=True)
class CvodesOptions(SundialsOptions):
    """``iteration``: how the implicit stage equations are solved, "newton" (with the
    Jacobian) or "functional" (fixed point: no Jacobian, the cheapest for non-stiff
    problems with Adams)."""

    method: Literal["bdf", "adams"] = "bdf"
    iteration: Literal["newton", "functional"] = "newton"


@integrator
class CasadiCvodes(CasadiBase):
    name = "casadi-cvodes"
    summary = "CasADi CVODES (BDF or Adams) on the symbolic ode form"
    Options = CvodesOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}
    plugin = "cvodes"

    def plugin_options(self, task: IntegrationTask) -> dict[str, Any]:
        method, iteration = task.options.method, task.options.iteration
        return {
            **_sundials_options(task),
            "linear_multistep_method": method,
            "nonlinear_solver_iteration": iteration,
        }


ALGEBRAIC_FRACTION = 0.1  # of rtol x magnitude: the algebraic groups' absolute tolerance


def algebraic_abstol(task: IntegrationTask) -> list[float]:
    """IDAS's absolute tolerance per component of [x; w; y_a] (:func:`_semi_explicit_dae`).

    IDAS tests the local error, and Newton's convergence, on the algebraic variables as
    well: the derivatives w (accelerations of 1e4 rad/s^2 on Andrews' squeezer) and the
    multipliers y_a (from 1e-15 to 99 there). With the positions' atol on them, rtol 1e-10
    asked the multipliers that are about 0 for 1e-13 absolute, below the rounding of the
    linear solve (1e-16 x 99 x cond 7e5): IDA_CONV_FAIL at t = 0. Each group gets
    max(atol, ALGEBRAIC_FRACTION x rtol x its largest initial magnitude); the differential
    states keep atol. (With the whole rtol the error of x, which the algebraic variables
    drive, grew past 50 rtol on an oscillator; a tenth keeps it.)
    """
    differential = np.flatnonzero(~task.form.algebraic)
    algebraic = np.flatnonzero(task.form.algebraic)

    def group(values: np.ndarray) -> float:
        largest = float(np.max(np.abs(values), initial=0.0))
        return max(task.atol, ALGEBRAIC_FRACTION * task.rtol * largest)

    derivatives, multipliers = group(task.yp0[differential]), group(task.y0[algebraic])
    return (
        [task.atol] * differential.size
        + [derivatives] * differential.size
        + [multipliers] * algebraic.size
    )


@integrator
class CasadiIdas(CasadiBase):
    name = "casadi-idas"
    summary = "CasADi IDAS on the dae form (index <= 1) as x' = w, 0 = F(t, x, y_a, w)"
    Options = SundialsOptions
    accepts: ClassVar[dict[str, int]] = {"dae": 1}
    plugin = "idas"

    def dae(self, task: IntegrationTask) -> tuple[dict[str, Any], Any]:
        dae, differential, algebraic = _semi_explicit_dae(task)
        return dae, (differential, algebraic)

    def source(self, task: IntegrationTask) -> ca.Function:
        return task.form.residual.function

    def layout(self, task: IntegrationTask) -> Any:
        algebraic = task.form.algebraic
        return np.flatnonzero(~algebraic), np.flatnonzero(algebraic)

    def plugin_options(self, task: IntegrationTask) -> dict[str, Any]:
        # IDAS starts from the consistent (y, y') the workbench computed: without
        # init_xdot it assumed x' = 0, an inconsistent start whose error test failed at
        # t = 0 from rtol 1e-8 on (and cost digits above)
        differential = np.flatnonzero(~task.form.algebraic)
        init_xdot = [float(x) for x in task.yp0[differential]]
        options = {**_sundials_options(task), "calc_ic": False, "init_xdot": init_xdot}
        options.pop("abstol")
        return options | {"abstolv": algebraic_abstol(task)}

    def initial(self, task: IntegrationTask, layout: Any) -> dict[str, np.ndarray]:
        differential, algebraic = layout
        z0 = np.concatenate([task.yp0[differential], task.y0[algebraic]])
        return {"x0": task.y0[differential], "z0": z0}

    def states(self, result: dict[str, Any], layout: Any, n: int) -> np.ndarray:
        differential, algebraic = layout
        xf, zf = np.asarray(result["xf"]), np.asarray(result["zf"])
        xf = xf.reshape(differential.size, -1)
        zf = zf.reshape(differential.size + algebraic.size, -1)
        y = np.empty((xf.shape[1], n))
        y[:, differential] = xf.T
        y[:, algebraic] = zf[differential.size :].T
        return y


@dataclass(frozen=True)
class CollocationOptions:
    degree: int = 3  # collocation points per step; Radau IIA order 2 degree - 1
    intervals_per_output: int = 0  # steps per output interval; 0 = refined until rtol is met

    def __post_init__(self) -> None:
        if not 1 <= self.degree <= 9:
            raise ConfigError(f"degree must be between 1 and 9, not {self.degree}")
        if self.intervals_per_output < 0:
            raise ConfigError(
                f"intervals_per_output must be >= 0 (0 = from rtol), not "
                f"{self.intervals_per_output}"
            )


MAX_ELEMENTS = 200_000  # collocation steps over the whole run before giving up
ROOTFINDER_MARGIN = 1e-2  # rootfinder residual tolerance / the step's error tolerance
ROOTFINDER_FLOOR = 1e-10  # Andrews: 1e-12 fails near t = 0.002 s, 1e-10 completes
MAX_FAILED_REFINEMENTS = 2  # failed marches refined in a row before the failure stands


@dataclass
class _March:
    """Collocation steps taken output interval by output interval."""

    times: np.ndarray  # output times reached
    y: np.ndarray  # (len(times), n)
    steps: int
    failure: str = ""  # empty: every interval was integrated


@integrator
class CasadiCollocation(CasadiBase):
    name = "casadi-collocation"
    summary = "CasADi Radau IIA collocation, steps refined until rtol is met (or fixed)"
    Options = CollocationOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}
    plugin = "collocation"

    def plugin_options(self, task: IntegrationTask) -> dict[str, Any]:
        # the rootfinder's residual (in the state's units) is asked for a hundredth of
        # the error allowed, not CasADi's fixed 1e-12, which Andrews' squeezer (rates of
        # 1e3 rad/s) cannot reach in double precision, and never below ROOTFINDER_FLOOR
        scale = max(1.0, float(np.max(np.abs(task.y0))))
        tolerance = max(ROOTFINDER_MARGIN * (task.atol + task.rtol * scale), ROOTFINDER_FLOOR)
        return {
            "collocation_scheme": "radau",
            "show_eval_warnings": False,
            "interpolation_order": task.options.degree,
            "rootfinder_options": {
                "show_eval_warnings": False,
                "abstol": tolerance,
                "abstolStep": tolerance,
            },
        }

    def step_function(self, task: IntegrationTask, elements: int) -> ca.Function:
        """One output interval [t_k, t_k + h] as tau in [0, 1] (parameters t_k, h), in
        ``elements`` steps: dy/dtau = h f(t_k + h tau, y)."""
        dae, _ = _ode_dae(task)
        sym = ca.SX if isinstance(dae["x"], ca.SX) else ca.MX
        tau, start, length = sym.sym("tau"), sym.sym("t_k"), sym.sym("h")
        ode = length * ca.substitute(dae["ode"], dae["t"], start + length * tau)
        scaled = {"t": tau, "x": dae["x"], "p": ca.vertcat(start, length), "ode": ode}
        options = self.plugin_options(task) | {"number_of_finite_elements": elements}
        return ca.integrator("casadi_collocation", self.plugin, scaled, 0.0, 1.0, options)

    def march(self, task: IntegrationTask, elements: int) -> _March:
        """Integrate interval by interval, ``elements`` steps in each; stop at the first
        failed interval (CasADi raises for the whole call, keeping no partial result)."""
        step = self.step_function(task, elements)
        times = task.times
        y = np.empty((times.size, task.y0.size))
        y[0] = task.y0
        for k in range(times.size - 1):
            h = float(times[k + 1] - times[k])
            try:
                y[k + 1] = np.asarray(step(x0=y[k], p=[float(times[k]), h])["xf"]).ravel()
            except RuntimeError as error:
                failure = (
                    f"{self.name}: at t = {times[k]:g}: the step to {times[k + 1]:g} failed "
                    f"({_error_line(error)})"
                )
                return _March(times[: k + 1], y[: k + 1], k * elements, failure)
            if not np.all(np.isfinite(y[k + 1])):
                failure = f"{self.name}: at t = {times[k]:g}: non-finite state at {times[k + 1]:g}"
                return _March(times[: k + 1], y[: k + 1], k * elements, failure)
        return _March(times, y, (times.size - 1) * elements)

    def initial_elements(self, task: IntegrationTask) -> int:
        """Steps per output interval to start from: steps of rtol^(1/order) times the
        run's length (the error of a step of relative length x is about x^(order+1))."""
        order = 2 * task.options.degree - 1
        span = float(task.times[-1] - task.times[0])
        longest = float(np.max(np.diff(task.times)))
        return max(1, math.ceil(longest / (span * task.rtol ** (1.0 / order))))

    def refined(self, task: IntegrationTask) -> tuple[_March, int]:
        """March with m steps per output interval, then 2m: the estimate of the finer
        march's error, |y_2m - y_m| / (2^p - 1) (p = 2 degree - 1), must be within
        atol + rtol |y| at every output, else m grows by what the estimate asks for. A
        failed march (a step too long for Newton's iteration) is refined too, up to
        MAX_FAILED_REFINEMENTS times; the result's steps count every march."""
        order = 2 * task.options.degree - 1
        intervals = task.times.size - 1
        elements = self.initial_elements(task)
        coarse = self.march(task, elements)
        total, failed = coarse.steps, 0
        while True:
            if 2 * elements * intervals > MAX_ELEMENTS:
                if not coarse.failure:
                    coarse.failure = (
                        f"{self.name}: rtol {task.rtol:g} not met with {elements} steps per "
                        f"output interval ({elements * intervals} steps; the limit is "
                        f"{MAX_ELEMENTS})"
                    )
                return coarse, total
            fine = self.march(task, 2 * elements)
            total += fine.steps
            if fine.failure or coarse.failure:
                failed = failed + 1 if fine.failure else 0
                if failed > MAX_FAILED_REFINEMENTS:
                    return fine, total
                coarse, elements = fine, 2 * elements
                continue
            estimate = np.abs(fine.y - coarse.y) / (2**order - 1)
            worst = float(np.max(estimate / (task.atol + task.rtol * np.abs(fine.y))))
            if worst <= 1.0:
                return fine, total
            growth = 1.3 * worst ** (1.0 / order)  # error ~ (steps)^-p, with a margin
            if growth <= 2.0:
                coarse, elements = fine, 2 * elements
            else:
                elements = math.ceil(elements * growth)
                coarse = self.march(task, elements)
                total += coarse.steps

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        """Fixed ``intervals_per_output`` steps, or :meth:`refined` until rtol is met."""
        fixed = task.options.intervals_per_output
        if fixed:
            result = self.march(task, fixed)
            total = result.steps
        else:
            result, total = self.refined(task)
        trajectory.times, trajectory.y = result.times, result.y
        trajectory.stats.n_steps = total
        trajectory.stats.n_rejected = 0
        if result.failure:
            trajectory.success = False
            trajectory.message = result.failure
            return
        stalled = _first_stalled(task, trajectory.times, trajectory.y)
        if stalled is not None:
            trajectory.success = False
            trajectory.message = (
                f"{self.name}: the implicit step failed after t = "
                f"{trajectory.times[stalled - 1]:g} (the state stopped changing)"
            )
            trajectory.times = trajectory.times[:stalled]
            trajectory.y = trajectory.y[:stalled]


def _first_stalled(task: IntegrationTask, times: np.ndarray, y: np.ndarray) -> int | None:
    """First output index whose state was not computed (see the module docstring)."""
    rhs = task.form.rhs.function  # not the FastFunction: these calls are no solver cost
    for k in range(1, len(times)):
        if not np.all(np.isfinite(np.asarray(rhs(times[k], y[k])))):
            return k
        if np.array_equal(y[k], y[k - 1]):
            if np.any(np.asarray(rhs(times[k - 1], y[k - 1])) != 0):
                return k
    return None
