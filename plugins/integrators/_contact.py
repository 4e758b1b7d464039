"""What the contact integrators share: the numbers of the contact form at a state, and the
velocity-level contact problem (impacts, Moreau-Jean steps) solved by proxsuite.

The velocity-level problem (Moreau 1988, Jean 1999; Acary & Brogliato 2008, ch. 10): with
the free velocity v_free (no contact impulse), impulses P = [P_N; P_T] on the contacts
``rows`` give v+ = v_free + M^-1 W^T P and local velocities U+ = W v_free + D P,
D = W M^-1 W^T (Delassus). Newton's impact law and Coulomb's law ask

    0 <= U_N+ + e U_N-  _|_  P_N >= 0,   U_T+ in -N_[-mu P_N, mu P_N](P_T)

(the tangential law per tangent component: a box, the friction pyramid of a spatial
contact). For a fixed bound s = mu P_N this is the optimality system of the convex QP
min 1/2 P^T D P + P^T b, b = W v_free + [e U_N-; 0], P_N >= 0, |P_T| <= s (Tresca
friction), solved by proxsuite's ProxQP; Coulomb's law is its fixed point in s
(Panagiotopoulos' iteration), reached in a few QPs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import proxsuite

from workbench.equations import Equations

QP_ACCURACY = 1e-10  # proxsuite's absolute accuracy (N s) of the impulses
FIXED_POINT_ITERATIONS = 50


@dataclass
class ContactState:
    """The mechanical and contact numbers at (t, q, v): M, Q, the gaps and W = [W_N; W_T]."""

    mass: np.ndarray
    forces: np.ndarray
    gaps: np.ndarray
    w_n: np.ndarray
    w_t: np.ndarray


def contact_state(equations: Equations, t: float, q: np.ndarray, v: np.ndarray) -> ContactState:
    mech, contacts = equations.forms["mechanical"], equations.contacts
    return ContactState(
        mech.mass(t, q)[0],
        mech.forces(t, q, v)[0],
        contacts.gaps(t, q)[0].reshape(-1),
        contacts.normal_jacobian(t, q)[0].reshape(contacts.n_contacts, -1),
        contacts.tangent_jacobian(t, q)[0].reshape(contacts.n_contacts * contacts.n_tangent, -1),
    )


def refuse(equations: Equations) -> str | None:
    """Why a contact integrator here cannot run these equations, or None."""
    if equations.contacts is None:
        return "the model has no unilateral contacts: use a smooth integrator"
    if equations.n_constraints:
        return (
            f"formalism {equations.formalism!r} gives {equations.n_constraints} bilateral "
            "constraint rows beside the contacts; contact integrators take unconstrained "
            "coordinates only so far (minimal-ode, or absolute-dae on a tree of free bodies)"
        )
    return None


@dataclass
class Impulses:
    """Solution of the velocity-level problem on ``active`` contacts."""

    normal: np.ndarray  # (n_active,) P_N
    tangent: np.ndarray  # (n_active * n_tangent,) P_T
    velocity: np.ndarray  # (nv,) v+
    residual: float  # complementarity residual max |min(P_N, U_N+ + e U_N-)|, normalised


def velocity_problem(
    equations: Equations,
    state: ContactState,
    v_free: np.ndarray,
    v_before: np.ndarray,
    active: np.ndarray,
) -> Impulses:
    """Impulses on the ``active`` contacts (boolean, one a contact) from v_free; Newton's
    law refers to the local velocities at ``v_before`` (module docstring)."""
    contacts = equations.contacts
    nt = contacts.n_tangent
    index = np.flatnonzero(active)
    if index.size == 0:
        return Impulses(np.zeros(0), np.zeros(0), v_free, 0.0)
    tangent_rows = (index[:, None] * nt + np.arange(nt)).reshape(-1)
    w = np.vstack([state.w_n[index], state.w_t[tangent_rows]])
    inverse_mass_wt = np.linalg.solve(state.mass, w.T)
    delassus = w @ inverse_mass_wt
    delassus = (delassus + delassus.T) / 2
    e, mu = contacts.restitution[index], contacts.friction[index]
    n = index.size
    b = w @ v_free
    b[:n] += e * (state.w_n[index] @ v_before)
    lower = np.concatenate([np.zeros(n), np.zeros(n * nt)])
    upper = np.concatenate([np.full(n, np.inf), np.zeros(n * nt)])
    bound = np.zeros(n)
    impulses = np.zeros(n * (1 + nt))
    for _ in range(FIXED_POINT_ITERATIONS):
        lower[n:], upper[n:] = -np.repeat(mu * bound, nt), np.repeat(mu * bound, nt)
        result = proxsuite.proxqp.dense.solve(
            delassus, b, None, None, None, None, None, l_box=lower, u_box=upper,
            eps_abs=QP_ACCURACY, eps_rel=0.0,
        )  # fmt: skip
        impulses = np.asarray(result.x)
        new_bound = np.maximum(impulses[:n], 0.0)
        if np.max(np.abs(new_bound - bound), initial=0.0) <= QP_ACCURACY * 10 or not mu.any():
            bound = new_bound
            break
        bound = new_bound
    normal, tangent = np.maximum(impulses[:n], 0.0), impulses[n:]
    velocity = v_free + inverse_mass_wt @ impulses
    target = state.w_n[index] @ velocity + e * (state.w_n[index] @ v_before)
    speeds = np.abs(np.concatenate([state.w_n[index] @ v_before, state.w_n[index] @ v_free]))
    scale = max(float(np.max(speeds)), 1e-12)  # the velocities the problem changes
    residual = float(np.max(np.abs(np.minimum(normal * np.diag(delassus)[:n], target)))) / scale
    return Impulses(normal, tangent, velocity, residual)
