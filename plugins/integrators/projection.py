"""Integrator ``projected``: any ode-form integrator, projected onto the constraint manifold.

The ode form of a constrained system is the index-1 formulation (possibly with Baumgarte
stabilization): it satisfies g = 0 and W v + w = 0 only in its derivatives, so the
residuals drift. Projection (Hairer-Lubich-Wanner, *Geometric Numerical Integration*
IV.4; Eich 1993) puts the state back on the manifold.

Design: one registered integrator ``projected`` with options ``base`` (the name of any
registered integrator that accepts the ode form, default ``rk4``), ``base_options`` (its
options), ``projection`` in {"none", "position", "position+velocity"} and ``metric``. It
runs the base integrator output interval by output interval (a fresh ``solve`` on
[t_i, t_{i+1}] from the projected state) and projects the state at each output time.
So projection happens at the output times only, not after every internal step: the
output grid sets how often (choose it fine enough); a base with step-size control
restarts at every output time. This keeps every base integrator untouched and reuses
it through the registry; the reusable piece is :func:`project_state`.

Projection of (q, v) at time t, in the metric ``metric`` ("mass": M(q), "identity"):

* position: Gauss-Newton on g(t, q) = 0 with minimal-norm corrections,
  q <- q + H(q) dv, dv = -M^-1 B^T (B M^-1 B^T)^-1 g with B = G H (mass metric: the
  correction is a velocity-space displacement of least kinetic "cost", as nq != nv
  coordinates such as Euler parameters require), or q <- q - G^T (G G^T)^-1 g
  (identity metric, in q directly); iterated until |g| <= tol (1 + |q|);
* velocity (after the position step): v <- v - M^-1 W^T (W M^-1 W^T)^-1 (W v + w), the
  orthogonal projection onto W v + w = 0 in the chosen metric (one linear solve; it
  also covers nonholonomic rows).

In the mass metric both corrections are solved as the augmented system
[M B^T; B 0] [dv; mu] = [0; -r] (r = g, or W v + w with W for B), which gives the formulas
above when M is invertible and stays nonsingular when it is not but M is positive
definite on the null space of B: absolute coordinates give point masses zero rotational
inertia, and the constraints fix those directions (minimal-norm least squares, so
redundant rows do no harm either).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from workbench.equations import Equations
from workbench.errors import ConfigError, IntegrationError, PluginError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.registry import get_integrator, integrator

Projection = Literal["none", "position", "position+velocity"]
Metric = Literal["mass", "identity"]


def project_state(
    equations: Equations,
    t: float,
    y: np.ndarray,
    mode: str = "position+velocity",
    metric: str = "mass",
    tolerance: float = 1e-13,
    max_iterations: int = 20,
) -> tuple[np.ndarray, int]:
    """(y projected onto the constraints, Gauss-Newton iterations) for y = [q, v, ...].

    ``mode``: "none", "position" or "position+velocity"; ``metric``: "mass" or
    "identity" (see the module docstring). IntegrationError if Gauss-Newton fails.
    """
    if mode == "none":
        return y, 0
    mech = equations.form("mechanical")
    nq, nv, nc, m = equations.nq, equations.nv, mech.n_constraints, mech.n_holonomic
    y = np.array(y, dtype=float)
    q, v = y[:nq], y[nq : nq + nv]
    iterations = 0
    if nc == 0:
        return y, 0

    def correction(q: np.ndarray, b: np.ndarray, residual: np.ndarray) -> np.ndarray:
        """dv of least dv^T M dv (mass) or |dv| (identity) with b dv = -residual."""
        if metric == "identity":
            return -b.T @ np.linalg.lstsq(b @ b.T, residual, rcond=None)[0]
        (mass,) = mech.mass(t, q)
        mass = np.atleast_2d(mass)
        rows = b.shape[0]
        augmented = np.block([[mass, b.T], [b, np.zeros((rows, rows))]])
        rhs = np.concatenate([np.zeros(nv), -np.asarray(residual, dtype=float).ravel()])
        return np.linalg.lstsq(augmented, rhs, rcond=None)[0][:nv]

    if m:
        scale = 1.0 + np.max(np.abs(q))
        for iterations in range(max_iterations + 1):  # noqa: B007 - returned
            (g,) = mech.position_constraints(t, q)
            if not np.all(np.isfinite(g)):
                raise IntegrationError(f"projection: the constraints are NaN at t = {t:.6g}")
            if np.max(np.abs(g)) <= tolerance * scale:
                break
            if iterations == max_iterations:
                raise IntegrationError(
                    f"projection: Gauss-Newton did not reach g = 0 at t = {t:.6g} "
                    f"(residual {np.max(np.abs(g)):.3g}); the state drifted too far"
                )
            (g_q,) = mech.position_jacobian(t, q)
            g_q = np.reshape(g_q, (m, nq))
            if metric == "identity":
                q = q - g_q.T @ np.linalg.lstsq(g_q @ g_q.T, g, rcond=None)[0]
            else:
                (h_matrix,) = mech.kinematics(t, q)
                h_matrix = np.reshape(h_matrix, (nq, nv))
                q = q + h_matrix @ correction(q, g_q @ h_matrix, np.ravel(g))
        y[:nq] = q
    if mode == "position+velocity":
        (w_matrix,) = mech.velocity_matrix(t, q)
        (residual,) = mech.velocity_constraints(t, q, v)
        v = v + correction(q, np.reshape(w_matrix, (nc, nv)), np.ravel(residual))
        y[nq : nq + nv] = v
    return y, iterations


@dataclass(frozen=True)
class ProjectedOptions:
    base: str = "rk4"  # any registered integrator accepting the ode form
    projection: Projection = "position+velocity"
    metric: Metric = "mass"
    base_options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.base_options, dict):
            raise ConfigError(f"base_options must be a table, not {self.base_options!r}")


@integrator
class Projected(Integrator):
    name = "projected"
    summary = "An ode-form integrator (base) projected onto g = 0 and W v + w = 0 at outputs"
    Options = ProjectedOptions
    accepts = {"ode": 0}

    def _base(self, options: Any) -> Integrator:
        base_class = get_integrator(options.base)
        if "ode" not in base_class.accepts:
            raise PluginError(
                f"projected: base integrator {options.base!r} does not accept the ode form "
                f"(it accepts {base_class.accepts})"
            )
        if base_class is type(self):
            raise PluginError("projected: the base integrator cannot be 'projected' itself")
        return base_class()

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        try:
            base = self._base(options)
            base.parse_options(options.base_options)
        except (PluginError, ConfigError) as error:
            return str(error)
        if options.projection != "none" and "mechanical" not in equations.forms:
            return "projection needs the mechanical form (constraint functions)"
        return base.incompatibility(equations, base.parse_options(options.base_options))

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        options = task.options
        base = self._base(options)
        equations, times = task.equations, task.times
        stats = trajectory.stats
        stats.n_newton = 0
        n_lu = 0
        y, _ = project_state(
            equations, float(times[0]), task.y0, options.projection, options.metric
        )
        rows, reached = [y], [float(times[0])]
        try:
            for t_start, t_end in zip(times[:-1], times[1:], strict=True):
                result = base.solve(
                    equations,
                    y,
                    None,
                    np.array([t_start, t_end]),
                    task.rtol,
                    task.atol,
                    options.base_options,
                    form="ode",
                )
                stats.n_steps += max(result.stats.n_steps, 0)
                stats.fixed_step = result.stats.fixed_step
                stats.n_rejected += max(result.stats.n_rejected, 0)
                n_lu += max(result.stats.n_lu, 0)
                if not result.success:
                    raise IntegrationError(
                        f"projected: base integrator {options.base!r} failed on "
                        f"[{t_start:.6g}, {t_end:.6g}] s: {result.message}"
                    )
                y, iterations = project_state(
                    equations, float(t_end), result.y[-1], options.projection, options.metric
                )
                stats.n_newton += iterations
                rows.append(y)
                reached.append(float(t_end))
        finally:  # keep what was reached, also when a step fails
            trajectory.y = np.array(rows)
            trajectory.times = np.array(reached)
        stats.n_lu = n_lu
