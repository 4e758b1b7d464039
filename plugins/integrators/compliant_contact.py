"""Compliant (penalty) contact, as MuJoCo models contact softly, integrated by a smooth
method (SciPy's Radau on the mechanical equations plus the contact forces).

Each contact pushes with lambda_N = max(0, k p - c U_N) at penetration p = -g_N > 0, the
stiffness ``stiffness`` k (N/m) stated in the row's options, the damping c = 2 zeta
sqrt(k m_eff) chosen so a linear spring-damper of the contact's effective mass
m_eff = 1 / (W_N M^-1 W_N^T) rebounds with the contact's restitution e:
zeta = -ln e / sqrt(pi^2 + ln^2 e) (e = 0: zeta = 1, critical). Friction is Coulomb's,
regularized: lambda_T = -mu lambda_N U_T / sqrt(U_T^2 + v_eps^2) (``slip_speed`` v_eps).
The answer converges to the rigid one only as k grows and v_eps shrinks: the contact
penetrates about m g / k at rest and creeps at about v_eps where it should stick.
Bilateral constraints beside the contacts (a closed loop; absolute coordinates with
joints) are kept at acceleration level, W_B v' = gamma, in the same linear solve
(:func:`_contact.constrained_solve`), and m_eff uses the constrained response.
Coulomb friction in a joint is regularized the same way: -bound U_F / sqrt(U_F^2 + v_eps^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.integrate import solve_ivp

from workbench.equations import Equations
from workbench.errors import ConfigError
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.options import with_unit
from workbench.plugin.registry import integrator
from workbench.plugins.integrators._contact import constrained_solve, contact_state, refuse


@dataclass(frozen=True)
class CompliantOptions:
    stiffness: float = with_unit(1e6, "N/m")  # of every contact
    slip_speed: float = with_unit(1e-4, "m/s")  # the regularization of Coulomb's law

    def __post_init__(self) -> None:
        if not (self.stiffness > 0 and math.isfinite(self.stiffness)):
            raise ConfigError(f"stiffness must be a finite number > 0 N/m, not {self.stiffness}")
        if not self.slip_speed > 0:
            raise ConfigError(f"slip_speed must be > 0 m/s, not {self.slip_speed}")


def damping_ratio(restitution: np.ndarray) -> np.ndarray:
    """The damping ratio of a linear spring-damper that rebounds with ``restitution``."""
    log_e = np.log(np.clip(restitution, 1e-300, 1.0))
    return np.where(restitution > 0, -log_e / np.sqrt(np.pi**2 + log_e**2), 1.0)


@integrator
class CompliantContact(Integrator):
    name = "compliant-contact"
    summary = "Penalty contact (stiffness stated, damping from e), SciPy Radau"
    Options = CompliantOptions
    accepts: ClassVar[dict[str, int]] = {"mechanical": 0}
    contacts: ClassVar[bool] = True

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        return refuse(equations)

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        equations, options = task.equations, task.options
        mech, contacts = task.form, equations.contacts
        nq, nv, n, nt = equations.nq, equations.nv, contacts.n_contacts, contacts.n_tangent
        zeta = damping_ratio(contacts.restitution)
        k = options.stiffness
        bound_f = contacts.joint_friction_bound

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            q, v = y[:nq], y[nq:]
            state = contact_state(equations, t, q, v)
            force = state.forces.copy()
            touching = np.flatnonzero(state.gaps < 0)
            if touching.size:
                columns = state.w_n[touching].T  # the constrained response N W_N^T
                zero = np.zeros((state.w_b.shape[0], touching.size))
                inverse_wt = constrained_solve(state, columns, zero)
                m_eff = 1 / np.einsum("ij,ji->i", state.w_n[touching], inverse_wt)
                c = 2 * zeta[touching] * np.sqrt(k * m_eff)
                u_n = state.w_n[touching] @ v
                lam_n = np.maximum(0.0, -k * state.gaps[touching] - c * u_n)
                force += state.w_n[touching].T @ lam_n
                for j, i in enumerate(touching):
                    w_t = state.w_t[i * nt : (i + 1) * nt]
                    u_t = w_t @ v
                    slip = np.sqrt(u_t @ u_t + options.slip_speed**2)
                    force -= w_t.T @ (contacts.friction[i] * lam_n[j] * u_t / slip)
            u_f = state.w_f @ v  # joint friction, regularized like the contacts'
            force -= state.w_f.T @ (bound_f * u_f / np.sqrt(u_f**2 + options.slip_speed**2))
            qdot = mech.qdot(t, q, v)[0].reshape(-1)
            return np.concatenate([qdot, constrained_solve(state, force)])

        def closing(i: int) -> Any:  # a gap turning negative: the contact's event
            def event(t: float, y: np.ndarray) -> float:
                return float(contacts.gaps(t, y[:nq])[0].reshape(-1)[i])

            event.direction = -1
            return event

        def deepest(i: int) -> Any:  # the normal velocity turning positive: deepest point
            def event(t: float, y: np.ndarray) -> float:
                w_n = contacts.normal_jacobian(t, y[:nq])[0].reshape(n, -1)
                return float(w_n[i] @ y[nq:])

            event.direction = 1
            return event

        y0 = task.y0[: nq + nv]
        solution = solve_ivp(rhs, (task.times[0], task.times[-1]), y0, method="Radau",
                             t_eval=task.times, rtol=task.rtol, atol=task.atol,
                             events=[closing(i) for i in range(n)]
                             + [deepest(i) for i in range(n)])  # fmt: skip
        trajectory.times = np.asarray(solution.t)
        trajectory.y = np.asarray(solution.y).T.reshape(len(solution.t), y0.size)
        trajectory.stats.n_lu = int(solution.nlu)
        if solution.status < 0:
            trajectory.success = False
            trajectory.message = f"compliant-contact: {solution.message}"
        gaps = [contacts.gaps(t, y[:nq])[0].reshape(-1)
                for t, y in zip(trajectory.times, trajectory.y, strict=True)]  # fmt: skip
        deepest_gaps = [contacts.gaps(0.0, y[:nq])[0].reshape(-1)
                         for ys in solution.y_events[n:] for y in ys]  # fmt: skip
        trajectory.contact = {
            "event_times": sorted(float(t) for ts in solution.t_events[:n] for t in ts),
            "penetration_max": float(np.max(-np.array(gaps + deepest_gaps), initial=0.0)),
            "complementarity_max": math.nan,  # no complementarity problem: a force law
            "stiffness": k,
        }
