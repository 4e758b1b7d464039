"""Formalism ``recursive``: articulated-body forward dynamics in O(n) (book 10.6, 11.4.2).

The generalized coordinates are the free joint coordinates of the spanning tree, as in
``minimal-ode`` (same q, v, same joint-space map). The accelerations come from three
recursions over the tree (Featherstone's articulated-body algorithm, the book's recursive
formalism 10.6.1-10.6.2), with no mass matrix formed:

1. outward: joint transform X_i (parent body -> body i), motion subspace S_i, body
   velocity V_i = X_i V_lambda(i) + S_i v_i and velocity-product acceleration
   c_i = c_J,i + V_i x S_i v_i;
2. inward: articulated inertia I^A_i and bias force p^A_i,
   U_i = I^A_i S_i, D_i = S_i^T U_i, u_i = tau_i - S_i^T p^A_i,
   I^A_lambda += X_i^T (I^A_i - U_i D_i^-1 U_i^T) X_i,
   p^A_lambda += X_i^T (p^A_i + I^a_i c_i + U_i D_i^-1 u_i);
3. outward: a'_i = X_i a_lambda + c_i, v_i' = D_i^-1 (u_i - U_i^T a'_i), a_i = a'_i + S_i v_i'.

Spatial vectors are Featherstone's: motion [angular; linear], force [moment; force],
in the coordinates of each body's reference frame, about its origin. S_i maps the joint
velocities to the twist of body i relative to its parent body, in body-i coordinates;
it is derived from :func:`workbench.mechanics.joints.relative_twist` (the one joint dispatch), so
every joint type of the model is handled. Applied forces: body wrenches of
:func:`workbench.mechanics.forces.body_wrenches` (gravity, springs, applied forces) are external
spatial forces f^x_i; joint springs and forces are the joint forces tau_i. A driven
(rheonomic) joint has its acceleration prescribed: S_i v_drive' is added to c_i and the
joint has no unknown.

The mechanical form also needs M and Q - h: M by composite rigid bodies (CRBA), h - Q by
recursive Newton-Euler (RNEA) at v' = 0. Option ``algorithm="rnea-crba"`` uses these
for the accelerations too (v' = M^-1 (Q - h), O(n^3) in the symbolic solve) for
comparison. Closed loops (book 11.4.2): the tree is cut at the loop-closing joints; the
constrained equations M v' = Q - h - W^T lambda use CRBA and RNEA (each O(n^2) / O(n)),
and the augmented solve of :func:`~workbench.equations.build_equations` is O(n^3): only
the unconstrained ode right-hand side is O(n). The ode form of a constrained model is the
index-1 system with Baumgarte stabilization.

All symbolic graphs are CasADi SX without expansion, so common subexpressions stay
shared and the ABA graph has O(n) instructions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np

from workbench.equations import (
    Equations,
    MechanicalSystem,
    build_joint_space_equations,
    joint_space_system,
)
from workbench.mechanics import forces as fm
from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import TreeKinematics
from workbench.model import GROUND, Joint, Model
from workbench.plugin.formalism import ConstraintOptions, Formalism
from workbench.plugin.registry import formalism

ZERO6 = ca.SX.zeros(6, 1)

# ---- spatial algebra (6-vectors [angular; linear], CasADi SX) ---------------------------


def motion_cross(v: Any, m: Any) -> Any:
    """v x m for motion vectors v, m (6,)."""
    w, v0 = v[:3], v[3:]
    return ca.vertcat(ca.cross(w, m[:3]), ca.cross(w, m[3:]) + ca.cross(v0, m[:3]))


def force_cross(v: Any, f: Any) -> Any:
    """v x* f for a motion vector v and a force vector f (6,)."""
    w, v0 = v[:3], v[3:]
    return ca.vertcat(ca.cross(w, f[:3]) + ca.cross(v0, f[3:]), ca.cross(w, f[3:]))


def transform_motion(E: Any, r: Any, m: Any) -> Any:
    """X m: a motion vector from parent to child coordinates (E: child <- parent rotation,
    r: child origin in parent coordinates)."""
    return ca.vertcat(ca.mtimes(E, m[:3]), ca.mtimes(E, m[3:] - ca.cross(r, m[:3])))


def transform_force_back(E: Any, r: Any, f: Any) -> Any:
    """X^T f: a force vector from child to parent coordinates."""
    force = ca.mtimes(E.T, f[3:])
    return ca.vertcat(ca.mtimes(E.T, f[:3]) + ca.cross(r, force), force)


def plucker(E: Any, r: Any) -> Any:
    """The 6x6 motion transform X = [E 0; -E r~ E]."""
    lower = -ca.mtimes(E, ca.skew(r))
    return ca.vertcat(ca.horzcat(E, ca.SX.zeros(3, 3)), ca.horzcat(lower, E))


def symmetric(entry: Any, n: int) -> Any:
    """The symmetric n x n SX matrix with entries ``entry(i, j)`` computed for i <= j only
    (the lower triangle shares the same expressions: no extra instructions)."""
    out = ca.SX.zeros(n, n)
    for i in range(n):
        for j in range(i, n):
            out[i, j] = entry(i, j)
            if j != i:
                out[j, i] = out[i, j]
    return out


def articulated_update(I_A: Any, U: Any, D_inv_U: Any) -> Any:
    """I^a = I^A - U D^-1 U^T (6 x 6, symmetric: 21 entries formed, not 36)."""
    return symmetric(lambda i, j: I_A[i, j] - ca.dot(U[i, :].T, D_inv_U[:, j]), 6)


def congruence(E: Any, r: Any, inertia: Any) -> Any:
    """X^T I X for a symmetric 6x6 (articulated) inertia I, X = plucker(E, r): I moved
    from child to parent coordinates.

    With I = [A B; B^T C] and the rotated blocks A' = E^T A E, B' = E^T B E,
    C' = E^T C E, X = diag(E, E) [1 0; -r~ 1] gives
    X^T I X = [A' + K + K^T - r~ C' r~, P; P^T, C'] with P = B' + r~ C', K = r~ B'^T.
    Only the unique entries of the symmetric blocks are formed: about 60 % of the
    instructions of the dense product (a revolute link of spatial-chain: 255 against 410).
    """
    A, B, C = inertia[:3, :3], inertia[:3, 3:], inertia[3:, 3:]

    def rotated(M: Any) -> Any:  # E^T M E for a symmetric M
        T = ca.mtimes(M, E)
        return symmetric(lambda i, j: ca.dot(E[:, i], T[:, j]), 3)

    A1, C1 = rotated(A), rotated(C)
    B1 = ca.mtimes([E.T, B, E])
    r_tilde = ca.skew(r)
    Q = ca.mtimes(r_tilde, C1)
    P = B1 + Q
    K = ca.mtimes(r_tilde, B1.T)
    QR = ca.mtimes(Q, r_tilde)
    top = symmetric(lambda i, j: A1[i, j] + K[i, j] + K[j, i] - QR[i, j], 3)
    return ca.vertcat(ca.horzcat(top, P), ca.horzcat(P.T, C1))


def spatial_inertia(mass: float, com: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Spatial inertia about the body frame's origin: [I_c + m c~ c~^T, m c~; m c~^T, m 1]."""
    c = np.asarray(com, dtype=float)
    c_tilde = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    return np.block(
        [
            [np.asarray(inertia, float) + mass * c_tilde @ c_tilde.T, mass * c_tilde],
            [mass * c_tilde.T, mass * np.eye(3)],
        ]
    )


def _sx(value: Any) -> Any:
    return value if isinstance(value, ca.SX) else ca.SX(ca.DM(np.asarray(value, dtype=float)))


# ---- joint model (Featherstone's jcalc through the joints.py dispatch) ----------------


def joint_model(joint: Joint, q: Any, v: Any) -> tuple[Any, Any, Any, Any]:
    """(E, r, S, c_J) of a tree joint at joint coordinates q (nq) and velocities v (nv).

    E (3, 3): rotation from the parent body's to the child body's coordinates; r (3): the
    child body frame's origin in parent body coordinates; S (6, nv): motion subspace, the
    child's twist relative to the parent body is S v, in child body coordinates about the
    child's origin; c_J (6): S' v, the rate of those components along q' = H(q) v at
    fixed v.
    """
    nq, nv = jk.dimensions(joint)
    R_P = ca.DM(joint.parent_frame.rotation)
    p_P = ca.DM(joint.parent_frame.position)
    R_Cf = ca.DM(joint.child_frame.rotation)
    c_pos = ca.DM(joint.child_frame.position)
    if nv == 0:
        R = ca.mtimes([R_P, R_Cf.T])
        E = _sx(R.T)
        r = _sx(p_P - ca.mtimes(R, c_pos))
        return E, r, ca.SX(6, 0), ZERO6
    qs, u = ca.SX.sym("qs", nq), ca.SX.sym("u", nv)
    r_rel, R_rel = jk.relative_transform(joint, qs)
    v_rel, w_rel = jk.relative_twist(joint, qs, u)
    R = ca.mtimes([R_P, _sx(R_rel), R_Cf.T])
    E = R.T
    r = p_P + ca.mtimes(R_P, _sx(r_rel)) - ca.mtimes(R, c_pos)
    w_b = ca.mtimes([E, R_P, _sx(w_rel)])
    v_b = ca.mtimes([E, R_P, _sx(v_rel)]) - ca.cross(w_b, _sx(c_pos))
    xi = ca.vertcat(w_b, v_b)
    S = ca.jacobian(xi, u)
    c_J = ca.mtimes(ca.jacobian(xi, qs), _sx(jk.coordinate_rates(joint, qs, u)))
    E, r, S, c_J = ca.substitute([E, r, S, c_J], [qs, u], [_sx(q), _sx(v)])
    return E, r, S, c_J


@dataclass
class Link:
    """One tree joint and its child body, with everything the recursions need."""

    joint: Joint
    body: str
    parent: int  # index of the parent link, -1 for the ground
    E: Any
    r: Any
    S: Any  # (6, nv) for a free joint, (6, 0) for driven and fixed joints
    v_J: Any  # (6,) joint twist S v (the drive's v for a driven joint)
    c: Any  # (6,) c_J + V x v_J (+ S v_drive' for a driven joint): filled by the outward pass
    c_J: Any
    inertia: Any  # (6, 6) spatial inertia about the body origin, body coordinates
    f_ext: Any  # (6,) applied force on the body, body coordinates
    tau: Any  # (nv,) joint forces
    v_slice: slice | None  # the joint's velocities in v (None if driven or fixed)

    @property
    def nv(self) -> int:
        return 0 if self.v_slice is None else self.v_slice.stop - self.v_slice.start


class SpatialTree:
    """The tree of ``model`` in spatial notation at symbolic (t, q, v) (Pinocchio's Data).

    ``links`` in parents-first order; ``velocities`` V_i (6,) and ``bias`` c_i (6,) of
    every link from the outward velocity pass; ``base_acceleration`` [0; -g] (6,): gravity
    as an upward acceleration of the ground, so ``f_ext`` holds only the other applied
    wrenches (:func:`~workbench.mechanics.forces.body_wrenches` without gravity, from the
    world poses of ``kinematics.bodies``).
    """

    def __init__(self, model: Model, kinematics: TreeKinematics) -> None:
        k = kinematics
        self.model, self.kinematics, self.nv = model, k, k.nv
        joint_coordinates = {j.name: k.joint_coordinates(j) for j in model.tree_joints}
        # gravity enters as the ground's acceleration -g (Featherstone's trick), so the
        # external forces need no world rotations unless the model has other wrenches
        wrenches = fm.body_wrenches(model, k.t, k.bodies, gravity=False)
        self.base_acceleration = ca.vertcat(ca.SX.zeros(3), -_sx(model.gravity))
        joint_forces = fm.joint_generalized_forces(model, k.t, joint_coordinates)
        index: dict[str, int] = {}
        self.links: list[Link] = []
        for joint in k.order:
            q_j, v_j = joint_coordinates[joint.name]
            E, r, S, c_J = joint_model(joint, q_j, v_j)
            nv = S.size2()
            v_J = ca.mtimes(S, _sx(v_j)) if nv else ZERO6
            v_slice = None
            if joint.drive is not None and nv:
                _, _, a_drive = jk.drive_values(joint, k.t)
                c_J = c_J + ca.mtimes(S, _sx(a_drive))
                S = ca.SX(6, 0)
            elif nv:
                v_slice = k.joint_slices[joint.name][1]
            body = model.bodies[joint.child]
            rotation = k.bodies[joint.child].rotation
            force, torque = wrenches[joint.child]
            f_ext = ca.vertcat(ca.mtimes(rotation.T, torque), ca.mtimes(rotation.T, force))
            tau = joint_forces.get(joint.name, 0) if v_slice is not None else 0
            tau = _sx(tau) if not isinstance(tau, int) else ca.SX.zeros(S.size2())
            self.links.append(
                Link(
                    joint,
                    joint.child,
                    -1 if joint.parent == GROUND else index[joint.parent],
                    E,
                    r,
                    S,
                    v_J,
                    None,
                    c_J,
                    _sx(spatial_inertia(body.mass, body.com, body.inertia)),
                    f_ext,
                    tau,
                    v_slice,
                )
            )
            index[joint.child] = len(self.links) - 1
        self.velocities: list[Any] = []
        for link in self.links:
            parent_v = ZERO6 if link.parent < 0 else self.velocities[link.parent]
            velocity = transform_motion(link.E, link.r, parent_v) + link.v_J
            link.c = link.c_J + motion_cross(velocity, link.v_J)
            self.velocities.append(velocity)

    def joint_forces(self) -> Any:
        """tau (nv): the joint forces of the model's joint springs and joint forces."""
        tau = ca.SX.zeros(self.nv)
        for link in self.links:
            if link.v_slice is not None:
                tau[link.v_slice] = link.tau
        return tau


def articulated_body_accelerations(tree: SpatialTree, tau: Any) -> Any:
    """v' (nv) by the articulated-body algorithm for joint forces ``tau`` (nv), O(n)."""
    links, V = tree.links, tree.velocities
    I_A = [link.inertia for link in links]
    p_A = [
        force_cross(V[i], ca.mtimes(link.inertia, V[i])) - link.f_ext
        for i, link in enumerate(links)
    ]
    U, D_inv_U, D_inv_u = [None] * len(links), [None] * len(links), [None] * len(links)
    for i in reversed(range(len(links))):
        link = links[i]
        if link.nv:
            U[i] = ca.mtimes(I_A[i], link.S)
            D = ca.mtimes(link.S.T, U[i])
            u = tau[link.v_slice] - ca.mtimes(link.S.T, p_A[i])
            if link.nv == 1:
                D_inv_U[i], D_inv_u[i] = U[i].T / D, u / D
            else:
                solution = ca.solve(D, ca.horzcat(U[i].T, u))
                D_inv_U[i], D_inv_u[i] = solution[:, :6], solution[:, 6]
            I_a = articulated_update(I_A[i], U[i], D_inv_U[i])
            p_a = p_A[i] + ca.mtimes(I_a, link.c) + ca.mtimes(U[i], D_inv_u[i])
        else:
            I_a, p_a = I_A[i], p_A[i] + ca.mtimes(I_A[i], link.c)
        if link.parent >= 0:
            I_A[link.parent] = I_A[link.parent] + congruence(link.E, link.r, I_a)
            p_A[link.parent] = p_A[link.parent] + transform_force_back(link.E, link.r, p_a)
    accelerations = ca.SX.zeros(tree.nv)
    a: list[Any] = []
    for i, link in enumerate(links):
        parent_a = tree.base_acceleration if link.parent < 0 else a[link.parent]
        a_i = transform_motion(link.E, link.r, parent_a) + link.c
        if link.nv:
            vdot = D_inv_u[i] - ca.mtimes(D_inv_U[i], a_i)
            accelerations[link.v_slice] = vdot
            a_i = a_i + ca.mtimes(link.S, vdot)
        a.append(a_i)
    return accelerations


def recursive_newton_euler(tree: SpatialTree, vdot: Any) -> Any:
    """tau = M v' + h - Q (nv): joint forces that, added to the model's, give ``vdot``, O(n).

    With vdot = 0 it is h - Q: gyroscopic and centrifugal terms minus applied forces.
    """
    links, V = tree.links, tree.velocities
    forces: list[Any] = []
    a: list[Any] = []
    for i, link in enumerate(links):
        parent_a = tree.base_acceleration if link.parent < 0 else a[link.parent]
        a_i = transform_motion(link.E, link.r, parent_a) + link.c
        if link.nv:
            a_i = a_i + ca.mtimes(link.S, vdot[link.v_slice])
        a.append(a_i)
        momentum = ca.mtimes(link.inertia, V[i])
        forces.append(ca.mtimes(link.inertia, a_i) + force_cross(V[i], momentum) - link.f_ext)
    tau = ca.SX.zeros(tree.nv)
    for i in reversed(range(len(links))):
        link = links[i]
        if link.nv:
            tau[link.v_slice] = ca.mtimes(link.S.T, forces[i]) - link.tau
        if link.parent >= 0:
            forces[link.parent] = forces[link.parent] + transform_force_back(
                link.E, link.r, forces[i]
            )
    return tau


def composite_rigid_body_mass(tree: SpatialTree) -> Any:
    """M (nv, nv) by the composite-rigid-body algorithm, O(n d) for tree depth d."""
    links = tree.links
    I_C = [link.inertia for link in links]
    for i in reversed(range(len(links))):
        link = links[i]
        if link.parent >= 0:
            I_C[link.parent] = I_C[link.parent] + congruence(link.E, link.r, I_C[i])
    mass = ca.SX.zeros(tree.nv, tree.nv)
    for i, link in enumerate(links):
        if not link.nv:
            continue
        F = ca.mtimes(I_C[i], link.S)
        mass[link.v_slice, link.v_slice] = ca.mtimes(link.S.T, F)
        j = i
        while links[j].parent >= 0:
            F = (
                transform_force_back(links[j].E, links[j].r, F)
                if F.size2() == 1
                else ca.mtimes(plucker(links[j].E, links[j].r).T, F)
            )
            j = links[j].parent
            if links[j].nv:
                block = ca.mtimes(F.T, links[j].S)
                mass[link.v_slice, links[j].v_slice] = block
                mass[links[j].v_slice, link.v_slice] = block.T
    return mass


# ---- the formalism --------------------------------------------------------------------


@dataclass(frozen=True)
class RecursiveOptions(ConstraintOptions):
    algorithm: Literal["aba", "rnea-crba"] = "aba"


def recursive_mechanical_system(
    model: Model, kinematics: TreeKinematics, algorithm: str = "aba"
) -> MechanicalSystem:
    """M (CRBA), Q - h (RNEA), constraints, and v' by ABA (``algorithm="aba"``)."""
    k = kinematics
    tree = SpatialTree(model, k)
    mass = composite_rigid_body_mass(tree)
    forces = -recursive_newton_euler(tree, ca.SX.zeros(k.nv))
    acceleration = None
    if algorithm == "aba":
        acceleration = articulated_body_accelerations(tree, tree.joint_forces())
    return joint_space_system(k, mass, forces, acceleration)


def ode_function(model: Model, algorithm: str = "aba") -> ca.Function:
    """f(t, y) = [q'; v'] of the tree (closure constraints ignored): the ode right-hand
    side exactly as :func:`build_equations` builds it, without the other forms (for
    benchmarks of large models)."""
    k = TreeKinematics(model.validate())
    tree = SpatialTree(model, k)
    if algorithm == "aba":
        acceleration = articulated_body_accelerations(tree, tree.joint_forces())
    else:
        mass = composite_rigid_body_mass(tree)
        acceleration = ca.solve(mass, -recursive_newton_euler(tree, ca.SX.zeros(k.nv)))
    y = ca.vertcat(k.q, k.v)
    return ca.Function("ode_rhs", [k.t, y], [ca.densify(ca.vertcat(k.qdot, acceleration))])


def _numeric_tree(model: Model) -> tuple[TreeKinematics, SpatialTree]:
    kinematics = TreeKinematics(model.validate())
    return kinematics, SpatialTree(model, kinematics)


def _check_size(name: str, value: Any, size: int) -> np.ndarray:
    array = np.asarray(value, dtype=float).reshape(-1)
    if array.shape != (size,):
        raise ValueError(f"{name}: expected {size} components, got {array.size}")
    return array


def inverse_dynamics(model: Model, q: Any, v: Any, a: Any, t: float = 0.0) -> np.ndarray:
    """tau (nv) = M(q) a + h(t, q, v) - Q(t, q, v) by recursive Newton-Euler.

    q (nq), v (nv), a (nv): free tree-joint coordinates, velocities and accelerations
    (as :class:`~workbench.mechanics.kinematics.TreeKinematics` orders them). tau: the joint forces
    to add to the model's applied forces so that v' = a.
    """
    k, tree = _numeric_tree(model)
    a_sym = ca.SX.sym("a", k.nv)
    f = ca.Function("rnea", [k.t, k.q, k.v, a_sym], [recursive_newton_euler(tree, a_sym)])
    args = (_check_size("q", q, k.nq), _check_size("v", v, k.nv), _check_size("a", a, k.nv))
    return np.asarray(f(t, *args), dtype=float).reshape(-1)


def forward_dynamics(
    model: Model, q: Any, v: Any, tau: Any = None, t: float = 0.0, algorithm: str = "aba"
) -> np.ndarray:
    """v' (nv) under the model's forces plus joint forces ``tau`` (nv, default 0).

    ``algorithm``: "aba" (articulated bodies) or "rnea-crba" (M by CRBA, h by RNEA).
    """
    k, tree = _numeric_tree(model)
    tau_sym = ca.SX.sym("tau", k.nv)
    if algorithm == "aba":
        vdot = articulated_body_accelerations(tree, tree.joint_forces() + tau_sym)
    else:
        mass = composite_rigid_body_mass(tree)
        vdot = ca.solve(mass, tau_sym - recursive_newton_euler(tree, ca.SX.zeros(k.nv)))
    f = ca.Function("fd", [k.t, k.q, k.v, tau_sym], [vdot])
    tau = np.zeros(k.nv) if tau is None else _check_size("tau", tau, k.nv)
    args = (_check_size("q", q, k.nq), _check_size("v", v, k.nv), tau)
    return np.asarray(f(t, *args), dtype=float).reshape(-1)


@formalism
class Recursive(Formalism):
    name = "recursive"
    summary = "Joint coordinates, articulated-body recursion without a mass matrix, O(n) (10.6)"
    Options = RecursiveOptions
    capabilities = frozenset({"planar", "spatial", "closed-loops", "rheonomic", "point-masses"})

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        options = cls.parse_options(options)
        return {"ode": 0, "dae": options.index, "mechanical": 0}

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        kinematics = TreeKinematics(model)
        system = recursive_mechanical_system(model, kinematics, options.algorithm)
        notes = []
        if system.n_constraints:
            notes.append(
                "closed loops: M by CRBA and h by RNEA, accelerations from the augmented "
                "system (O(n^3)); the ode form is index 1 with Baumgarte stabilization"
            )
        return build_joint_space_equations(
            self.name, model, kinematics, system, options, ode=True, notes=notes
        )
