"""Moreau-Jean time-stepping on the ``mechanical`` form with unilateral contacts.

The velocity-level scheme of Moreau (1988) and Jean (1999) (Acary & Brogliato 2008, 10.1):
with step h and theta = 1/2,

    q_m = q_k + h/2 H v_k                             (where contacts are looked for)
    M (v_k+1 - v_k) = h Q(t_k, q_k, v_k) + W^T P      (impulses P over the step)
    q_k+1 = q_k + h H (theta v_k+1 + (1 - theta) v_k)

(Euler parameters renormalized after each step), the contacts with g_N(q_m) <= 0
active, and P from Newton's impact law and Coulomb's law at velocity level
(:func:`_contact.velocity_problem`: proxsuite, or Clarabel for Coulomb's disc of a
spatial contact). Impacts, sticking and sliding need no
events: the method is first order and takes the same step throughout.
An impact is counted where a contact closes with an impulse, at the time its gap crosses
zero by linear interpolation within the step; a slip-to-stick switch where a closed
contact's friction impulse leaves the edge of its cone (at the step's end). ``step``: 0
takes it from rtol (:func:`step_for_tolerance`, order 1), never longer than an output
interval.

Bilateral constraints beside the contacts (a closed loop; absolute coordinates with
joints) hold at velocity level in the same problem, W_B v_k+1 + w = 0 (their impulses
eliminated with the KKT matrix, :func:`_contact.velocity_problem`); the positions are then
stabilized by projecting q_k+1 onto g(q) = 0
(:func:`_contact.project`, Gauss-Newton with minimum-norm steps) after each step.
Coulomb friction in a joint takes an impulse |P_F| <= h bound on the joint's rate in the
same problem (a box beside the contacts').
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from workbench.equations import Equations
from workbench.errors import ConfigError
from workbench.plugin.integrator import (
    IntegrationTask,
    Integrator,
    Trajectory,
    step_for_tolerance,
)
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator
from workbench.plugins.integrators._contact import (
    constrained_solve,
    contact_state,
    project,
    refuse,
    velocity_problem,
)


@dataclass(frozen=True)
class MoreauJeanOptions:
    step: float = with_unit(0.0, "s")  # 0: from rtol (order 1)
    theta: float = 0.5  # the theta-method's weight of v_k+1 in the position update

    def __post_init__(self) -> None:
        if not (self.step >= 0 and math.isfinite(self.step)):
            raise ConfigError(
                f"step must be a finite number >= 0 s (0: from rtol), not {self.step}"
            )
        if not 0.5 <= self.theta <= 1.0:
            raise ConfigError(f"theta must be in [0.5, 1], not {self.theta}")


@integrator
class MoreauJean(Integrator):
    name = "moreau-jean"
    summary = "Moreau-Jean time-stepping: velocity-level impacts, Coulomb friction (QP, SOCP)"
    Options = MoreauJeanOptions
    accepts: ClassVar[dict[str, int]] = {"mechanical": 0}
    contacts: ClassVar[bool] = True

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        return refuse(equations)

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        equations, options = task.equations, task.options
        mech, contacts = task.form, equations.contacts
        nq, nv = equations.nq, equations.nv
        times = task.times
        # the rule's step, never longer than an output interval (the step actually taken)
        h_max = options.step or step_for_tolerance(task.rtol, 1)
        h_max = min(h_max, float(np.min(np.diff(times))))
        trajectory.stats.fixed_step = h_max
        out = [task.y0[: nq + nv].copy()]
        t, q, v = float(times[0]), task.y0[:nq].copy(), task.y0[nq : nq + nv].copy()
        events: list[float] = []
        penetration, residual, steps = 0.0, 0.0, 0
        touch = 1e-9 * max(1.0, float(np.max(np.abs(q), initial=0.0)))  # a gap of round-off
        roundoff = touch if contacts.n_tangent > 1 else 0.0
        closed = contacts.gaps(t, q)[0].reshape(-1) <= touch
        stuck = np.zeros(closed.size, dtype=bool)
        nt, mu = contacts.n_tangent, contacts.friction
        for target in times[1:]:
            while t < target - 1e-12 * max(1.0, abs(target)):
                h = min(h_max, target - t)
                state = contact_state(equations, t, q, v)
                kinematics = mech.kinematics(t, q)[0]
                q_mid = q + h / 2 * kinematics @ v
                # closed at the midpoint; spatial: also pushed last step and open by
                # round-off (Clarabel's interior point can leave a resting contact a hair above)
                gaps_mid = contacts.gaps(t + h / 2, q_mid)[0].reshape(-1)
                active = (gaps_mid <= 0) | (closed & (gaps_mid <= roundoff))
                v_free = v + h * constrained_solve(state, state.forces)
                solved = velocity_problem(equations, state, v_free, v, active,
                                          h * contacts.joint_friction_bound)  # fmt: skip
                v_new = solved.velocity
                residual = max(residual, solved.residual)
                q_new = q + h * kinematics @ (options.theta * v_new + (1 - options.theta) * v)
                for block in equations.quaternion_slices:  # back onto the unit sphere
                    q_new[block] /= np.linalg.norm(q_new[block])
                if equations.n_constraints:  # position-level stabilization
                    q_new, _ = project(equations, t + h, q_new, v_new)
                gaps_new = contacts.gaps(t + h, q_new)[0].reshape(-1)
                pushed = np.zeros(active.size, dtype=bool)
                pushed[np.flatnonzero(active)] = solved.normal > 0
                for i in np.flatnonzero(pushed & ~closed):
                    g0 = state.gaps[i]
                    g1 = g0 + h * state.w_n[i] @ v  # the gap's path without the impulse
                    fraction = g0 / (g0 - g1) if g0 > 0 and g1 < g0 else 0.0
                    events.append(t + h * min(max(fraction, 0.0), 1.0))
                # slip to stick: a pushed contact whose friction impulse leaves the cone's
                # edge and whose sliding velocity vanishes (at the step's end)
                sticking = np.zeros(active.size, dtype=bool)
                if solved.normal.size:
                    p_t = np.linalg.norm(solved.tangent.reshape(-1, nt), axis=1)  # in the disc
                    inside = p_t < mu[active] * solved.normal * (1 - 1e-6)
                    sticking[np.flatnonzero(active)] = inside & (solved.normal > 0)
                for i in np.flatnonzero(sticking & ~stuck & closed & pushed):
                    if mu[i] > 0:
                        events.append(t + h)
                closed, stuck = pushed, sticking
                penetration = max(penetration, float(np.max(-gaps_new, initial=0.0)))
                t, q, v = t + h, q_new, v_new
                steps += 1
            out.append(np.concatenate([q, v]))
        trajectory.times = times.copy()
        trajectory.y = np.array(out)
        trajectory.stats.n_steps = steps
        trajectory.stats.n_rejected = 0
        trajectory.contact = {
            "event_times": events,
            "penetration_max": penetration,
            "complementarity_max": residual,
        }
