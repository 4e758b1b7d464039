"""Integrator ``rattle``: symplectic RATTLE for holonomically constrained mechanical systems.

H. C. Andersen, "Rattle: a velocity version of the Shake algorithm", J. Comput. Phys. 52
(1983); B. Leimkuhler, S. Reich, *Simulating Hamiltonian Dynamics* (2004), ch. 7. For

    M v' = Q(t, q) - G(t, q)^T lambda,   g(t, q) = 0,   q' = v,   M constant,

one step of size h is

    v_{1/2} = v_n + h/2 M^-1 (Q(t_n, q_n) - G(q_n)^T lambda_n)
    q_{n+1} = q_n + h v_{1/2},                 g(t_{n+1}, q_{n+1}) = 0     (solve lambda_n)
    v_{n+1} = v_{1/2} + h/2 M^-1 (Q(t_{n+1}, q_{n+1}) - G(q_{n+1})^T mu_n)
    G(q_{n+1}) v_{n+1} + w(t_{n+1}, q_{n+1}) = 0                           (solve mu_n)

lambda_n by Newton's method on g (matrix -h^2/2 G(q_{n+1}) M^-1 G(q_n)^T, rebuilt every
iteration), mu_n by one linear solve. Without constraints it is the Stormer-Verlet
(velocity Verlet) method. It is second order, symmetric and, for conservative forces,
symplectic on the constraint manifold: the energy error stays bounded over long times
instead of drifting.

Applicability (``incompatibility``): the mechanical form with a constant, nonsingular mass
matrix (checked at two random q), q' = v (H = identity, nq = nv), no nonholonomic rows and
forces independent of v (damping or gyroscopic terms would make the second half kick
implicit and destroy symplecticity). Time-dependent forces Q(t, q) and rheonomic
constraints g(t, q) are accepted: the scheme stays explicit and second order (and
symplectic for the non-autonomous Hamiltonian), only the energy is then not conserved.
Point-mass pendulums in joint angles (M = m l^2) and planar rigid bodies in absolute
coordinates (M = diag(m, m, I)) qualify; a mass matrix depending on q (most joint-
coordinate formalisms) and absolute point-mass models whose rotation has zero inertia do
not.

Fixed step: option ``step`` (s), by default the step an order-2 method needs at rtol
(:func:`workbench.plugin.integrator.step_for_tolerance`: 1e-3 s at rtol 1e-6); each
output interval is divided into equal steps; the row's ``fixed_step_s`` records the
longest step taken (shorter than the one asked where it does not divide an interval).
Trajectories carry [q, v, lambda] with the multipliers of [M W^T; W 0] at each output state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from workbench.equations import Equations
from workbench.equations.initial import accelerations
from workbench.errors import ConfigError, IntegrationError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    Trajectory,
    step_for_tolerance,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator

ORDER = 2  # RATTLE is second order in positions and velocities (Hairer et al. VII.1)


@dataclass(frozen=True)
class RattleOptions:
    step: float | None = with_unit(None, "s")  # None: from rtol (step_for_tolerance, order 2)
    newton_tol: float = 1e-13  # on the position constraint residual, relative to 1 + |q|
    max_newton: int = 20

    def __post_init__(self) -> None:
        if self.step is not None and not (self.step > 0 and math.isfinite(self.step)):
            raise ConfigError(f"step must be a positive number of seconds, not {self.step}")
        if not self.newton_tol > 0 or self.max_newton < 1:
            raise ConfigError("newton_tol must be > 0 and max_newton >= 1")


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    scale = max(1.0, float(np.max(np.abs(a), initial=0.0)), float(np.max(np.abs(b), initial=0.0)))
    return bool(np.all(np.isfinite(a)) and np.allclose(a, b, rtol=0.0, atol=1e-11 * scale))


@integrator
class Rattle(Integrator):
    name = "rattle"
    summary = "Symplectic RATTLE / Stormer-Verlet: constant M, q' = v, holonomic, conservative"
    Options = RattleOptions
    accepts = {"mechanical": 3}

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        mech = equations.forms.get("mechanical")
        if mech is None:
            return "needs the mechanical form"
        nq, nv = equations.nq, equations.nv
        if nq != nv:
            return f"needs q' = v, but nq = {nq} != nv = {nv} (q' = H(q) v)"
        if mech.n_constraints > mech.n_holonomic:
            return "nonholonomic constraints are not handled (RATTLE is for holonomic ones)"
        rng = np.random.default_rng(12345)
        q1, q2 = rng.uniform(-1.0, 1.0, nq), rng.uniform(-1.0, 1.0, nq)
        v1, v2 = rng.uniform(-1.0, 1.0, nv), rng.uniform(-1.0, 1.0, nv)
        for q in (q1, q2):
            (h_matrix,) = mech.kinematics(0.0, q)
            if not _close(np.reshape(h_matrix, (nq, nv)), np.eye(nv)):
                return "needs q' = v, but the kinematics matrix H(q) is not the identity"
            for t in (0.0, 1.0):
                (offset,) = mech.kinematics_offset(t, q)
                if not _close(np.ravel(offset), np.zeros(nq)):
                    return "needs q' = v, but q' has a part f(t, q) that does not move with v"
        (m1,) = mech.mass(0.0, q1)
        (m2,) = mech.mass(0.0, q2)
        if not _close(np.atleast_2d(m1), np.atleast_2d(m2)):
            return "needs a constant mass matrix, but M depends on q"
        if nv and np.linalg.cond(np.atleast_2d(m1)) > 1e12:
            return "needs a nonsingular mass matrix (M is singular, e.g. a point mass's spin)"
        (f1,) = mech.forces(0.0, q1, v1)
        (f2,) = mech.forces(0.0, q1, v2)
        if not _close(f1, f2):
            return "needs forces independent of v (damping, gyroscopic or applied forces in v)"
        return None

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        eq, mech, times = task.equations, task.form, task.times
        self.mech, self.options, self.stats = mech, task.options, trajectory.stats
        self.nq, self.nv, self.nc = eq.nq, eq.nv, mech.n_constraints
        t = float(times[0])
        q, v = task.y0[: self.nq].copy(), task.y0[self.nq : self.nq + self.nv].copy()
        (mass,) = mech.mass(t, q)
        self.inverse_mass = np.linalg.inv(np.atleast_2d(mass))  # constant: inverted once
        self.stats.n_lu, self.stats.n_newton = 1, 0
        _, lam, _ = accelerations(eq, t, q, v)
        rows, reached = [np.concatenate([q, v, lam])], [t]
        step = task.options.step
        step = float(step) if step is not None else step_for_tolerance(task.rtol, ORDER)
        self.stats.fixed_step = step
        self.force = self._forces(t, q)
        self.g_q = self._jacobian(t, q)
        longest = 0.0
        try:
            for t_out in times[1:]:
                n_steps = max(1, math.ceil((t_out - t) / step - 1e-9))
                h = (t_out - t) / n_steps
                longest = max(longest, h)  # the step taken, not the one asked
                self.stats.fixed_step = longest
                t_start = t
                for k in range(n_steps):
                    q, v, lam = self._step(t_start + k * h, h, q, v, lam)
                    self.stats.n_steps += 1
                t = float(t_out)
                _, lam_out, _ = accelerations(eq, t, q, v)
                rows.append(np.concatenate([q, v, lam_out]))
                reached.append(t)
        finally:  # keep what was reached, also when a step fails
            trajectory.y = np.array(rows)
            trajectory.times = np.array(reached)

    def _forces(self, t: float, q: np.ndarray) -> np.ndarray:
        (force,) = self.mech.forces(t, q, np.zeros(self.nv))
        if not np.all(np.isfinite(force)):
            raise IntegrationError(f"rattle: the forces became NaN or infinite at t = {t:.6g}")
        return force

    def _jacobian(self, t: float, q: np.ndarray) -> np.ndarray:
        if not self.nc:
            return np.zeros((0, self.nq))
        (g_q,) = self.mech.position_jacobian(t, q)
        return np.reshape(g_q, (self.nc, self.nq))

    def _step(
        self, t: float, h: float, q: np.ndarray, v: np.ndarray, lam: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One RATTLE step from t to t + h; lam: the previous position multipliers (guess)."""
        t_new = t + h
        kick = v + 0.5 * h * self.inverse_mass @ self.force
        if self.nc:
            m_inv_gt = self.inverse_mass @ self.g_q.T
            lam = self._position_multipliers(t_new, h, q, kick, m_inv_gt, lam)
            kick = kick - 0.5 * h * m_inv_gt @ lam
        q = q + h * kick
        self.force = self._forces(t_new, q)
        v = kick + 0.5 * h * self.inverse_mass @ self.force
        if self.nc:
            # velocity multipliers: W (v - h/2 M^-1 W^T mu) + w = 0, linear in mu
            self.g_q = self._jacobian(t_new, q)
            (residual,) = self.mech.velocity_constraints(t_new, q, v)
            m_inv_gt = self.inverse_mass @ self.g_q.T
            mu = np.linalg.solve(0.5 * h * self.g_q @ m_inv_gt, residual)
            self.stats.n_lu += 1
            v = v - 0.5 * h * m_inv_gt @ mu
        return q, v, lam

    def _position_multipliers(
        self,
        t_new: float,
        h: float,
        q: np.ndarray,
        kick: np.ndarray,
        m_inv_gt: np.ndarray,
        lam: np.ndarray,
    ) -> np.ndarray:
        """Newton on g(t_new, q + h (kick - h/2 M^-1 G^T lam)) = 0 for lam."""
        options = self.options
        scale = 1.0 + np.max(np.abs(q))
        for iteration in range(options.max_newton + 1):
            q_new = q + h * (kick - 0.5 * h * m_inv_gt @ lam)
            (g,) = self.mech.position_constraints(t_new, q_new)
            if not np.all(np.isfinite(g)):
                raise IntegrationError(f"rattle: the constraints became NaN at t = {t_new:.6g}")
            if np.max(np.abs(g)) <= options.newton_tol * scale:
                return lam
            if iteration == options.max_newton:
                break
            matrix = -0.5 * h * h * self._jacobian(t_new, q_new) @ m_inv_gt
            lam = lam + np.linalg.solve(matrix, -g)
            self.stats.n_lu += 1
            self.stats.n_newton += 1
        raise IntegrationError(
            f"rattle: the position constraints could not be solved at t = {t_new:.6g} "
            f"(residual {np.max(np.abs(g)):.3g}); reduce the step"
        )
