"""What the contact integrators share: the numbers of the contact form at a state, and the
velocity-level contact problem (impacts, Moreau-Jean steps) solved by proxsuite (planar
contacts) or Clarabel (spatial contacts: Coulomb's disc, a second-order cone).

The velocity-level problem (Moreau 1988, Jean 1999; Acary & Brogliato 2008, ch. 10): with
the free velocity v_free (no contact impulse), impulses P = [P_N; P_T] on the contacts
``rows`` give v+ = v_free + M^-1 W^T P and local velocities U+ = W v_free + D P,
D = W M^-1 W^T (Delassus). Newton's impact law and Coulomb's law ask

    0 <= U_N+ + e U_N-  _|_  P_N >= 0,   U_T+ in -N_C(P_T),  C = {|P_T| <= mu P_N}

(C: Coulomb's disc, an interval for a planar contact). For a fixed bound s = mu P_N this
is the optimality system of the convex program min 1/2 P^T D P + P^T b,
b = W v_free + [e U_N-; 0], P_N >= 0, |P_T| <= s (Tresca friction): a box QP solved by
proxsuite's ProxQP for planar contacts, a QP with a second-order cone per spatial contact
solved by Clarabel; Coulomb's law is its fixed point in s (Panagiotopoulos' iteration),
reached in a few programs.

Bilateral constraints beside the contacts (a closed loop; absolute coordinates with
joints), W_B v + w = 0, hold as equalities through every impact and time step: their
impulses are eliminated with the KKT matrix [M W_B^T; W_B 0] (its Schur complement,
Acary & Brogliato 2008, 10.1), so v_free is first moved onto W_B v + w = 0 and M^-1 W^T
becomes the constrained response N W^T, D = W N W^T; the QP is then the one above
(M may be singular there, as a point mass's rotation in absolute coordinates).
Positions drift off g(q) = 0 only as the velocity level lets them: :func:`project` puts q
back on g = 0 (Gauss-Newton, minimum norm) and v on W v + w = 0 (in the metric of M).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import clarabel
import numpy as np
import proxsuite
from scipy import sparse

from workbench.equations import Equations
from workbench.errors import IntegrationError

QP_ACCURACY = 1e-10  # proxsuite's absolute accuracy (N s) of the impulses
FIXED_POINT_ITERATIONS = 50
CONIC_ACCURACY = 1e-12  # Clarabel's gap and feasibility tolerances (spatial contacts)


@dataclass
class ContactState:
    """The mechanical and contact numbers at (t, q, v): M, Q, the gaps and W = [W_N; W_T];
    the bilateral rows W_B (nb, nv) with W_B v + w = 0 and W_B v' = gamma (nb = 0: none)."""

    mass: np.ndarray
    forces: np.ndarray
    gaps: np.ndarray
    w_n: np.ndarray
    w_t: np.ndarray
    w_b: np.ndarray
    w_b_offset: np.ndarray  # w
    gamma: np.ndarray
    w_f: np.ndarray  # (nf, nv): the rates of the joints with friction, U_F = W_F v


def contact_state(equations: Equations, t: float, q: np.ndarray, v: np.ndarray) -> ContactState:
    mech, contacts = equations.forms["mechanical"], equations.contacts
    nb, nv = mech.n_constraints, equations.nv
    w_b, offset, gamma = np.zeros((0, nv)), np.zeros(0), np.zeros(0)
    if nb:
        w_b = np.asarray(mech.velocity_matrix(t, q)[0]).reshape(nb, nv)
        offset = np.asarray(mech.velocity_constraints(t, q, v)[0]).reshape(-1) - w_b @ v
        gamma = np.asarray(mech.acceleration_rhs(t, q, v)[0]).reshape(-1)
    return ContactState(
        np.asarray(mech.mass(t, q)[0]).reshape(nv, nv),
        np.asarray(mech.forces(t, q, v)[0]).reshape(nv),
        contacts.gaps(t, q)[0].reshape(-1),
        contacts.normal_jacobian(t, q)[0].reshape(contacts.n_contacts, nv),
        contacts.tangent_jacobian(t, q)[0].reshape(contacts.n_contacts * contacts.n_tangent, nv),
        w_b,
        offset,
        gamma,
        joint_rate_matrix(equations, t, q),
    )


