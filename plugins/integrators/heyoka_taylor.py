"""heyoka's adaptive Taylor method on the ``ode`` form: y' = f(t, y), y = [q, v].

heyoka (Biscani & Izzo 2021, MNRAS 504, 2614) integrates by Taylor series whose
coefficients it computes by automatic differentiation of the right-hand side's expression
tree, compiled with LLVM; order and step adapt to the tolerance (order about
-ln(tol) / 2, the step from the last two coefficients, Jorba & Zou 2005). The equations'
CasADi graph is translated into heyoka expressions (``_casadi_heyoka``), so the integrated
system is the formalism's own, operation for operation.

Tolerance: heyoka has one, ``tol``, applied as an absolute error where the state's
infinity norm is below 1 and a relative one above; the plugin passes min(rtol, atol).
Option ``precision``: "double", "extended" (x86 80-bit long double, 64-bit mantissa) or
"quad" (IEEE binary128, where the heyoka build supports it); states are returned as
doubles. ``high_accuracy`` (heyoka's option) trades some speed for smaller round-off in
the Taylor summation, for tolerances near machine precision. ``compact_mode``: heyoka's
mode for large expressions (loops over functions instead of one straight-line body);
"auto" turns it on above COMPACT_MODE_INSTRUCTIONS CasADi instructions. Measured at tol
1e-15 (2026-11-23, loaded 2-core machine): the heavy top's 760 instructions compile in
3.6 s compact and 164 s not, and integrate in 0.016 s against 0.011 s.

Statistics: ``n_steps`` are heyoka's steps; each step evaluates the right-hand side's
Taylor jet once, counted as ``n_rhs``; no Jacobian, no rejected steps (a Taylor step is
never rejected); the LLVM compilation is ``setup_s``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from workbench.errors import ConfigError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.registry import integrator

# heyoka (and the SymPy it imports: 140 MiB, 0.3 s) is imported by a run that uses it, not
# by plugin discovery: every sweep's parent and report would carry it otherwise.
PRECISIONS = ("double", "extended", "quad")
COMPACT_MODE_INSTRUCTIONS = 50


def fp_type(precision: str) -> Any:
    """heyoka's floating-point type of ``precision`` (quad: where the build has real128)."""
    if precision == "double":
        return float
    if precision == "extended":
        return np.longdouble
    import heyoka as hy

    if not hasattr(hy, "real128"):
        raise ConfigError(
            'precision "quad" needs a heyoka built with real128 (binary128); this one has '
            'none: use "extended"'
        )
    return hy.real128


@dataclass(frozen=True)
class HeyokaOptions:
    precision: str = "double"  # "double", "extended" (80-bit) or "quad" (binary128)
    high_accuracy: bool = True  # heyoka's compensated summation of the Taylor series
    compact_mode: str = "auto"  # "auto", "on" or "off"

    def __post_init__(self) -> None:
        if self.precision not in PRECISIONS:
            raise ConfigError(
                f"precision must be one of {sorted(PRECISIONS)}, not {self.precision!r}"
            )
        fp_type(self.precision)  # quad without real128: said here, not at the run
        if self.compact_mode not in ("auto", "on", "off"):
            raise ConfigError(
                f'compact_mode must be "auto", "on" or "off", not {self.compact_mode!r}'
            )


def taylor_system(function: Any, n: int) -> tuple[list[Any], int]:
    """heyoka's [(y_i, f_i(t, y))] for the CasADi ode right-hand side ``function`` (t, y) -> y',
    and the number of instructions of its SX graph."""
    import heyoka as hy

    from workbench.plugins.integrators._casadi_heyoka import as_sx_function, translate

    sx = as_sx_function(function)
    variables = list(hy.make_vars(*[f"y{i}" for i in range(n)])) if n > 1 else [hy.make_vars("y0")]
    (derivatives,) = translate(sx, [[hy.time], variables])
    return list(zip(variables, derivatives, strict=True)), sx.n_instructions()


@integrator
class HeyokaTaylor(Integrator):
    name = "heyoka-taylor"
    summary = "heyoka: adaptive-order Taylor method (LLVM), double, extended or quad precision"
    Options = HeyokaOptions
    accepts: ClassVar[dict[str, int]] = {"ode": 0}

    def incompatibility(self, equations: Any, options: Any) -> str | None:
        form = equations.forms.get("ode")
        if form is None:
            return None
        from workbench.plugins.integrators._casadi_heyoka import TranslationError, as_sx_function

        try:
            as_sx_function(form.rhs.function)
        except TranslationError as error:
            return str(error)
        return None

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        import heyoka as hy

        from workbench.plugins.integrators._casadi_heyoka import TranslationError

        options = task.options
        started = time.perf_counter()
        try:
            system, instructions = taylor_system(task.form.rhs.function, task.form.n)
        except TranslationError as error:
            trajectory.success = False
            trajectory.message = f"{self.name}: {error}"
            return
        real = fp_type(options.precision)
        compact = {"on": True, "off": False}.get(
            options.compact_mode, instructions > COMPACT_MODE_INSTRUCTIONS
        )

        def typed(values: np.ndarray) -> np.ndarray:
            return np.asarray(values, dtype=float).astype(real)

        tol = min(task.rtol, task.atol)
        taylor = hy.taylor_adaptive(
            system,
            typed(task.y0),
            time=real(float(task.times[0])),
            tol=real(tol),
            high_accuracy=options.high_accuracy,
            compact_mode=compact,
            fp_type=real,
        )
        trajectory.stats.setup_s = time.perf_counter() - started
        outcome, _, _, n_steps, _, states = taylor.propagate_grid(typed(task.times))
        reached = task.times.size
        if outcome != hy.taylor_outcome.time_limit:
            end = float(taylor.time)
            reached = int(np.searchsorted(task.times, end, side="right"))
            trajectory.success = False
            trajectory.message = f"{self.name}: heyoka stopped at t = {end:.6g} s ({outcome.name})"
        trajectory.times = task.times[:reached]
        trajectory.y = np.asarray(states, dtype=float)[:reached].reshape(reached, task.form.n)
        trajectory.stats.n_steps = int(n_steps)
        trajectory.stats.n_rhs = int(n_steps)
        trajectory.stats.n_rejected = 0
