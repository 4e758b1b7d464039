"""SUNDIALS CVODE and IDA through scikit-sundae (``sksundae``), with exact dense Jacobians.

* ``sundials-cvode-bdf`` / ``sundials-cvode-adams``: CVODE on the ``ode`` form
  y' = f(t, y): BDF orders 1-5 or Adams-Moulton orders 1-12, both with Newton iterations
  on the exact df/dy.
* ``sundials-ida``: IDA (variable-order BDF) on the ``dae`` form 0 = F(t, y, y') up to
  index 2, iteration matrix dF/dy + c dF/dy' exact. The workbench passes a consistent
  (y0, y0'); option ``calc_initcond`` lets IDA correct y0' and the algebraic y0 anyway.
  The algebraic components (multipliers) are excluded from the local error test
  (option ``suppress_algebraic``, default on) — the standard treatment of index-2
  systems (Brenan, Campbell, Petzold 1996), and needed at index 1 too: there lambda is
  fixed by W v' = gamma, i.e. by v', whose BDF value is one order less accurate than v,
  so an error test on lambda forces tiny steps (heavy-top, absolute-dae, index 1, rtol
  1e-6: 250 000 residual evaluations with lambda in the test, 1 700 without, the same
  pose error). scikit-sundae does not expose IDASetSuppressAlg, so this is done with an
  absolute tolerance of ``ALGEBRAIC_ATOL`` for them, which makes their error weights
  vanish.

Steps are taken one at a time (``onestep``) and the outputs interpolated from the
solver's own polynomial (``normal`` mode behind the last step), so ``n_steps`` is the
number of accepted steps. scikit-sundae reports only right-hand-side and Jacobian
counts; IDA evaluates the Jacobian at every linear setup, so for IDA ``n_lu`` is the
number of Jacobian evaluations; rejected steps and Newton iterations are not
exposed (-1).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from sksundae.cvode import CVODE
from sksundae.ida import IDA

from workbench.errors import ConfigError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    LastEvaluation,
    Trajectory,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator

ALGEBRAIC_ATOL = 1e10  # error weight 1 / (rtol |y| + atol) ~ 0: out of the error test


@dataclass(frozen=True)
class SundialsOptions:
    max_steps: int = 100_000  # accepted steps in all before giving up
    max_step: float = with_unit(0.0, "s")  # 0 = unbounded
    max_order: int = 0  # 0 = the method's highest (BDF 5, Adams 12)

    def __post_init__(self) -> None:
        if self.max_steps < 1:
            raise ConfigError(f"max_steps must be >= 1, not {self.max_steps}")
        if self.max_step < 0:
            raise ConfigError(f"max_step must be >= 0 s (0 = unbounded), not {self.max_step}")
        if self.max_order < 0:
            raise ConfigError(f"max_order must be >= 0 (0 = highest), not {self.max_order}")


@dataclass(frozen=True)
class IdaOptions(SundialsOptions):
    calc_initcond: bool = False  # let IDACalcIC correct y0' and the algebraic y0
    suppress_algebraic: bool = True  # multipliers out of the local error test (index >= 1)


def _common_options(task: IntegrationTask, highest_order: int) -> dict[str, Any]:
    options = task.options
    return {
        "rtol": task.rtol,
        "atol": task.atol,
        "max_step": options.max_step,
        "max_order": options.max_order or highest_order,
        "max_num_steps": options.max_steps,
    }


def _march(
    solver: Any,
    task: IntegrationTask,
    trajectory: Trajectory,
    name: str,
    y0: np.ndarray,
    last: LastEvaluation,
    probe: Callable[[float, Any], np.ndarray],
) -> None:
    """Step one accepted step at a time to times[-1], interpolating every output passed;
    a failure's message says when the equations were NaN or infinite: ``last``, else
    ``probe(t, the solver's result)`` after the time reached."""
    times = task.times
    rows, reached = [np.array(y0, dtype=float)], [times[0]]
    k, steps, t_last, replay = 1, 0, float(times[0]), False
    while k < len(times):
        if steps >= task.options.max_steps:
            trajectory.success = False
            trajectory.message = (
                f"{name}: {steps} steps taken before t = {times[-1]:g} (option max_steps)"
            )
            break
        result = solver.step(times[-1], method="onestep", tstop=times[-1])
        if not result.success:
            trajectory.success = False
            trajectory.message = f"{name}: at t = {float(result.t):g}: {result.message}"
            trajectory.message += _nonfinite_note(last, probe, result, float(times[-1]))
            break
        if not np.all(np.isfinite(result.y)):
            # NaN fails every comparison, so the error test passes it: stop here ourselves
            trajectory.success = False
            trajectory.message = f"{name}: the solution became NaN at t = {float(result.t):g}"
            break
        if result.t == t_last and replay:
            # after an interpolated output the solver first hands back its last step again
            replay = False
            continue
        if result.t <= t_last:
            trajectory.success = False
            trajectory.message = f"{name}: no progress at t = {t_last:g} (step size underflow)"
            trajectory.message += _nonfinite_note(last, probe, result, float(times[-1]))
            break
        steps, t_last = steps + 1, float(result.t)
        while k < len(times) and times[k] <= result.t:
            output = solver.step(times[k], method="normal")
            replay = True
            rows.append(np.array(output.y, dtype=float))
            reached.append(times[k])
            k += 1
    trajectory.times = np.array(reached)
    trajectory.y = np.vstack(rows)
    trajectory.stats.n_steps = steps


def _nonfinite_note(last: LastEvaluation, probe: Any, result: Any, t_end: float) -> str:
    """Whether the equations were NaN or infinite: the last evaluation, else probed at the
    solver's result after its time."""
    return last.note(lambda t: probe(t, result), float(result.t), t_end)


class CvodeBase(Integrator):
    """CVODE on the ode form; subclasses set ``method``."""

    Options = SundialsOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}
    method: ClassVar[str] = "BDF"

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        rhs, jacobian = task.form.rhs, task.form.jacobian
        last = LastEvaluation("right-hand side")

        def rhsfn(t: float, y: np.ndarray, yp: np.ndarray) -> None:
            last.t, last.value = t, rhs.into(t, y)[0]
            yp[:] = last.value

        def jacfn(t: float, y: np.ndarray, yp: np.ndarray, jj: np.ndarray) -> None:
            jj[:, :] = jacobian.into(t, y)[0]

        solver = CVODE(
            rhsfn,
            method=self.method,
            jacfn=jacfn,  # Newton iterations for Adams too (SUNDIALS' default)
            **_common_options(task, 5 if self.method == "BDF" else 12),
        )
        solver.init_step(task.times[0], task.y0)
        probe = lambda t, result: rhs.into(t, result.y)[0]  # noqa: E731
        _march(solver, task, trajectory, self.name, task.y0, last, probe)
        trajectory.stats.n_rejected = -1


