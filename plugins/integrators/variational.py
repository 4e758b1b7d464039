"""Integrator ``variational-midpoint``: a constrained variational integrator for M(q).

J. E. Marsden, M. West, "Discrete mechanics and variational integrators", Acta Numerica
10 (2001) 357-514, sections 1.5-3.5; B. Leimkuhler, S. Reich, *Simulating Hamiltonian
Dynamics* (2004), ch. 7 (the RATTLE-type treatment of holonomic constraints). For

    M(q) v' = Q(t, q, v) - G(t, q)^T lambda,   g(t, q) = 0,   q' = v,

with the Lagrangian L = v^T M(q) v / 2 - V(q), the midpoint discrete Lagrangian
L_d(q0, q1) = h L(q_m, v_m), q_m = (q0 + q1)/2, v_m = (q1 - q0)/h, gives
D1 L_d = h/2 L_q - M(q_m) v_m and D2 L_d = h/2 L_q + M(q_m) v_m, and one step from
(q_k, p_k = M(q_k) v_k) is

    p_k + D1 L_d(q_k, q_{k+1}) - h/2 G(q_k)^T lambda = 0,   g(t_{k+1}, q_{k+1}) = 0
    p_{k+1} = D2 L_d(q_k, q_{k+1}) - h/2 G(q_{k+1})^T mu,   G(q_{k+1}) v_{k+1} + w = 0

with M(q_{k+1}) v_{k+1} = p_{k+1}: q_{k+1} and lambda by Newton's method, v_{k+1} and mu
by one linear solve of [M, h/2 G^T; G, 0] (so M itself may be singular where the constraints
make that matrix regular, as for point masses in absolute coordinates).
L_q = Q + (d(M v)/dq) v is read from the mechanical form's ``dynamics`` (its dr/dq at
a = v minus at a = 0 is d(M v)/dq), so every force in Q enters as the
midpoint discrete Lagrange-d'Alembert force: conservative systems are integrated
symplectically (energy error bounded over long runs, no drift; momentum maps kept),
others at second order. Newton uses the iteration matrix without the second derivatives of
the kinetic energy (an O(h) relative error: linear convergence, rate O(h)); its residual and
matrix are one CasADi function of the form's (:func:`fused_pieces`), compiled with them.

Unlike ``rattle`` it accepts a configuration-dependent M(q) (joint coordinates), and
forces depending on v. It needs q' = v (H = identity, nq = nv, no offset f) and holonomic
constraints only. Fixed step: option ``step`` (s), by default taken from rtol by the rule
of :func:`workbench.plugin.integrator.step_for_tolerance` for order 2 (at most the smallest
output interval), each output interval divided into equal steps; the row's
``fixed_step_s`` records the longest step taken. Trajectories carry
[q, v, lambda] with the multipliers of [M W^T; W 0] at each output state.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations import Equations
from workbench.equations.evaluate import FastFunction
from workbench.equations.initial import accelerations
from workbench.errors import ConfigError, IntegrationError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator
from workbench.plugins.integrators.generalized_alpha import (
    default_step,
    is_identity_kinematics,
    step_warning,
)


@dataclass(frozen=True)
class VariationalOptions:
    step: float | None = with_unit(None, "s")  # None: from rtol (step_for_tolerance, order 2)
    newton_tol: float = 1e-13  # on the position increment, relative to 1 + |q|
    max_newton: int = 30

    def __post_init__(self) -> None:
        if self.step is not None and not (self.step > 0 and math.isfinite(self.step)):
            raise ConfigError(f"step must be a positive number of seconds, not {self.step}")
        if not self.newton_tol > 0 or self.max_newton < 1:
            raise ConfigError("newton_tol must be > 0 and max_newton >= 1")


@dataclass
class _Fused:
    """A step's pieces as one CasADi call each (a Newton iteration was four calls of the
    form's functions and NumPy algebra around them: a step cost 2.5x as much):

    ``newton(t, h, q0, q1, p0, lam) -> (residual, matrix, p1, finite)``: Newton's residual
    and iteration matrix at the guess q1 (with the constraint rows when there are
    constraints), the momentum p1 it gives (``h/2 L_q + M v_m``), and the sum of L_q and
    of the dynamics' residual at a = v_m, finite if they are;
    ``velocity(t, h, q, p) -> (matrix, rhs, G)``: [M, h/2 G^T; G, 0] and [p; -w] at (t, q),
    and G."""

    newton: FastFunction
    velocity: FastFunction


_FUSED: dict[int, tuple[weakref.ref, _Fused]] = {}  # id(form) -> (the form, its pieces)


def _compiler_of(function: Any) -> Any:
    """The :class:`~workbench.equations.compiled.Compiler` a form's function runs under."""
    return getattr(getattr(function, "fast", function), "compiler", None)


