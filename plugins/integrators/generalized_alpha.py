"""Integrator ``generalized-alpha``: Arnold & Bruls (2007) on the index-3 mechanical form.

M. Arnold, O. Bruls, "Convergence of the generalized-alpha scheme for constrained
mechanical systems", Multibody Syst. Dyn. 18 (2007) 185-202. For

    M(q) v' = Q(t, q, v) - W(q)^T lambda,   g(t, q) = 0,   q' = H(t, q) v + f(t, q)

one step from (q_n, v_n, v'_n, a_n) to t_{n+1} = t_n + h solves for the true
acceleration v'_{n+1} and the multipliers lambda_{n+1}:

    (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) v'_{n+1} + alpha_f v'_n
    q_{n+1} = q_n + h H_mid (v_n + h (1/2 - beta) a_n + h beta a_{n+1}) + h f_mid
    v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1}
    M(q_{n+1}) v'_{n+1} - Q(t_{n+1}, q_{n+1}, v_{n+1}) + W^T lambda_{n+1} = 0
    g(t_{n+1}, q_{n+1}) / (beta h^2) = 0           (holonomic rows, index 3)
    (W v + w)(t_{n+1}, q_{n+1}, v_{n+1}) / (gamma h) = 0   (nonholonomic rows)

``a`` is the pseudo-acceleration (a_0 = v'_0, from [M W^T; W 0] at the initial state).
Chung-Hulbert parameters from the spectral radius at infinity rho = ``rho_inf``:
alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f - alpha_m,
beta = (gamma + 1/2)^2 / 4. Positions and velocities converge at order 2.

Newton's method on (v'_{n+1}, lambda_{n+1}) uses the exact iteration matrix built from
``MechanicalForm.dynamics`` (dr/dq, dr/dv, M, W^T) and the constraint Jacobian. With
c = (1 - alpha_f)/(1 - alpha_m):

    [ M + gamma h c dr/dv + beta h^2 c dr/dq H_mid    W^T ] [dv']   = -[ r       ]
    [ c G H_mid                                       0   ] [dlam]     [ g/(b h^2)]

The constraint rows are scaled by 1/(beta h^2) (Arnold-Bruls; Bottasso et al. 2007), so
the matrix stays O(1) as h -> 0 instead of having condition number O(h^-2). For the
nonholonomic rows the term dc/dq of the velocity constraint is left out of the matrix
(their rows are W c): Newton then converges linearly, not quadratically, on them.

Coordinates with q' = H v + f, H != identity (Euler parameters, nq != nv) or f != 0
(rheonomic coordinates: minimal velocities on a moving plane): the position update uses
H and f at the explicit midpoint q_mid = q_n + h/2 (H(t_n, q_n) v_n + f(t_n, q_n)), which
keeps the update second-order accurate and explicit in the unknowns. Unit-norm conditions of Euler
parameters are satisfied only if the formalism states them among g; the Lie-group variant
``lie-generalized-alpha`` (:mod:`.lie_generalized_alpha`) keeps them on the unit sphere by
overriding the position update (:meth:`GeneralizedAlpha._advance`, ``_position_tangent``).

Step size: option ``step`` (s) or, by default, the step the tolerance asks of an order-2
method (:func:`workbench.plugin.integrator.step_for_tolerance`: 1e-2 s at rtol 1e-4,
1e-3 s at 1e-6, 1e-4 s at 1e-8); each output interval is divided into equal steps so that
output times are hit exactly, and the row's ``fixed_step_s`` records the longest step taken
(after a halving, the halved step).
With ``adaptive=True`` the step is controlled by an estimate of the local position error:
the difference between the generalized-alpha position q_{n+1} and the second-order Taylor
predictor q_n + h H (v_n + h/2 v'_n), both O(h^3) accurate locally, so the difference is
an O(h^3) (conservative) measure of the local error; weighted by atol + rtol |q| (RMS),
a step is accepted when it is <= 1 and the next step is h * clip(0.9 err^(-1/3), 0.2, 4).
A Newton failure shrinks the step by 4 (adaptive); with a fixed step it takes the rest of
the output interval, from the last step that converged, with half the step (at most
HALVINGS times), keeps the shorter step and warns in the row: on Andrews' squeezer the
step rtol 1e-6 asks (1 ms) turns the fastest body by too much for Newton near t = 0.025 s
(issue 32: hht-alpha and lie-generalized-alpha failed there with every formalism; the
Arnold-Bruls scaling of the constraint rows is in place).
When rtol asks a step longer than the output interval, the interval is taken and the row
warns that the accuracy asked was not attempted (:func:`step_warning`).

Trajectories carry [q, v, lambda] (lambda of every velocity-level constraint row).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

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


@dataclass(frozen=True)
class StepOptions:
    """The options every member of the generalized-alpha family shares."""

    step: float | None = with_unit(None, "s")  # None: from rtol (step_for_tolerance, order 2)
    adaptive: bool = False
    newton_tol: float = 1e-10  # on the position increment, relative to 1 + |q|
    max_newton: int = 12

    def __post_init__(self) -> None:
        if self.step is not None and not (self.step > 0 and math.isfinite(self.step)):
            raise ConfigError(f"step must be a positive number of seconds, not {self.step}")
        if not self.newton_tol > 0 or self.max_newton < 1:
            raise ConfigError("newton_tol must be > 0 and max_newton >= 1")


@dataclass(frozen=True)
class GeneralizedAlphaOptions(StepOptions):
    rho_inf: float = 0.9  # spectral radius at infinity, in [0, 1]

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0.0 <= self.rho_inf <= 1.0:
            raise ConfigError(f"rho_inf must lie in [0, 1], not {self.rho_inf}")


def chung_hulbert(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, beta, gamma) of the generalized-alpha method for rho_inf."""
    alpha_m = (2 * rho_inf - 1) / (rho_inf + 1)
    alpha_f = rho_inf / (rho_inf + 1)
    gamma = 0.5 + alpha_f - alpha_m
    beta = 0.25 * (gamma + 0.5) ** 2
    return alpha_m, alpha_f, beta, gamma


