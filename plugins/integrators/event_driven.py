"""Event-driven integration of unilateral contacts with Coulomb friction (Pfeiffer &
Glocker 1996; Leine & Glocker 2003): smooth phases between events, integrated by SciPy's
``solve_ivp`` (DOP853), with root-finding on the switching functions, and Newton's impact
law at each impact.

In a smooth phase every contact has a mode: open, closed and sliding, or closed and
sticking. Closed contacts keep U_N' = 0 (and U_T' = 0 when sticking) through contact
forces solved with the accelerations (least squares: redundant corners share them);
a sliding contact's friction is -mu lambda_N along its sliding velocity. The phase ends
where an open gap reaches zero (an impact: :func:`_contact.velocity_problem` with the
restitution), a normal force falls to zero (lift-off), a sliding velocity reaches zero
(slip to stick, if mu lambda_N holds it) or a sticking force reaches the cone (stick to
slip). The modes are then chosen again and the method restarts. Planar models only (one
tangent: the sliding direction is a sign).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.integrate import solve_ivp

from workbench.equations import Equations
from workbench.errors import ConfigError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.registry import integrator
from workbench.plugins.integrators._contact import contact_state, refuse, velocity_problem

OPEN, SLIP, STICK = 0, 1, 2


@dataclass(frozen=True)
class EventDrivenOptions:
    max_events: int = 1000  # events before the run stops (an accumulation of impacts)
    rest_speed: float = 1e-6  # m/s; a contact leaving an impact slower than this stays closed

    def __post_init__(self) -> None:
        if self.max_events < 1:
            raise ConfigError(f"max_events must be >= 1, not {self.max_events}")
        if not self.rest_speed > 0:
            raise ConfigError(f"rest_speed must be > 0 m/s, not {self.rest_speed}")


@integrator
class EventDriven(Integrator):
    name = "event-driven"
    summary = "Event-driven: DOP853 between contact events, Newton's impact law, stick/slip"
    Options = EventDrivenOptions
    accepts: ClassVar[dict[str, int]] = {"mechanical": 0}
    contacts: ClassVar[bool] = True

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        if equations.contacts is not None and equations.contacts.n_tangent != 1:
            return "stick/slip events of spatial contacts (two tangents) are not written yet"
        return refuse(equations)

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        phases = _Phases(task)
        phases.run(trajectory)


class _Phases:
    def __init__(self, task: IntegrationTask) -> None:
        self.task, self.equations = task, task.equations
        self.mech, self.contacts = task.form, task.equations.contacts
        self.nq, self.nv = task.equations.nq, task.equations.nv
        self.n = self.contacts.n_contacts
        self.scale = 1.0  # a length for gap tolerances
        self.events: list[float] = []
        self.penetration = 0.0
        self.residual = 0.0

    # -- the smooth phase in given modes --------------------------------------------
    def accelerations(self, t: float, y: np.ndarray, modes: np.ndarray, signs: np.ndarray):
        """(v', lambda_N (n), lambda_T (n)) in ``modes``; sliding friction along -signs."""
        q, v = y[: self.nq], y[self.nq :]
        state = contact_state(self.equations, t, q, v)
        closed = np.flatnonzero(modes != OPEN)
        stick = np.flatnonzero(modes == STICK)
        mu = self.contacts.friction
        w_n_bias = self.contacts.normal_bias(t, q, v)[0].reshape(-1)
        w_t_bias = self.contacts.tangent_bias(t, q, v)[0].reshape(-1)
        force_dirs = [state.w_n[i] - mu[i] * signs[i] * state.w_t[i] * (modes[i] == SLIP)
                      for i in closed] + [state.w_t[i] for i in stick]  # fmt: skip
        rows = [state.w_n[i] for i in closed] + [state.w_t[i] for i in stick]
        bias = [w_n_bias[i] for i in closed] + [w_t_bias[i] for i in stick]
        k = len(rows)
        lam_n, lam_t = np.zeros(self.n), np.zeros(self.n)
        if k == 0:
            return np.linalg.solve(state.mass, state.forces), lam_n, lam_t
        f = np.array(force_dirs).T
        kkt = np.block([[state.mass, -f], [np.array(rows), np.zeros((k, k))]])
        rhs = np.concatenate([state.forces, -np.array(bias)])
        solution = np.linalg.lstsq(kkt, rhs, rcond=1e-12)[0]
        a, lam = solution[: self.nv], solution[self.nv :]
        lam_n[closed] = lam[: closed.size]
        lam_t[stick] = lam[closed.size :]
        slip = closed[modes[closed] == SLIP]
        lam_t[slip] = -mu[slip] * signs[slip] * lam_n[slip]
        return a, lam_n, lam_t

    def choose_modes(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Modes after an event: closed where the gap is ~0 and not opening; stick where not
        sliding and the cone holds the sticking force; lift-off where lambda_N < 0."""
        q, v = y[: self.nq], y[self.nq :]
        state = contact_state(self.equations, t, q, v)
        u_n, u_t = state.w_n @ v, state.w_t @ v
        tol = self.task.options.rest_speed
        gap_tol = max(1e-9, 10 * self.task.atol) * self.scale
        modes = np.where((state.gaps <= gap_tol) & (u_n <= tol), STICK, OPEN)
        modes[(modes == STICK) & (np.abs(u_t) > tol)] = SLIP
        signs = np.sign(u_t)
        mu = self.contacts.friction
        for _ in range(4 * self.n + 2):
            _, lam_n, lam_t = self.accelerations(t, y, modes, signs)
            lifted = (modes != OPEN) & (lam_n < 0)
            slipping = (modes == STICK) & (np.abs(lam_t) > mu * lam_n * (1 + 1e-9))
            if not lifted.any() and not slipping.any():
                break
            modes[lifted] = OPEN
            signs[slipping] = -np.sign(lam_t[slipping])
            modes[slipping] = SLIP
        return modes, signs

    def switching_functions(self, modes: np.ndarray, signs: np.ndarray) -> list:
        def make(i: int, kind: str) -> Any:
            def event(t: float, y: np.ndarray) -> float:
                q, v = y[: self.nq], y[self.nq :]
                if kind == "gap":
                    return float(self.contacts.gaps(t, q)[0].reshape(-1)[i])
                if kind == "slide":
                    return float(signs[i] * (self.contacts.tangent_jacobian(t, q)[0]
                                             .reshape(self.n, -1)[i] @ v))  # fmt: skip
                _, lam_n, lam_t = self.accelerations(t, y, modes, signs)
                if kind == "normal":
                    return float(lam_n[i])
                return float(self.contacts.friction[i] * lam_n[i] - abs(lam_t[i]))

            event.terminal, event.direction = True, -1
            return event

        kinds = {OPEN: ["gap"], SLIP: ["normal", "slide"], STICK: ["normal", "cone"]}
        return [make(i, kind) for i in range(self.n) for kind in kinds[int(modes[i])]]

    # -- the run ---------------------------------------------------------------------
    def run(self, trajectory: Trajectory) -> None:
        task = self.task
        times, t_end = task.times, float(task.times[-1])
        t, y = float(times[0]), task.y0[: self.nq + self.nv].copy()
        out_t, out_y, steps = [times[0]], [y.copy()], 0
        for _ in range(task.options.max_events + 1):
            modes, signs = self.choose_modes(t, y)
            rhs = self.right_hand_side(modes, signs)
            wanted = times[(times > t) & (times <= t_end)]
            solution = solve_ivp(
                rhs, (t, t_end), y, method="DOP853", t_eval=wanted, rtol=task.rtol,
                atol=task.atol, events=self.switching_functions(modes, signs),
            )  # fmt: skip
            # a phase ended by an event before its first output time: SciPy gives lists
            phase_t = np.asarray(solution.t, dtype=float)
            phase_y = np.asarray(solution.y, dtype=float).reshape(y.size, phase_t.size)
            steps += phase_t.size
            for s, z in zip(phase_t, phase_y.T, strict=True):
                out_t.append(s)
                out_y.append(z)
                gaps = self.contacts.gaps(s, z[: self.nq])[0].reshape(-1)
                self.penetration = max(self.penetration, float(np.max(-gaps, initial=0.0)))
            if solution.status != 1:  # the end, or a failure
                if solution.status < 0:
                    trajectory.success = False
                    trajectory.message = f"{self.name_of()}: {solution.message}"
                break
            t_event = min(te[0] for te in solution.t_events if te.size)
            y = next(ye[0] for te, ye in zip(solution.t_events, solution.y_events, strict=True)
                     if te.size and te[0] == t_event)  # fmt: skip
            t = float(t_event)
            y = self.impact(t, y)
        else:
            trajectory.success = False
            trajectory.message = (
                f"event-driven: more than {task.options.max_events} events by t = {t:.6g} s "
                "(impacts accumulating?); raise max_events or use moreau-jean"
            )
        trajectory.times = np.asarray(out_t, dtype=float)
        trajectory.y = np.asarray(out_y, dtype=float)
        trajectory.stats.n_steps = -1
        trajectory.stats.n_rejected = -1
        trajectory.contact = {
            "event_times": self.events,
            "penetration_max": self.penetration,
            "complementarity_max": self.residual,
        }

    def right_hand_side(self, modes: np.ndarray, signs: np.ndarray) -> Any:
        """y' = [q', v'] of the smooth phase in ``modes``."""

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            qdot = self.mech.qdot(t, y[: self.nq], y[self.nq :])[0].reshape(-1)
            return np.concatenate([qdot, self.accelerations(t, y, modes, signs)[0]])

        return rhs

    def name_of(self) -> str:
        return "event-driven"

    def impact(self, t: float, y: np.ndarray) -> np.ndarray:
        """Newton's impact law at the contacts touching at t (a no-op for a stick/slip or
        lift-off switch, whose contacts do not approach); every switch is an event."""
        q, v = y[: self.nq], y[self.nq :]
        state = contact_state(self.equations, t, q, v)
        gap_tol = max(1e-9, 10 * self.task.atol) * self.scale
        approaching = (state.gaps <= gap_tol) & (state.w_n @ v < -self.task.options.rest_speed)
        self.events.append(t)
        if not approaching.any():
            return y
        touching = state.gaps <= gap_tol
        solved = velocity_problem(self.equations, state, v, v, touching)
        self.residual = max(self.residual, solved.residual)
        return np.concatenate([q, solved.velocity])