def joint_rate_matrix(equations: Equations, t: float, q: np.ndarray) -> np.ndarray:
    """W_F (nf, nv): the rates of the joints with Coulomb friction, U_F = W_F v."""
    contacts, nv = equations.contacts, equations.nv
    if not contacts.n_joint_frictions:
        return np.zeros((0, nv))
    return np.asarray(contacts.joint_rate_jacobian(t, q)[0]).reshape(-1, nv)


def constrained_solve(state: ContactState, rhs: np.ndarray, bilateral: np.ndarray | None = None):
    """x with M x + W_B^T mu = rhs and W_B x = ``bilateral`` (default gamma: the
    accelerations the bilateral constraints allow under the forces ``rhs``; columns of
    ``rhs`` take columns of ``bilateral``); M^-1 rhs without bilateral rows. Solved on the
    KKT matrix [M W_B^T; W_B 0] (least squares: M may be singular, as a point mass's
    in absolute coordinates, and rows redundant)."""
    nb = state.w_b.shape[0]
    if nb == 0:
        return np.linalg.solve(state.mass, rhs)
    kkt = np.block([[state.mass, state.w_b.T], [state.w_b, np.zeros((nb, nb))]])
    lower = state.gamma if bilateral is None else bilateral
    solution = np.linalg.lstsq(kkt, np.concatenate([rhs, lower]), rcond=1e-12)[0]
    return solution[: rhs.shape[0]]


POSITION_TOLERANCE = 1e-12  # m (or rad): |g| left by the projection, relative to the size of q


def project(equations: Equations, t: float, q: np.ndarray, v: np.ndarray):
    """(q, v) put back on the bilateral constraints: q on g(t, q) = 0 by Gauss-Newton with
    minimum-norm steps, then v on W v + w = 0 in the metric of M (module docstring)."""
    mech = equations.forms["mechanical"]
    if not mech.n_constraints:
        return q, v
    q = q.copy()
    tolerance = POSITION_TOLERANCE * max(1.0, float(np.max(np.abs(q), initial=0.0)))
    for _ in range(10 * bool(mech.n_holonomic)):
        g = np.asarray(mech.position_constraints(t, q)[0]).reshape(-1)
        if np.max(np.abs(g), initial=0.0) <= tolerance:
            break
        jacobian = np.asarray(mech.position_jacobian(t, q)[0]).reshape(g.size, -1)
        q -= np.linalg.lstsq(jacobian, g, rcond=1e-12)[0]
        for block in equations.quaternion_slices:
            q[block] /= np.linalg.norm(q[block])
    mass = np.asarray(mech.mass(t, q)[0]).reshape(v.size, v.size)
    w_b = np.asarray(mech.velocity_matrix(t, q)[0]).reshape(mech.n_constraints, -1)
    residual = np.asarray(mech.velocity_constraints(t, q, v)[0]).reshape(-1)
    nb = residual.size
    kkt = np.block([[mass, w_b.T], [w_b, np.zeros((nb, nb))]])
    change = np.linalg.lstsq(kkt, np.concatenate([np.zeros(v.size), -residual]), rcond=1e-12)[0]
    return q, v + change[: v.size]


def refuse(equations: Equations) -> str | None:
    """Why a contact integrator here cannot run these equations, or None."""
    if equations.contacts is None:
        return "the model has no unilateral contacts: use a smooth integrator"
    return None


