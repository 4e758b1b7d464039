"""The ``scipy-dae`` package's Radau IIA and BDF on the ``dae`` form, 0 = F(t, y, y').

scipy-dae (Jonas Breuling) extends SciPy's ``solve_ivp`` methods to implicit equations:
Radau IIA order 5 and the variable-order NDF/BDF, both with Newton iterations on
dF/dy + c dF/dy' from the equations' exact Jacobian. It is meant for DAEs up to index 3
with the algebraic variables' index declared (``var_index``, scaling their error
estimates by h^(index - 1)); version 0.1.1, the one on the registry, raises
NotImplementedError for ``var_index``. The multipliers (lambda, and mu at index 2) are
therefore left out of the local error test instead, through their absolute tolerance
(ALGEBRAIC_ATOL), as IDA does with ``suppress_algebraic``, and at index 3 the velocities
too (index-2 variables there): their error estimates do not shrink with the step, and with
them in the test both methods stop at t = 0 ("required step size is less than spacing
between numbers") at every tolerance tried. The positions alone then control the step.

Statistics: right-hand-side and Jacobian evaluations are counted by the base class;
``n_lu`` is the package's ``nlu``; accepted steps are counted through an event function
that never crosses zero (the package calls it once at t0 and once a step); rejected
steps are not reported (-1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy_dae.integrate import solve_dae

from workbench.errors import ConfigError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator

LEAST_RTOL = 100 * np.finfo(float).eps  # scipy_dae.integrate._dae.common's floor
ALGEBRAIC_ATOL = 1e10  # error weight 1 / (rtol |y| + atol) ~ 0: out of the error test


@dataclass(frozen=True)
class ScipyDaeOptions:
    max_step: float = with_unit(float("inf"), "s")  # upper bound on the step size
    suppress_algebraic: bool = True  # multipliers out of the local error test

    def __post_init__(self) -> None:
        if not self.max_step > 0:
            raise ConfigError(f"max_step must be > 0 s, not {self.max_step}")


class ScipyDae(Integrator):
    """Base of the scipy-dae methods; subclasses set ``method``."""

    Options = ScipyDaeOptions
    accepts: ClassVar[dict[str, int]] = {"dae": 3}
    method: ClassVar[str] = "Radau"

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        form, options = task.form, task.options

        def residual(t: float, y: np.ndarray, yp: np.ndarray) -> np.ndarray:
            return form.residual(t, y, yp)[0]

        def jacobian(t: float, y: np.ndarray, yp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            (d_y,) = form.jacobian(t, y, yp, 0.0)
            (with_yp,) = form.jacobian(t, y, yp, 1.0)
            return d_y, with_yp - d_y

        atol: float | np.ndarray = task.atol
        if options.suppress_algebraic and form.index >= 1 and form.algebraic.any():
            suppressed = form.algebraic.copy()
            if form.index == 3:  # the velocities are index-2 variables there
                nq = task.equations.nq
                suppressed[nq : nq + task.equations.nv] = True
            atol = np.where(suppressed, ALGEBRAIC_ATOL, task.atol)
        calls = [0]
        if task.rtol < LEAST_RTOL:  # the package raises it to LEAST_RTOL, said only by a print
            trajectory.warnings.append(
                f"the accuracy asked was not attempted: scipy-dae raises rtol {task.rtol:g} to "
                f"its least, {LEAST_RTOL:.3g} (100 machine epsilons), which was taken instead"
            )

        def count_step(t: float, y: np.ndarray, yp: np.ndarray) -> float:
            calls[0] += 1
            return 1.0  # never zero: no event, only a call per accepted step

        solution = solve_dae(
            residual,
            (task.times[0], task.times[-1]),
            task.y0,
            task.yp0,
            method=self.method,
            t_eval=task.times,
            rtol=task.rtol,
            atol=atol,
            jac=jacobian,
            max_step=options.max_step,
            events=count_step,
        )
        trajectory.times = np.asarray(solution.t)
        trajectory.y = np.asarray(solution.y).T.reshape(len(solution.t), task.y0.size)
        trajectory.stats.n_steps = max(calls[0] - 1, 0)
        trajectory.stats.n_rejected = -1
        trajectory.stats.n_lu = int(getattr(solution, "nlu", -1))
        if solution.status < 0:
            trajectory.success = False
            trajectory.message = f"{self.name}: {solution.message}"


@integrator
class ScipyDaeRadau(ScipyDae):
    name = "scipy-dae-radau"
    summary = "scipy-dae Radau IIA order 5 on F(t, y, y') = 0, index <= 3, exact Jacobian"
    method = "Radau"


@integrator
class ScipyDaeBdf(ScipyDae):
    name = "scipy-dae-bdf"
    summary = "scipy-dae variable-order BDF (NDF) on F(t, y, y') = 0, index <= 3"
    method = "BDF"
