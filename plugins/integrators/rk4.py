"""The classical fixed-step Runge-Kutta method of order 4 on the ``ode`` form.

    k1 = f(t, y),  k2 = f(t + h/2, y + h/2 k1),  k3 = f(t + h/2, y + h/2 k2),
    k4 = f(t + h, y + h k3),  y_next = y + h/6 (k1 + 2 k2 + 2 k3 + k4).

Each output interval [t_i, t_i+1] is divided into ceil((t_i+1 - t_i) / step) equal steps,
so steps land on the output times and no step is longer than the step: option ``step``
if given (then the tolerances are not used), else the step an order-4 method needs at rtol
(:func:`workbench.plugin.integrator.step_for_tolerance`: 1e-3 s at rtol 1e-6, 3.2e-4 s
at 1e-8). The global error is O(step^4); the row's ``fixed_step_s`` records the
longest step taken (an output interval is cut into equal steps no longer than the one asked).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from workbench.errors import ConfigError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    Trajectory,
    step_for_tolerance,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator

ORDER = 4


@dataclass(frozen=True)
class Rk4Options:
    step: float | None = with_unit(None, "s")  # largest step; None: from rtol (step_for_tolerance)

    def __post_init__(self) -> None:
        if self.step is not None and not (math.isfinite(self.step) and self.step > 0):
            raise ConfigError(f"step must be a positive number of seconds, not {self.step}")


@integrator
class Rk4(Integrator):
    name = "rk4"
    summary = "Classical Runge-Kutta order 4, fixed step (from rtol or option step)"
    Options = Rk4Options
    accepts: ClassVar[dict[str, int]] = {"ode": 0}

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        rhs = task.form.rhs
        times = task.times
        y = task.y0.copy()
        rows = [y.copy()]
        steps = 0
        step = task.options.step or step_for_tolerance(task.rtol, ORDER)
        trajectory.stats.fixed_step = step
        longest = 0.0  # the step taken: each output interval in equal steps no longer
        for t_start, t_end in zip(times[:-1], times[1:], strict=True):
            n = max(1, math.ceil((t_end - t_start) / step * (1 - 1e-12)))
            h = (t_end - t_start) / n
            longest = max(longest, h)
            trajectory.stats.fixed_step = longest
            for i in range(n):
                t = t_start + i * h
                (k1,) = rhs(t, y)
                (k2,) = rhs(t + h / 2, y + h / 2 * k1)
                (k3,) = rhs(t + h / 2, y + h / 2 * k2)
                (k4,) = rhs(t + h, y + h * k3)
                y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            steps += n
            rows.append(y.copy())
            if not np.all(np.isfinite(y)):
                trajectory.message = f"rk4: the solution became NaN or infinite by t = {t_end:g}"
                break
        trajectory.times = times[: len(rows)]
        trajectory.y = np.vstack(rows)
        trajectory.stats.n_steps = steps