def tresca_problem(delassus, b, n, nt, friction_bounds, joint_bounds) -> np.ndarray:
    """P = [P_N; P_T; P_F] minimizing 1/2 P^T D P + P^T b with P_N >= 0, the friction
    impulse of contact i in its disc |P_T,i| <= friction_bounds[i] and |P_F| <=
    joint_bounds: an interval per planar contact (a box QP, proxsuite's ProxQP), a
    second-order cone per spatial contact (Clarabel)."""
    if nt == 1:
        lower = np.concatenate([np.zeros(n), -friction_bounds, -joint_bounds])
        upper = np.concatenate([np.full(n, np.inf), friction_bounds, joint_bounds])
        result = proxsuite.proxqp.dense.solve(
            delassus, b, None, None, None, None, None, l_box=lower, u_box=upper,
            eps_abs=QP_ACCURACY, eps_rel=0.0,
        )  # fmt: skip
        return np.asarray(result.x)
    return disc_problem(delassus, b, n, nt, friction_bounds, joint_bounds)


def disc_problem(delassus, b, n, nt, friction_bounds, joint_bounds) -> np.ndarray:
    """The Tresca problem of :func:`tresca_problem` with Coulomb's disc per spatial contact,
    by Clarabel: A P + s = c, s in K, K = R+^n (P_N >= 0) x R+^2nf (the joints' box) x,
    per contact, the cone ||P_T,i|| <= friction_bounds[i] (a zero cone where the bound is
    0: a cone without interior stalls an interior-point method). Solved in units where D
    and b are of order 1 (its tolerances are absolute in part)."""
    nf, size = joint_bounds.size, b.size
    d_scale = max(float(np.max(np.abs(np.diag(delassus)))), 1e-300)
    b_scale = max(float(np.max(np.abs(b), initial=0.0)), 1e-300)
    unit = b_scale / d_scale  # the impulse that changes the velocities by about |b|
    friction_bounds, joint_bounds = friction_bounds / unit, joint_bounds / unit
    tangent = n + np.arange(n * nt).reshape(n, nt)
    joints = n * (1 + nt) + np.arange(nf)
    zero = [row for i in range(n) if friction_bounds[i] <= 0 for row in tangent[i]]
    rows, offsets = [np.eye(size)[zero]], [np.zeros(len(zero))]
    cones = [clarabel.ZeroConeT(len(zero))] if zero else []
    rows += [-np.eye(size)[:n], np.eye(size)[joints], -np.eye(size)[joints]]
    offsets += [np.zeros(n), joint_bounds, joint_bounds]
    cones.append(clarabel.NonnegativeConeT(n + 2 * nf))
    for i in np.flatnonzero(friction_bounds > 0):
        rows += [np.zeros((1, size)), -np.eye(size)[tangent[i]]]
        offsets += [[friction_bounds[i]], np.zeros(nt)]
        cones.append(clarabel.SecondOrderConeT(1 + nt))
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = CONIC_ACCURACY
    solver = clarabel.DefaultSolver(
        sparse.csc_matrix(np.triu(delassus / d_scale)), np.asarray(b) / b_scale,
        sparse.csc_matrix(np.vstack(rows)), np.concatenate(offsets).astype(float), cones,
        settings,
    )  # fmt: skip
    solution = solver.solve()
    if str(solution.status) not in ("Solved", "AlmostSolved"):
        raise IntegrationError(
            f"Clarabel failed on a contact problem ({solution.status}): try a smaller step"
        )
    return np.asarray(solution.x) * unit


def disc_residual(p_t, u_t, bound, stiffness) -> np.ndarray:
    """Per contact, how far (P_T, U_T+) is from Coulomb's law in the disc |P_T| <= bound:
    the natural map |D_TT (P_T - proj_disc(P_T - U_T+ / D_TT))| (m/s), zero iff P_T is in
    the disc and opposes U_T+ with |P_T| = bound where U_T+ != 0 (D_TT: the mean diagonal of
    the contact's tangent block of the Delassus matrix)."""
    stiffness = np.maximum(stiffness, 1e-300)[:, None]
    trial = p_t - u_t / stiffness
    length = np.linalg.norm(trial, axis=1, keepdims=True)
    projected = trial * np.minimum(1.0, bound[:, None] / np.maximum(length, 1e-300))
    return np.linalg.norm(stiffness * (p_t - projected), axis=1)