def _expanded(function: ca.Function) -> ca.Function:
    """``function`` as one SX graph where its parts allow (the VM runs it several times
    faster than an MX graph of calls), else as it is (a form of MX functions, e.g. with a
    linear solve inside)."""
    try:
        return function.expand()
    except RuntimeError:
        return function


def fused_pieces(mech: Any, n: int, nc: int) -> _Fused:
    """:class:`_Fused` of the mechanical form ``mech``, built once per form (and compiled
    as the form's own functions are: its ``compile`` option)."""
    cached = _FUSED.get(id(mech))
    if cached is not None and cached[0]() is mech:
        return cached[1]
    t, h = ca.MX.sym("t"), ca.MX.sym("h")
    q0, q1, p0 = ca.MX.sym("q0", n), ca.MX.sym("q1", n), ca.MX.sym("p0", n)
    lam = ca.MX.sym("lam", nc)
    dynamics = mech.dynamics.function
    q_m, v_m, no_lam = 0.5 * (q0 + q1), (q1 - q0) / h, ca.MX.zeros(nc)
    r1, j1, _, mass, _ = dynamics(t + 0.5 * h, q_m, v_m, v_m, no_lam)
    r0, j0, _, _, _ = dynamics(t + 0.5 * h, q_m, v_m, ca.MX.zeros(n), no_lam)
    dmv_dq = j1 - j0  # d(M v)/dq
    l_q = -r0 + ca.mtimes(dmv_dq, v_m)
    residual = p0 + 0.5 * h * l_q - ca.mtimes(mass, v_m)
    # dL_q/dv = (d(M v)/dq)^T for the Lagrangian part; d2T/dq2 is O(h) and left out
    matrix = -0.25 * h * j0 + 0.5 * (dmv_dq.T - dmv_dq) - mass / h
    if nc:
        g0 = mech.position_jacobian.function(t, q0)
        g1 = mech.position_jacobian.function(t + h, q1)
        residual = ca.vertcat(
            residual - 0.5 * h * ca.mtimes(g0.T, lam),
            mech.position_constraints.function(t + h, q1),
        )
        matrix = ca.blockcat([[matrix, -0.5 * h * g0.T], [g1, ca.MX.zeros(nc, nc)]])
    p1 = 0.5 * h * l_q + ca.mtimes(mass, v_m)
    newton = ca.Function(
        "variational_newton", [t, h, q0, q1, p0, lam],
        [ca.densify(x) for x in (residual, matrix, p1, ca.sum1(l_q) + ca.sum1(r1))],
    )  # fmt: skip
    q, p = ca.MX.sym("q", n), ca.MX.sym("p", n)
    mass_q = mech.mass.function(t, q)
    if nc:
        g = mech.position_jacobian.function(t, q)
        w = mech.velocity_constraints.function(t, q, ca.MX.zeros(n))
        kkt = ca.blockcat([[mass_q, 0.5 * h * g.T], [g, ca.MX.zeros(nc, nc)]])
        rhs = ca.vertcat(p, -w)
    else:
        g, kkt, rhs = ca.MX.zeros(0, n), mass_q, p
    velocity = ca.Function(
        "variational_velocity", [t, h, q, p], [ca.densify(kkt), ca.densify(rhs), ca.densify(g)]
    )
    compiler = _compiler_of(mech.dynamics)
    fused = _Fused(*(FastFunction(_expanded(f), compiler) for f in (newton, velocity)))
    _FUSED[id(mech)] = (weakref.ref(mech), fused)
    weakref.finalize(mech, _FUSED.pop, id(mech), None)
    return fused