ORDER = 2  # of positions and velocities (Arnold & Bruls 2007)


def default_step(times: np.ndarray, step: float | None, rtol: float) -> float:
    """The requested step, or the step of an order-2 method at ``rtol``
    (:func:`~workbench.plugin.integrator.step_for_tolerance`), at most the smallest output
    interval (the adaptive mode's first step)."""
    if step is not None:
        return float(step)
    return float(min(step_for_tolerance(rtol, ORDER), np.min(np.diff(times))))


def step_warning(times: np.ndarray, step: float | None, rtol: float) -> str:
    """The row's warning when rtol did not set the step: the step rtol asks
    (:func:`step_for_tolerance`) is longer than the output interval, so the interval was
    taken instead, the same step as at a tighter rtol ('' otherwise)."""
    interval = float(np.min(np.diff(times))) if len(times) > 1 else math.inf
    if step is not None or not step_for_tolerance(rtol, ORDER) > interval * (1 + 1e-9):
        return ""
    return (
        f"the accuracy asked was not attempted: rtol {rtol:g} asks a step of "
        f"{step_for_tolerance(rtol, ORDER):.3g} s, longer than the output interval "
        f"{interval:.3g} s, which was taken instead (as at a tighter rtol)"
    )


HALVINGS = 10  # a fixed step halved at most this often after Newton failures (1/1024)


def is_identity_kinematics(mech: Any, t: float, q: np.ndarray, nv: int) -> bool:
    """True if q' = v (H = identity, f = 0) at q and at a perturbed q and time."""
    if q.size != nv:
        return False
    rng = np.random.default_rng(1)
    for time, point in ((t, q), (t + 0.5, q + rng.uniform(-0.5, 0.5, q.size))):
        (h_matrix,) = mech.kinematics(time, point)
        (offset,) = mech.kinematics_offset(time, point)
        if not np.allclose(np.reshape(h_matrix, (q.size, nv)), np.eye(nv), rtol=0, atol=1e-14):
            return False
        if np.any(np.abs(np.ravel(offset)) > 1e-14):
            return False
    return True


