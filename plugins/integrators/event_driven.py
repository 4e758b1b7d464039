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
slip). The modes are then chosen again and the method restarts.

A planar contact has one tangent (its slip direction is a sign); a spatial one two: the
friction -mu lambda_N d acts along the unit slip direction d = U_T / |U_T| (frozen at the
phase's start direction d_0 once U_T . d_0 <= 0, so that the force is continuous where a
straight slip stops), slip to stick is U_T . d_0 reaching zero, a slip that turns 60 degrees
from d_0 starts a new phase (a new d_0), and sticking holds while |lambda_T| <= mu lambda_N
(the friction disc); a contact that starts to slip does so against its sticking force.

Bilateral constraints beside the contacts (a closed loop; absolute coordinates with
joints) keep W_B v' = gamma in every phase: their forces are solved with the closed
contacts' forces and the accelerations in one KKT system; the impact map keeps
W_B v+ + w = 0 as equalities (:func:`_contact.velocity_problem`); at every event the state
is projected back onto g(q) = 0 and W_B v + w = 0 (:func:`_contact.project`), so the
drift of the index-1 phases does not build up from phase to phase.

Coulomb friction in a joint (:class:`~workbench.model.JointFriction`) is a contact that
never opens: sticking, its torque (or force) lambda_F keeps the joint rate's derivative
zero, solved with the rest, until |lambda_F| reaches the bound; sliding, it is -bound
times the sign of the rate, until the rate reaches zero; there it slips on the way its
rate then turns (U_F' = W_F v' + wdot_F under the friction that opposes it: a slider-crank's
dead centre turns its piston whatever the friction), else it sticks. Impacts take no
impulsive joint friction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.integrate import solve_ivp

from workbench.equations import Equations
from workbench.errors import ConfigError
from workbench.model import SphereContact
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator
from workbench.plugins.integrators._contact import (
    contact_state,
    project,
    refuse,
    velocity_problem,
)

OPEN, SLIP, STICK = 0, 1, 2