@integrator
class VariationalMidpoint(Integrator):
    name = "variational-midpoint"
    summary = "Midpoint variational integrator (Marsden-West): M(q), q' = v, holonomic"
    Options = VariationalOptions
    accepts = {"mechanical": 3}

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        mech = equations.forms.get("mechanical")
        if mech is None:
            return "needs the mechanical form"
        if mech.n_constraints > mech.n_holonomic:
            return "nonholonomic constraints are not handled (the method is for holonomic ones)"
        rng = np.random.default_rng(12345)
        q = rng.uniform(-1.0, 1.0, equations.nq)
        if not is_identity_kinematics(mech, 0.0, q, equations.nv):
            return "needs q' = v (H = identity, no offset f); use generalized-alpha for H(q)"
        return None

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        eq, mech, times = task.equations, task.form, task.times
        self.mech, self.options, self.stats = mech, task.options, trajectory.stats
        self.n, self.nc = eq.nq, mech.n_constraints
        self.fused = fused_pieces(mech, self.n, self.nc)
        self.stats.n_lu, self.stats.n_newton = 0, 0
        t = float(times[0])
        q, v = task.y0[: self.n].copy(), task.y0[self.n : 2 * self.n].copy()
        _, lam, _ = accelerations(eq, t, q, v)
        p = self._mass(t, q) @ v
        self._last_velocity = v
        rows, reached = [np.concatenate([q, v, lam])], [t]
        step = default_step(times, task.options.step, task.rtol)
        self.stats.fixed_step = step
        trajectory.warnings.extend(filter(None, [step_warning(times, task.options.step,
                                                              task.rtol)]))  # fmt: skip
        lam_position = np.zeros(self.nc)
        longest = 0.0
        try:
            for t_out in times[1:]:
                n_steps = max(1, math.ceil((t_out - t) / step - 1e-9))
                h = (t_out - t) / n_steps
                longest = max(longest, h)  # the step taken, not the one asked
                self.stats.fixed_step = longest
                t_start = t
                for k in range(n_steps):
                    q, p, v, lam_position = self._step(t_start + k * h, h, q, p, lam_position)
                    self.stats.n_steps += 1
                t = float(t_out)
                _, lam_out, _ = accelerations(eq, t, q, v)
                rows.append(np.concatenate([q, v, lam_out]))
                reached.append(t)
        finally:  # keep what was reached, also when a step fails
            trajectory.y = np.array(rows)
            trajectory.times = np.array(reached)

    # ---- pieces -------------------------------------------------------------------------
    def _mass(self, t: float, q: np.ndarray) -> np.ndarray:
        (mass,) = self.mech.mass(t, q)
        return np.reshape(mass, (self.n, self.n))

    def _velocity(self, t: float, q: np.ndarray, p: np.ndarray, h: float):
        """(v, mu, G) with M v = p - h/2 G^T mu and G v + w = 0 at (t, q): one solve of
        [M, h/2 G^T; G, 0], regular also for a singular M that the constraints complete."""
        matrix, rhs, g = self.fused.velocity(t, h, q, p)
        self.stats.n_lu += 1
        try:
            solution = np.linalg.solve(matrix.reshape(len(rhs), -1), rhs)
        except np.linalg.LinAlgError:
            if not self.nc:
                raise IntegrationError(
                    f"{self.name}: the mass matrix is singular at t = {t:.6g} (p = M v has no "
                    "unique v); use a formalism whose coordinates all carry inertia"
                ) from None
            raise IntegrationError(
                f"{self.name}: [M, G^T; G, 0] is singular at t = {t:.6g}: the mass matrix is "
                "singular on the constraints' tangent space, or the constraints are redundant"
            ) from None
        return solution[: self.n], solution[self.n :], g

    def _step(
        self, t: float, h: float, q0: np.ndarray, p0: np.ndarray, lam: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(q1, p1, v1, lambda) one step on from (t, q0, p0); lam: the last position
        multipliers (a guess)."""
        n, options, newton = self.n, self.options, self.fused.newton
        t_new = t + h
        # predictor: the last step's midpoint velocity (an O(h^2) guess), at first v0
        q1 = q0 + h * self._last_velocity
        scale = 1.0 + np.max(np.abs(q0))
        increment = math.inf
        for iteration in range(options.max_newton + 1):
            residual, matrix, p1, finite = newton(t, h, q0, q1, p0, lam)
            self.stats.n_rhs += 2  # the dynamics at a = v_m and at a = 0
            if not math.isfinite(finite[0]):
                raise IntegrationError(
                    f"{self.name}: the equations became NaN or infinite at t = {t + h / 2:.6g}"
                )
            if increment <= options.newton_tol * scale:
                break  # converged: these terms, at the accepted q1, give p1
            if iteration == options.max_newton:
                raise IntegrationError(
                    f"{self.name}: Newton did not converge at t = {t_new:.6g} with step "
                    f"{h:.3g} s (last increment {increment:.3g}); reduce the step"
                )
            try:  # (a 1 x 1 matrix comes as a vector: FastFunction's column outputs)
                delta = np.linalg.solve(matrix.reshape(len(residual), -1), -residual)
            except np.linalg.LinAlgError as error:
                raise IntegrationError(
                    f"{self.name}: singular iteration matrix at t = {t_new:.6g}: {error}"
                ) from None
            self.stats.n_lu += 1
            self.stats.n_newton += 1
            q1 = q1 + delta[:n]
            lam = lam + delta[n:]
            increment = float(np.max(np.abs(delta[:n]), initial=0.0))
            if not math.isfinite(increment):
                raise IntegrationError(f"{self.name}: the positions became NaN at t = {t_new:.6g}")
        self._last_velocity = (q1 - q0) / h
        v1, mu, g1 = self._velocity(t_new, q1, p1, h)  # velocity multipliers mu: G v1 + w = 0
        if self.nc:
            p1 = p1 - 0.5 * h * g1.reshape(self.nc, self.n).T @ mu
        return q1, p1, v1, lam