class _State:
    """Everything the method carries from step to step."""

    def __init__(
        self, q: np.ndarray, v: np.ndarray, vdot: np.ndarray, a: np.ndarray, lam: np.ndarray
    ) -> None:
        self.q, self.v, self.vdot, self.a, self.lam = q, v, vdot, a, lam


@integrator
class GeneralizedAlpha(Integrator):
    name = "generalized-alpha"
    summary = "Generalized-alpha on the index-3 form, Chung-Hulbert rho_inf (Arnold-Bruls 2007)"
    Options = GeneralizedAlphaOptions
    accepts = {"mechanical": 3}

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        options = task.options
        mech = task.form
        eq = task.equations
        nq, nv, nc, m = eq.nq, eq.nv, mech.n_constraints, mech.n_holonomic
        times = task.times
        t = float(times[0])
        q, v = task.y0[:nq].copy(), task.y0[nq : nq + nv].copy()
        vdot, lam, _ = accelerations(eq, t, q, v)
        state = _State(q, v, vdot, vdot.copy(), lam)
        self._setup(options, mech, nq, nv, nc, m, is_identity_kinematics(mech, t, q, nv))
        stats = trajectory.stats
        stats.n_lu, stats.n_newton = 0, 0
        rows = [np.concatenate([q, v, lam])]
        reached = [t]
        h = default_step(times, options.step, task.rtol)
        if not options.adaptive:
            stats.fixed_step = h
            trajectory.warnings.extend(filter(None, [step_warning(times, options.step,
                                                                  task.rtol)]))  # fmt: skip
        halvings, taken = 0, 0.0
        h_min = 1e-14 * max(1.0, abs(times[-1]))
        try:
            for t_out in times[1:]:
                if options.adaptive:
                    while t < t_out:
                        h_try = min(h, t_out - t)
                        if t_out - t - h_try < 1e-12 * abs(t_out):
                            h_try = t_out - t
                        try:
                            new = self._step(state, t, h_try, stats)
                        except _NewtonFailure as failure:
                            stats.n_rejected += 1
                            h = h_try / 4
                            if h < h_min:
                                raise IntegrationError(str(failure)) from None
                            continue
                        error = self._error(state, new, t, h_try, task.rtol, task.atol)
                        factor = min(4.0, max(0.2, 0.9 * error ** (-1 / 3))) if error > 0 else 4.0
                        if error <= 1.0:
                            clipped = h_try < h
                            state = new
                            t = float(t_out) if h_try == t_out - t else t + h_try
                            stats.n_steps += 1
                            # a step shortened to hit an output time does not shrink the next one
                            h = max(h, h_try * factor) if clipped else h_try * factor
                        else:
                            stats.n_rejected += 1
                            h = h_try * factor
                            if h < h_min:
                                raise IntegrationError(
                                    f"{self.name}: step size {h:.3g} s underflow at t = {t:.6g}"
                                )
                else:
                    # Newton fails when a step is too long for the motion (Andrews'
                    # squeezer at 1 ms near t = 0.025 s): the rest of the interval, from the
                    # last step that converged, is taken with half the step, kept for the
                    # rest of the run and said in the row. (Redoing the whole interval made a
                    # blow-up's ten halvings cost 2 x the interval / the last step: 205,569
                    # steps and 48 s of CPU for y'' = y'^2.)
                    while True:
                        t_start = t
                        n_steps = max(1, math.ceil((t_out - t_start) / h - 1e-9))
                        h_interval = (t_out - t_start) / n_steps
                        if not halvings:  # the step taken (after one: the halved step)
                            taken = max(taken, h_interval)
                            stats.fixed_step = taken
                        try:
                            for k in range(n_steps):
                                state = self._step(state, t, h_interval, stats)
                                stats.n_steps += 1
                                t = t_start + (k + 1) * h_interval
                        except _NewtonFailure as failure:
                            stats.n_rejected += 1
                            halvings += 1
                            if halvings > HALVINGS:
                                raise IntegrationError(
                                    f"{failure} after {HALVINGS} halvings of the step: the "
                                    "trajectory had left the motion at the longer steps; set "
                                    "a shorter step or adaptive=True"
                                ) from None
                            h = h_interval / 2
                            stats.fixed_step = min(stats.fixed_step, h)
                            continue
                        break
                    if halvings and not any("halved" in w for w in trajectory.warnings):
                        trajectory.warnings.append(
                            f"step halved: Newton failed near t = {t_out:.6g} s at the step "
                            f"rtol asked (the motion is too fast for it; fixed_step_s is the "
                            "shortest step taken)"
                        )
                    t = float(t_out)
                rows.append(np.concatenate([state.q, state.v, state.lam]))
                reached.append(float(t_out))
        finally:  # keep what was reached, also when a step fails
            trajectory.y = np.array(rows)
            trajectory.times = np.array(reached)

    @staticmethod
    def parameters(options: Any) -> tuple[float, float, float, float]:
        """(alpha_m, alpha_f, beta, gamma) of this member of the family."""
        return chung_hulbert(options.rho_inf)

    # ---- one step -------------------------------------------------------------------
    def _setup(
        self, options: Any, mech: Any, nq: int, nv: int, nc: int, m: int, identity: bool
    ) -> None:
        self.alpha_m, self.alpha_f, self.beta, self.gamma = self.parameters(options)
        self.mech, self.nq, self.nv, self.nc, self.m = mech, nq, nv, nc, m
        self.identity = identity
        self.newton_tol, self.max_newton = options.newton_tol, options.max_newton

    def _mid_kinematics(
        self, t: float, h: float, q: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """H and f of q' = H v + f at the explicit midpoint (t + h/2, q_mid)."""
        if self.identity:
            return np.eye(self.nv), np.zeros(self.nq)
        mech = self.mech
        (h_n,) = mech.kinematics(t, q)
        (f_n,) = mech.kinematics_offset(t, q)
        q_mid = q + 0.5 * h * (np.reshape(h_n, (self.nq, self.nv)) @ v + np.ravel(f_n))
        (h_mid,) = mech.kinematics(t + h / 2, q_mid)
        (f_mid,) = mech.kinematics_offset(t + h / 2, q_mid)
        return np.reshape(h_mid, (self.nq, self.nv)), np.ravel(f_mid).copy()

    def _advance(
        self, q: np.ndarray, h: float, increment: np.ndarray, context: tuple[np.ndarray, ...]
    ) -> np.ndarray:
        """q_{n+1} from q_n and the velocity-space increment (v_n + h (1/2 - beta) a_n +
        h beta a_{n+1}): q_n + h (H_mid increment + f_mid); ``context`` = (H_mid, f_mid)."""
        h_mid, f_mid = context
        return q + h * (h_mid @ increment + f_mid)

    def _position_tangent(
        self, q: np.ndarray, h: float, increment: np.ndarray, context: tuple[np.ndarray, ...]
    ) -> np.ndarray:
        """d q_{n+1} / d increment divided by h (nq, nv): H_mid, for the iteration matrix."""
        return context[0]

    def _step(self, state: _State, t: float, h: float, stats: Any) -> _State:
        """One generalized-alpha step from t to t + h; _NewtonFailure if Newton fails."""
        mech, nv, nc, m = self.mech, self.nv, self.nc, self.m
        alpha_m, alpha_f, beta, gamma = self.alpha_m, self.alpha_f, self.beta, self.gamma
        c = (1 - alpha_f) / (1 - alpha_m)
        t_new = t + h
        context = self._mid_kinematics(t, h, state.q, state.v)
        vdot, lam = state.vdot.copy(), state.lam.copy()
        q_scale = 1.0 + np.max(np.abs(state.q), initial=0.0)
        last = math.inf
        for iteration in range(1, self.max_newton + 1):
            a = (alpha_f * state.vdot + (1 - alpha_f) * vdot - alpha_m * state.a) / (1 - alpha_m)
            increment = state.v + h * (0.5 - beta) * state.a + h * beta * a
            q = self._advance(state.q, h, increment, context)
            v = state.v + h * (1 - gamma) * state.a + h * gamma * a
            tangent = self._position_tangent(q, h, increment, context)
            r, r_q, r_v, mass, w_t = self.mech.dynamics(t_new, q, v, vdot, lam)
            r_q, r_v = np.reshape(r_q, (nv, self.nq)), np.reshape(r_v, (nv, nv))
            matrix = np.reshape(mass, (nv, nv)) + gamma * h * c * r_v
            matrix += beta * h * h * c * (r_q @ tangent)
            residual = np.ravel(r)
            if nc:
                w_t = np.reshape(w_t, (nv, nc))
                rows = np.zeros((nc, nv))
                constraint = np.zeros(nc)
                if m:
                    (g,) = mech.position_constraints(t_new, q)
                    (g_q,) = mech.position_jacobian(t_new, q)
                    constraint[:m] = np.ravel(g) / (beta * h * h)
                    rows[:m] = c * (np.reshape(g_q, (m, self.nq)) @ tangent)
                if nc > m:
                    (cv,) = mech.velocity_constraints(t_new, q, v)
                    constraint[m:] = np.ravel(cv)[m:] / (gamma * h)
                    rows[m:] = c * w_t.T[m:]
                matrix = np.block([[matrix, w_t], [rows, np.zeros((nc, nc))]])
                residual = np.concatenate([residual, constraint])
            if not np.all(np.isfinite(residual)) or not np.all(np.isfinite(matrix)):
                raise _NewtonFailure(
                    f"{self.name}: the equations became NaN or infinite at "
                    f"t = {t_new:.6g} (step {h:.3g} s, Newton iteration {iteration})"
                )
            try:
                lu = scipy.linalg.lu_factor(matrix, check_finite=False)
            except (ValueError, np.linalg.LinAlgError) as error:
                raise _NewtonFailure(
                    f"{self.name}: singular iteration matrix at t = {t_new:.6g}: {error}"
                ) from None
            stats.n_lu += 1
            stats.n_newton += 1
            delta = scipy.linalg.lu_solve(lu, -residual, check_finite=False)
            vdot += delta[:nv]
            lam += delta[nv:]
            change = beta * h * h * c * np.max(np.abs(delta[:nv]), initial=0.0)
            if not math.isfinite(change):
                break
            if change <= self.newton_tol * q_scale:
                a = (alpha_f * state.vdot + (1 - alpha_f) * vdot - alpha_m * state.a) / (
                    1 - alpha_m
                )
                increment = state.v + h * (0.5 - beta) * state.a + h * beta * a
                q = self._advance(state.q, h, increment, context)
                v = state.v + h * (1 - gamma) * state.a + h * gamma * a
                return _State(q, v, vdot, a, lam)
            if iteration > 3 and change > 2 * last:
                break  # diverging
            last = change
        raise _NewtonFailure(
            f"{self.name}: Newton did not converge at t = {t_new:.6g} with step {h:.3g} s "
            f"(last position increment {last:.3g}); reduce the step or use adaptive=True"
        )

    def _error(
        self, old: _State, new: _State, t: float, h: float, rtol: float, atol: float
    ) -> float:
        """RMS of (q_{n+1} - Taylor predictor) weighted by atol + rtol |q|."""
        context = self._mid_kinematics(t, h, old.q, old.v)
        predictor = self._advance(old.q, h, old.v + 0.5 * h * old.vdot, context)
        weight = atol + rtol * np.maximum(np.abs(old.q), np.abs(new.q))
        return float(np.sqrt(np.mean(((new.q - predictor) / weight) ** 2)))


class _NewtonFailure(Exception):
    pass