@dataclass(frozen=True)
class EventDrivenOptions:
    max_events: int = 1000  # events before the run stops (an accumulation of impacts)
    # a contact leaving an impact slower than this stays closed
    rest_speed: float = with_unit(1e-6, "m/s")

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
        self.nf = self.contacts.n_joint_frictions
        self.bound_f = self.contacts.joint_friction_bound
        self.scale = 1.0  # a length for gap tolerances
        self.events: list[float] = []
        self.penetration = 0.0
        self.residual = 0.0
        self.labels: list[tuple[int, str]] = []  # the current phase's switching functions

    # -- the smooth phase in given modes --------------------------------------------
    def accelerations(self, t: float, y: np.ndarray, modes: np.ndarray, signs: np.ndarray):
        """(v', lambda_N (n), lambda_T (n, n_tangent), lambda_F (nf)) in ``modes`` (n + nf:
        the contacts', then the joint frictions'); ``signs`` (n + nf, n_tangent): each
        contact's slip direction at the phase's start (a sign in a planar model), each
        joint's slip sign in column 0."""
        q, v = y[: self.nq], y[self.nq :]
        state = contact_state(self.equations, t, q, v)
        joint_modes, joint_signs = modes[self.n :], signs[self.n :, 0]
        modes, signs = modes[: self.n], signs[: self.n]
        joint_stick = np.flatnonzero(joint_modes == STICK)
        joint_slip = np.flatnonzero(joint_modes == SLIP)
        lam_f = np.zeros(self.nf)
        lam_f[joint_slip] = -self.bound_f[joint_slip] * joint_signs[joint_slip]
        forces = state.forces + state.w_f.T @ lam_f  # the sliding joints' friction
        joint_bias = (self.contacts.joint_rate_bias(t, q, v)[0].reshape(-1) if self.nf
                      else np.zeros(0))  # fmt: skip
        closed = np.flatnonzero(modes != OPEN)
        stick = np.flatnonzero(modes == STICK)
        mu, nt = self.contacts.friction, self.contacts.n_tangent
        w_n_bias = self.contacts.normal_bias(t, q, v)[0].reshape(-1)
        w_t_bias = self.contacts.tangent_bias(t, q, v)[0].reshape(-1)
        w_t = state.w_t.reshape(self.n, nt, self.nv)
        slip = self.slip_directions(w_t @ v, signs)
        force_dirs = [state.w_n[i] - mu[i] * (modes[i] == SLIP) * slip[i] @ w_t[i]
                      for i in closed] + [row for i in stick for row in w_t[i]]  # fmt: skip
        rows = [state.w_n[i] for i in closed] + [row for i in stick for row in w_t[i]]
        bias = [w_n_bias[i] for i in closed] + [w_t_bias[i * nt + k] for i in stick
                                                 for k in range(nt)]  # fmt: skip
        k_contacts = len(rows)
        force_dirs += [state.w_f[i] for i in joint_stick]
        rows += [state.w_f[i] for i in joint_stick]
        bias += [joint_bias[i] for i in joint_stick]
        k, nb = len(rows), state.w_b.shape[0]
        lam_n, lam_t = np.zeros(self.n), np.zeros((self.n, nt))
        if k + nb == 0:
            return np.linalg.solve(state.mass, forces), lam_n, lam_t, lam_f  # nb = 0 here
        # the contacts' forces f lam and the bilateral ones -W_B^T mu, with their rows
        f = np.hstack([np.array(force_dirs).reshape(k, self.nv).T, -state.w_b.T])
        rows = np.vstack([np.array(rows).reshape(k, self.nv), state.w_b])
        kkt = np.block([[state.mass, -f], [rows, np.zeros((k + nb, k + nb))]])
        rhs = np.concatenate([forces, -np.array(bias).reshape(k), state.gamma])
        solution = np.linalg.lstsq(kkt, rhs, rcond=1e-12)[0]
        a, lam = solution[: self.nv], solution[self.nv :]
        lam_n[closed] = lam[: closed.size]
        lam_t[stick] = lam[closed.size : k_contacts].reshape(-1, nt)
        lam_f[joint_stick] = lam[k_contacts:k]
        sliding = closed[modes[closed] == SLIP]
        lam_t[sliding] = -mu[sliding, None] * slip[sliding] * lam_n[sliding, None]
        return a, lam_n, lam_t, lam_f

    @staticmethod
    def slip_directions(u_t: np.ndarray, signs: np.ndarray) -> np.ndarray:
        """Each contact's unit slip direction: that of its sliding velocity ``u_t`` (n, nt)
        while it points ahead of the phase's start direction ``signs``, else ``signs``
        (so the friction stays continuous where a straight slip stops: its event)."""
        speed = np.linalg.norm(u_t, axis=1, keepdims=True)
        ahead = (np.sum(u_t * signs, axis=1, keepdims=True) > 0) & (speed > 0)
        return np.where(ahead, u_t / np.where(speed > 0, speed, 1.0), signs)

    def choose_modes(
        self, t: float, y: np.ndarray, fired: tuple[int, str] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Modes after an event: closed where the gap is ~0 and not opening; stick where not
        sliding and the cone holds the sticking force (the friction disc of a spatial
        contact); lift-off where lambda_N < 0. Also each slip direction (n, n_tangent).

        ``fired`` (contact, kind) is the switch that ended the last phase: its force stands
        at the boundary (lambda_N = 0, or the cone), where the tests above cannot tell the
        sides apart, so that contact takes the transition the event signals."""
        q, v = y[: self.nq], y[self.nq :]
        state = contact_state(self.equations, t, q, v)
        nt = self.contacts.n_tangent
        u_n, u_t = state.w_n @ v, (state.w_t @ v).reshape(self.n, nt)
        tol = self.task.options.rest_speed
        gap_tol = max(1e-9, 10 * self.task.atol) * self.scale
        modes = np.where((state.gaps <= gap_tol) & (u_n <= tol), STICK, OPEN)
        speed = np.linalg.norm(u_t, axis=1)
        modes[(modes == STICK) & (speed > tol)] = SLIP
        signs = u_t / np.where(speed > 0, speed, 1.0)[:, None]
        u_f = state.w_f @ v  # the joints with friction: slipping where they turn
        joint_modes = np.where(np.abs(u_f) > tol, SLIP, STICK)
        joint_signs = np.zeros((self.nf, nt))
        joint_signs[:, 0] = np.sign(u_f)
        modes, signs = np.concatenate([modes, joint_modes]), np.vstack([signs, joint_signs])
        mu, n = self.contacts.friction, self.n
        if self.nf:  # a joint at rest slips the way its rate then turns (a dead centre's
            # kinematics may turn it whatever the friction), else it sticks
            joint_bias = self.contacts.joint_rate_bias(t, q, v)[0].reshape(-1)
            for i in np.flatnonzero(joint_modes == STICK):
                for sign in (1.0, -1.0):
                    modes[n + i], signs[n + i, 0] = SLIP, sign
                    a = self.accelerations(t, y, modes, signs)[0]
                    if sign * (state.w_f[i] @ a + joint_bias[i]) > 0:
                        break
                else:
                    modes[n + i], signs[n + i, 0] = STICK, 0.0
        if fired is not None:
            self.take_fired_switch(t, y, modes, signs, fired)
        for _ in range(4 * (n + self.nf) + 2):
            _, lam_n, lam_t, lam_f = self.accelerations(t, y, modes, signs)
            held = np.linalg.norm(lam_t, axis=1)
            lifted = (modes[:n] != OPEN) & (lam_n < 0)
            slipping = (modes[:n] == STICK) & ~lifted & (held > mu * lam_n * (1 + 1e-9))
            joint_slipping = (modes[n:] == STICK) & (
                np.abs(lam_f) > self.bound_f * (1 + 1e-9) + 1e-12
            )
            if not lifted.any() and not slipping.any() and not joint_slipping.any():
                break
            modes[:n][lifted] = OPEN
            # stick to slip: the contact starts to slide against the force that held it
            signs[:n][slipping] = -lam_t[slipping] / held[slipping, None]
            modes[:n][slipping] = SLIP
            signs[n:, 0][joint_slipping] = -np.sign(lam_f[joint_slipping])
            modes[n:][joint_slipping] = SLIP
        return modes, signs

    def take_fired_switch(
        self, t: float, y: np.ndarray, modes: np.ndarray, signs: np.ndarray, fired: tuple
    ) -> None:
        """Apply the transition of the event that fired (see :meth:`choose_modes`) in place."""
        i, kind = fired
        if kind == "normal" and modes[i] != OPEN:
            # lambda_N fell through 0 (the event's direction): released, the gap's
            # acceleration equals the closed one's 0 there and then turns outward; a wrong
            # release only costs a zero-speed impact that closes it again
            modes[i] = OPEN
        elif kind == "cone" and modes[i] == STICK:
            lam_t = self.accelerations(t, y, modes, signs)[2][i]
            held = np.linalg.norm(lam_t)
            if held > 0:  # slide against the force that held it
                modes[i], signs[i] = SLIP, -lam_t / held
        elif kind == "joint-cone" and modes[self.n + i] == STICK:
            lam_f = self.accelerations(t, y, modes, signs)[3][i]
            if lam_f != 0:
                modes[self.n + i], signs[self.n + i, 0] = SLIP, -np.sign(lam_f)

    def switching_functions(self, modes: np.ndarray, signs: np.ndarray) -> list:
        nt = self.contacts.n_tangent

        def make(i: int, kind: str) -> Any:
            def event(t: float, y: np.ndarray) -> float:
                q, v = y[: self.nq], y[self.nq :]
                if kind == "gap":
                    return float(self.contacts.gaps(t, q)[0].reshape(-1)[i])
                if kind == "joint-slide":  # the joint's slip stops (or reverses)
                    w_f = self.contacts.joint_rate_jacobian(t, q)[0].reshape(self.nf, self.nv)
                    return float(signs[self.n + i, 0] * (w_f[i] @ v))
                if kind == "joint-cone":
                    lam_f = self.accelerations(t, y, modes, signs)[3]
                    return float(self.bound_f[i] - abs(lam_f[i]))
                if kind in ("slide", "turn"):
                    w_t = self.contacts.tangent_jacobian(t, q)[0].reshape(self.n, nt, self.nv)[i]
                    u_t = w_t @ v
                    if kind == "slide":  # the slip stops (or reverses, planar)
                        return float(signs[i] @ u_t)
                    # a spatial slip turned 60 degrees from the phase's start: new phase
                    return float(signs[i] @ u_t - np.linalg.norm(u_t) / 2)
                _, lam_n, lam_t, _ = self.accelerations(t, y, modes, signs)
                if kind == "normal":
                    return float(lam_n[i])
                return float(self.contacts.friction[i] * lam_n[i] - np.linalg.norm(lam_t[i]))

            event.terminal, event.direction = True, -1
            return event

        slide = ["normal", "slide"] + (["turn"] if nt > 1 else [])
        kinds = {OPEN: ["gap"], SLIP: slide, STICK: ["normal", "cone"]}
        joint_kinds = {SLIP: ["joint-slide"], STICK: ["joint-cone"]}
        self.labels = self.switch_labels(modes, kinds, joint_kinds)
        return [make(i, kind) for i, kind in self.labels]

    def switch_labels(self, modes: np.ndarray, kinds: dict, joint_kinds: dict) -> list:
        """(contact or joint index, kind) of each switching function, in their order."""
        return [(i, kind) for i in range(self.n) for kind in kinds[int(modes[i])]] + [
            (i, kind) for i in range(self.nf) for kind in joint_kinds[int(modes[self.n + i])]
        ]

    # -- the run ---------------------------------------------------------------------
    def run(self, trajectory: Trajectory) -> None:
        task = self.task
        times, t_end = task.times, float(task.times[-1])
        spacing = np.diff(np.asarray(times, dtype=float))
        pairs = any(isinstance(c, SphereContact) for c in self.task.equations.model.contacts)
        self.max_step = float(np.max(spacing)) if pairs and spacing.size else np.inf
        t, y = float(times[0]), task.y0[: self.nq + self.nv].copy()
        out_t, out_y, steps = [times[0]], [y.copy()], 0
        fired = None
        for _ in range(task.options.max_events + 1):
            modes, signs = self.choose_modes(t, y, fired)
            rhs = self.right_hand_side(modes, signs)
            wanted = times[(times > t) & (times <= t_end)]
            # SciPy looks for sign changes between steps only: a sphere pair's gap can close
            # and open again within one step (two balls in free flight passing through each
            # other), so with sphere pairs no step spans more than an output interval
            solution = solve_ivp(
                rhs, (t, t_end), y, method="DOP853", t_eval=wanted, rtol=task.rtol,
                atol=task.atol, events=self.switching_functions(modes, signs),
                max_step=self.max_step,
            )  # fmt: skip
            # (an event in the first step, before any output time, leaves lists)
            sampled_t = np.asarray(solution.t, dtype=float).reshape(-1)
            sampled_y = np.asarray(solution.y, dtype=float).reshape(y.size, sampled_t.size)
            steps += sampled_t.size
            for s, z in zip(sampled_t, sampled_y.T, strict=True):
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
            k = next(k for k, te in enumerate(solution.t_events) if te.size and te[0] == t_event)
            y, fired = solution.y_events[k][0], self.labels[k]
            t = float(t_event)
            y = self.impact(t, y)
            q, v = project(self.equations, t, y[: self.nq], y[self.nq :])
            y = np.concatenate([q, v])
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
