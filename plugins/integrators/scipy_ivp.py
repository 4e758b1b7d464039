"""SciPy's ``solve_ivp`` methods on the ``ode`` form: y' = f(t, y), y = [q, v].

One class, parameterized by a table of workbench names -> SciPy methods. The implicit
methods (Radau, BDF, LSODA) get the exact Jacobian df/dy of the equations. Output at
``task.times`` comes from each method's dense output (``t_eval``).

Statistics: right-hand-side and Jacobian evaluations are counted by the base class;
``n_lu`` is SciPy's ``nlu``; ``n_steps`` counts accepted steps through a subclass of
the SciPy solver; rejected steps and Newton iterations are not reported by SciPy (-1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK45, OdeSolver, Radau, solve_ivp

from workbench.errors import ConfigError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    LastEvaluation,
    Trajectory,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator

LEAST_RTOL = 100 * np.finfo(float).eps  # scipy.integrate._ivp.common.validate_tol's floor


@dataclass(frozen=True)
class ScipyOptions:
    max_step: float = with_unit(float("inf"), "s")  # upper bound on the step size
    first_step: float | None = with_unit(None, "s")  # None lets the method choose

    def __post_init__(self) -> None:
        if not self.max_step > 0:
            raise ConfigError(f"max_step must be > 0 s, not {self.max_step}")
        if self.first_step is not None and not self.first_step > 0:
            raise ConfigError(f"first_step must be > 0 s, not {self.first_step}")


def _counting(method: type[OdeSolver], counter: list[int]) -> type[OdeSolver]:
    """A subclass of ``method`` that counts its accepted steps in ``counter[0]``."""

    class Counting(method):  # type: ignore[valid-type, misc]
        def _step_impl(self):  # noqa: ANN202 - SciPy's private signature
            success, message = super()._step_impl()
            if success:
                counter[0] += 1
            return success, message

    Counting.__name__ = f"Counting{method.__name__}"
    return Counting


class ScipyIvp(Integrator):
    """Base of the solve_ivp family; subclasses set ``method`` and ``implicit``."""

    Options = ScipyOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}
    method: ClassVar[type[OdeSolver]] = RK45
    implicit: ClassVar[bool] = False

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        form, options = task.form, task.options
        accepted = [0]

        last = LastEvaluation("right-hand side")

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            # a copy: RK stages keep the returned arrays. No finiteness test here: at
            # about 1 us a call it cost more than many a right-hand side; a failure
            # looks at the latest value instead (a NaN makes the method shrink its step
            # until it gives up, evaluating at the NaN to the end)
            value = form.rhs.into(t, y)[0].copy()
            last.t, last.value = t, value
            return value

        if task.rtol < LEAST_RTOL:  # SciPy raises it to LEAST_RTOL, said only by a UserWarning
            trajectory.warnings.append(
                f"the accuracy asked was not attempted: SciPy raises rtol {task.rtol:g} to its "
                f"least, {LEAST_RTOL:.3g} (100 machine epsilons), which was taken instead"
            )
        extra: dict[str, Any] = {"max_step": options.max_step}
        if options.first_step is not None:
            extra["first_step"] = options.first_step
        if self.implicit:
            extra["jac"] = lambda t, y: form.jacobian(t, y)[0]
        solution = solve_ivp(
            rhs,
            (task.times[0], task.times[-1]),
            task.y0,
            method=_counting(self.method, accepted),
            t_eval=task.times,
            rtol=task.rtol,
            atol=task.atol,
            **extra,
        )
        trajectory.times = np.asarray(solution.t)
        trajectory.y = np.asarray(solution.y).T.reshape(len(solution.t), task.y0.size)
        trajectory.stats.n_steps = accepted[0]
        trajectory.stats.n_rejected = -1
        trajectory.stats.n_lu = int(solution.nlu) if self.implicit else -1
        if solution.status < 0:
            trajectory.success = False
            trajectory.message = f"{self.name}: {solution.message}"
            trajectory.message += last.note()


# workbench name -> (SciPy method, uses the Jacobian, summary)
METHODS: dict[str, tuple[type[OdeSolver], bool, str]] = {
    "scipy-rk45": (RK45, False, "SciPy RK45: explicit Dormand-Prince 5(4), adaptive"),
    "scipy-dop853": (DOP853, False, "SciPy DOP853: explicit Dormand-Prince 8(5,3), adaptive"),
    "scipy-radau": (Radau, True, "SciPy Radau: implicit Radau IIA order 5, exact Jacobian"),
    "scipy-bdf": (BDF, True, "SciPy BDF: variable-order BDF (NDF) 1-5, exact Jacobian"),
    "scipy-lsoda": (LSODA, True, "SciPy LSODA: Adams/BDF with stiffness switching (ODEPACK)"),
}

for _name, (_method, _implicit, _summary) in METHODS.items():
    integrator(
        type(
            "Scipy" + _method.__name__.title().replace("_", ""),
            (ScipyIvp,),
            {
                "name": _name,
                "summary": _summary,
                "method": _method,
                "implicit": _implicit,
                "__module__": __name__,
            },
        )
    )