@integrator
class CvodeBdf(CvodeBase):
    name = "sundials-cvode-bdf"
    summary = "SUNDIALS CVODE, variable-order BDF 1-5, Newton with exact dense Jacobian"
    method = "BDF"


@integrator
class CvodeAdams(CvodeBase):
    name = "sundials-cvode-adams"
    summary = "SUNDIALS CVODE, variable-order Adams-Moulton 1-12, exact dense Jacobian"
    method = "Adams"


@integrator
class Ida(Integrator):
    name = "sundials-ida"
    summary = "SUNDIALS IDA, variable-order BDF on F(t, y, y') = 0, index <= 2, exact Jacobian"
    Options = IdaOptions
    accepts: ClassVar[dict[str, int]] = {"dae": 2}

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        form = task.form
        residual, jacobian = form.residual, form.jacobian
        algebraic = np.flatnonzero(form.algebraic)
        setups = [0]  # IDA evaluates the Jacobian at each linear setup

        last = LastEvaluation("residual")

        def resfn(t: float, y: np.ndarray, yp: np.ndarray, res: np.ndarray) -> None:
            last.t, last.value = t, residual.into(t, y, yp)[0]
            res[:] = last.value

        def jacfn(
            t: float, y: np.ndarray, yp: np.ndarray, res: np.ndarray, cj: float, jj: np.ndarray
        ) -> None:
            setups[0] += 1
            jj[:, :] = jacobian.into(t, y, yp, cj)[0]

        options = _common_options(task, 5)
        if task.options.suppress_algebraic and form.index >= 1 and algebraic.size:
            atol = np.full(form.n, task.atol)
            atol[algebraic] = ALGEBRAIC_ATOL
            options["atol"] = atol
        initcond: Literal["yp0"] | None = "yp0" if task.options.calc_initcond else None
        solver = IDA(
            resfn,
            jacfn=jacfn,
            algebraic_idx=algebraic if algebraic.size else None,
            calc_initcond=initcond,
            calc_init_dt=float(task.times[1] - task.times[0]),
            **options,
        )
        start = solver.init_step(task.times[0], task.y0, task.yp0)
        if not start.success:
            trajectory.success = False
            trajectory.message = f"{self.name}: initial conditions: {start.message}"
            return
        probe = lambda t, result: residual.into(t, result.y, result.yp)[0]  # noqa: E731
        _march(solver, task, trajectory, self.name, start.y, last, probe)
        trajectory.stats.n_lu = setups[0]
        trajectory.stats.n_rejected = -1