@dataclass
class Impulses:
    """Solution of the velocity-level problem on ``active`` contacts."""

    normal: np.ndarray  # (n_active,) P_N
    tangent: np.ndarray  # (n_active * n_tangent,) P_T
    velocity: np.ndarray  # (nv,) v+
    residual: float  # max |min(P_N D_NN, U_N+ + e U_N-)|, spatial: the disc's too; relative
    joint: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (nf,) P_F


def velocity_problem(
    equations: Equations,
    state: ContactState,
    v_free: np.ndarray,
    v_before: np.ndarray,
    active: np.ndarray,
    joint_bounds: np.ndarray | None = None,
) -> Impulses:
    """Impulses on the ``active`` contacts (boolean, one a contact) from v_free; Newton's
    law refers to the local velocities at ``v_before`` (module docstring). Bilateral rows
    W_B v+ + w = 0 hold as equalities. ``joint_bounds`` (nf,): the joints with Coulomb
    friction take impulses |P_F| <= joint_bounds on their rates (Moreau-Jean: h times the
    friction bound); None leaves them out (an impact: no impulsive joint friction)."""
    contacts = equations.contacts
    nt = contacts.n_tangent
    index = np.flatnonzero(active)
    nb = state.w_b.shape[0]
    if nb:  # onto W_B v + w = 0 (the bilateral impulses that need no contact impulse)
        v_free = v_free + constrained_solve(state, np.zeros_like(v_free),
                                            -(state.w_b @ v_free + state.w_b_offset))  # fmt: skip
    nf = 0 if joint_bounds is None else state.w_f.shape[0]
    if index.size == 0 and nf == 0:
        return Impulses(np.zeros(0), np.zeros(0), v_free, 0.0)
    tangent_rows = (index[:, None] * nt + np.arange(nt)).reshape(-1)
    w = np.vstack([state.w_n[index], state.w_t[tangent_rows], state.w_f[:nf]])
    inverse_mass_wt = constrained_solve(state, w.T, np.zeros((nb, w.shape[0])))
    delassus = w @ inverse_mass_wt
    delassus = (delassus + delassus.T) / 2
    e, mu = contacts.restitution[index], contacts.friction[index]
    n = index.size
    b = w @ v_free
    b[:n] += e * (state.w_n[index] @ v_before)
    joint = np.zeros(0) if joint_bounds is None else np.asarray(joint_bounds, dtype=float)
    bound = np.zeros(n)
    impulses = np.zeros(n * (1 + nt) + nf)
    for _ in range(FIXED_POINT_ITERATIONS):
        impulses = tresca_problem(delassus, b, n, nt, mu * bound, joint)
        new_bound = np.maximum(impulses[:n], 0.0)
        if np.max(np.abs(new_bound - bound), initial=0.0) <= QP_ACCURACY * 10 or not mu.any():
            bound = new_bound
            break
        bound = new_bound
    normal, tangent = np.maximum(impulses[:n], 0.0), impulses[n : n * (1 + nt)]
    velocity = v_free + inverse_mass_wt @ impulses
    target = state.w_n[index] @ velocity + e * (state.w_n[index] @ v_before)
    speeds = np.abs(np.concatenate([state.w_n[index] @ v_before, state.w_n[index] @ v_free]))
    scale = max(float(np.max(speeds, initial=0.0)), 1e-12)  # the velocities it changes
    residual = np.abs(np.minimum(normal * np.diag(delassus)[:n], target))
    residual = float(np.max(residual, initial=0.0)) / scale
    if n and nt > 1 and mu.any():  # Coulomb's disc, relative to the slip speeds it changes
        slip = (w[n : n * (1 + nt)] @ velocity).reshape(n, nt)
        speeds = np.abs(w[n : n * (1 + nt)] @ np.stack([v_before, v_free], axis=1))
        slip_scale = max(scale, float(np.max(speeds, initial=0.0)))
        stiffness = np.diag(delassus)[n : n * (1 + nt)].reshape(n, nt).mean(axis=1)
        friction = disc_residual(tangent.reshape(n, nt), slip, mu * normal, stiffness)
        residual = max(residual, float(np.max(friction, initial=0.0)) / slip_scale)
    return Impulses(normal, tangent, velocity, residual, impulses[n * (1 + nt) :])
