"""Formalism ``recursive``: articulated-body forward dynamics in O(n) (book 10.6, 11.4.2).

The generalized coordinates are the free joint coordinates of the spanning tree, as in
``minimal-ode`` (same q, v, same joint-space map). The accelerations come from recursions
over the tree (the book's recursive formalism, 10.6.1 for a chain, 10.6.2 for a tree, in
Featherstone's spatial notation), with no mass matrix formed.

Notation. Body i has the parent body lambda(i) (the ground has velocity 0 and the
acceleration a_0 = [0; -g], so gravity needs no force of its own). X_i is the Pluecker
transform from lambda(i)'s coordinates to i's; S_i (6, n_i) the motion subspace of joint
i, v_i (n_i) its velocities, v_J,i = S_i v_i the joint twist and c_J,i its
velocity-product term; I_i the spatial inertia of body i, f^x_i the applied forces on it,
tau_i the joint forces. Spatial vectors are motion [angular; linear] and force
[moment; force] (:mod:`workbench.numerics.spatial`), each body's in the coordinates of its
joint frame J_i about J_i's origin (:func:`joint_frame`).

Computational frames. J_i is fixed to body i and chosen numerically at build time, before
any symbol exists: the joint's child frame C_i, turned for a revolute, prismatic or
cylindrical joint so that its axis is z. Then S_i is a constant unit column (e_z; [1; 0]
for a spherical joint, whose velocities are its angular velocity in C_i) and c_J,i = 0,
X_i is a constant placement (the parent's J, the joint frame P, the axis turn, folded into
numbers) times a rotation about z (4 trigonometric products), and the inertias are
turned into J_i numerically. Geometry then costs what Pinocchio's does, a fixed price a
link: 53,978 -> 25,909 CasADi instructions on a random 30-body tree of every joint type
(2026-11-24; docs/performance.md). A free joint (J_i = C) has S and c_J written out, and
the articulated-body algorithm takes it in Pinocchio's free-flyer velocities
[R^T p'; omega], in which S is constant (:class:`LocalVelocities`).

Articulated-body algorithm (forward dynamics, v' for given tau):

1. outward  V_i = X_i V_lambda(i) + v_J,i,  c_i = c_J,i + V_i x v_J,i,
            I^A_i = I_i,  p^A_i = V_i x* I_i V_i - f^x_i;
2. inward   U_i = I^A_i S_i,  D_i = S_i^T U_i,  u_i = tau_i - S_i^T p^A_i,
            I^a_i = I^A_i - U_i D_i^-1 U_i^T,  p^a_i = p^A_i + I^a_i c_i + U_i D_i^-1 u_i,
            I^A_lambda(i) += X_i^T I^a_i X_i,  p^A_lambda(i) += X_i^T p^a_i;
3. outward  a'_i = X_i a_lambda(i) + c_i,  v'_i = D_i^-1 (u_i - U_i^T a'_i),
            a_i = a'_i + S_i v'_i.

Operations the mathematics does not need are left out: p^A_i through the centre of mass
(:func:`~workbench.numerics.spatial.rigid_bias_force`); for S_i of unit columns e_k (a
joint in its own frame) the columns k of D_i^-1 U_i^T are exact ones, and a_i differs
from a'_i only in rows k, where a'_i,k cancels (:func:`_unit_joint_accelerations`);
symmetric inertias summed on one triangle.

Recursive Newton-Euler (inverse dynamics, tau for given v'): outward
a_i = X_i a_lambda(i) + S_i v'_i + c_i and f_i = I_i a_i + V_i x* I_i V_i - f^x_i; inward
tau_i = S_i^T f_i and f_lambda(i) += X_i^T f_i. Composite rigid bodies (the mass matrix):
inward I^C_lambda(i) += X_i^T I^C_i X_i from I^C_i = I_i; then M_ii = S_i^T I^C_i S_i and,
walking from i to the root with F = I^C_i S_i, F <- X_j^T F, M_ij = F^T S_j.

The joint model (:func:`joint_model`, Featherstone's jcalc) gives X_i, S_i, v_J,i and
c_J,i of every joint type from the one joint dispatch of :mod:`workbench.mechanics.joints`.
Applied forces: body wrenches of :func:`workbench.mechanics.forces.body_wrenches`
(springs, applied forces) are f^x_i; joint springs and forces are tau_i. A driven
(rheonomic) joint has its acceleration prescribed: S_i v_drive' is part of c_J,i, and the
joint has no unknown (n_i = 0).

The mechanical form also needs M and Q - h: M by composite rigid bodies (CRBA), h - Q by
recursive Newton-Euler (RNEA) at v' = 0. Option ``algorithm="rnea-crba"`` uses these
for the accelerations too (v' = M^-1 (Q - h), O(n^3) in the symbolic solve) for
comparison. Closed loops (book 11.4.2): the tree is cut at the loop-closing joints; the
constrained equations M v' = Q - h - W^T lambda use CRBA and RNEA (each O(n^2) / O(n)),
and the augmented solve of :func:`~workbench.equations.build_equations` is O(n^3): only
the unconstrained ode right-hand side is O(n). The ode form of a constrained model is the
index-1 system with Baumgarte stabilization.

Contacts (docs/nonsmooth.md): the contact form (gaps, their Jacobians W_N, W_T, joint
rates W_F) is the core's (:mod:`workbench.equations.contacts`), built by
:func:`~workbench.equations.build_equations` on the tree's body states, the same as
minimal-ode's; the contact integrators take M (CRBA) and Q - h (RNEA) from the mechanical
form.

All symbolic graphs are CasADi SX without expansion, so common subexpressions stay
shared and the ABA graph has O(n) instructions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

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
from workbench.numerics.spatial import (
    articulated_update,
    congruence,
    force_cross,
    motion_cross,
    rigid_bias_force,
    rotate_z_inertia,
    spatial_inertia,
    symmetric,
    symmetric_sum,
    transform_force_back,
    transform_motion,
)
from workbench.plugin.formalism import ConstraintOptions, Formalism
from workbench.plugin.registry import formalism

ZERO6 = ca.SX.zeros(6, 1)
TURN_MAX_NONZEROS = 5  # a revolute joint's congruence turns first (:class:`Turn`) up to these


def _sx(value: Any) -> Any:
    return value if isinstance(value, ca.SX) else ca.SX(ca.DM(np.asarray(value, dtype=float)))


# ---- joint frames and the joint model (Featherstone's jcalc) ----------------------------


def _snap(matrix: Any) -> np.ndarray:
    """A numeric matrix with round-off zeros (|x| < 1e-14) made exact, so that products
    with symbols skip them (CasADi drops x * 0 and x * 1 when it builds a graph)."""
    matrix = np.array(matrix, dtype=float)
    matrix[np.abs(matrix) < 1e-14] = 0.0
    return matrix


def axis_frame(axis: Any) -> np.ndarray:
    """A rotation A (3, 3) whose z column is the unit ``axis``: exact (a signed permutation)
    for a coordinate axis, so aligned joints keep their structural zeros."""
    z = jk.unit(axis)
    k = int(np.argmax(np.abs(z)))
    if np.count_nonzero(z) == 1:
        x = np.eye(3)[(k + 1) % 3]
    else:
        x = np.cross(np.eye(3)[int(np.argmin(np.abs(z)))], z)
        x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


_AXIAL = ("revolute", "prismatic", "cylindrical")


Placement = tuple[np.ndarray, np.ndarray]  # (rotation (3, 3), origin (3)) of a frame


def _placement(joint: Joint, parent: Placement | None) -> tuple[Any, Any, Any, float]:
    """(L_R, L_r, A, d), all numeric: the joint frame P in the parent's joint frame
    (rotation L_R, origin L_r), the turn A (C to J, axis to z) and the slide d of J along
    a revolute axis that makes one coordinate of L_r zero (fewer products in X_i)."""
    J_R, J_p = parent if parent is not None else (np.eye(3), np.zeros(3))
    L_R = _snap(J_R.T @ joint.parent_frame.rotation)
    L_r = J_R.T @ (joint.parent_frame.position - J_p)
    A = axis_frame(joint.axis) if joint.type in _AXIAL else np.eye(3)
    d = 0.0
    if joint.type == "revolute":
        axis = L_R @ A[:, 2]
        k = int(np.argmax(np.abs(axis)))
        d = -L_r[k] / axis[k]
        L_r = L_r + d * axis
        L_r[k] = 0.0
    return L_R, _snap(L_r), A, d


def joint_frame(joint: Joint, parent: Placement | None = None) -> Placement:
    """(rotation (3, 3), origin (3)) of joint i's computational frame J_i in its child
    body's coordinates (``parent``: the parent's, None for the ground): the child frame C,
    turned for revolute, prismatic and cylindrical joints so that the axis is z, and slid
    along a revolute axis (:func:`_placement`). The recursions work in J_i, where the joint
    is simple: S_i is constant and sparse, X_i a constant placement times a rotation
    about z."""
    _, _, A, d = _placement(joint, parent)
    rotation, origin = joint.child_frame.rotation, joint.child_frame.position
    return _snap(rotation @ A), origin + d * (rotation @ A[:, 2])


def _unit_columns(rows: list[int]) -> Any:
    """S (6, len(rows)) with a structural 1 at (rows[k], k) and no other entries."""
    S = ca.SX(6, len(rows))
    for column, row in enumerate(rows):
        S[row, column] = 1
    return S


class JointMotion(NamedTuple):
    """What a tree joint contributes to the recursions, in joint-frame coordinates.

    E (3, 3), r (3): X_i, as rotation from the parent's joint frame J_lambda(i) to J_i
    coordinates and J_i's origin in J_lambda(i) coordinates. S (6, n): motion subspace, n
    the joint's unknown velocities (0 for fixed and driven joints). v_J (6): J_i's twist
    relative to the parent body, S v (the drive's for a driven joint). c_J (6): S' v, the
    rate of v_J at fixed v (plus S v_drive' for a driven joint).
    """

    E: Any
    r: Any
    S: Any
    v_J: Any
    c_J: Any
    local: LocalVelocities | None = None
    turn: Turn | None = None


class Turn(NamedTuple):
    """A revolute joint's X_i = X_z(q) X_F: the constant placement F (its rotation
    ``frame`` (3, 3) and the offset r, numbers) followed by the rotation about J_i's z
    axis by the joint angle (``cos``, ``sin``), so E = R_z(q)^T ``frame``. The
    articulated-body algorithm's congruence X_i^T I X_i turns I about z first
    (:func:`~workbench.numerics.spatial.rotate_z_inertia`) and then moves it by the
    numbers of F, whose zeros and unit entries (aligned axes) cost nothing."""

    cos: Any
    sin: Any
    frame: Any


class LocalVelocities(NamedTuple):
    """A joint whose S(q) = S_nu T(q) is not constant, seen by the articulated-body
    algorithm in the velocities nu = T v whose motion subspace S_nu (6, n) is constant
    unit columns (c_J = 0 in nu): a free joint, nu = [C's linear velocity; its angular
    velocity], both in C, as Pinocchio's free flyer. Then D = S_nu^T I^A S_nu is a block
    of I^A, with no symbolic congruence through S(q).

    ``tau``: tau -> tau_nu = T^-T tau (n); ``rates``: nu' -> v' = T^-1 (nu' - T' v) (n).
    """

    S: Any
    tau: Callable[[Any], Any]
    rates: Callable[[Any], Any]


def joint_model(
    joint: Joint, q: Any, v: Any, t: Any, parent: Placement | None = None
) -> JointMotion:
    """X_i, S_i, v_J,i, c_J,i of a tree joint at its coordinates q (nq), velocities v (nv)
    and time t, for every joint type, in the joint frames of :func:`joint_frame`.

    ``parent``: J_lambda(i) in the parent body's coordinates (None: the ground, whose
    frame is the world). The pose of J_i in J_lambda(i) is L M(q) A with L = J_lambda(i)^-1
    P constant (folded numerically here), M(q) the joint's relative pose of
    :func:`jk.relative_transform` and A = C^-1 J_i constant. For revolute, prismatic,
    cylindrical and spherical joints S_i is constant (e_z, or [1; 0] for a spherical joint,
    whose velocities are the angular velocity in C) and c_J,i = 0; the other types take S
    as the Jacobian of their twist in v and c_J as its derivative along q' = H(q) v.
    """
    nq, nv = jk.dimensions(joint)
    L_R, L_r, A, _ = _placement(joint, parent)
    kind = joint.type
    if nv == 0:  # fixed
        return JointMotion(_sx((L_R @ A).T), _sx(L_r), ca.SX(6, 0), ZERO6, ZERO6)
    q, v = _sx(q), _sx(v)
    axis = _snap(L_R @ A[:, 2]) if kind in ("prismatic", "cylindrical") else None
    turn = None
    if kind == "revolute":
        R_z, frame = _rotation_z(q[0]), _sx((L_R @ A).T)
        E = ca.mtimes(R_z.T, frame)
        # the turn first pays where the constant rotation is sparse (an axis permutation
        # or a turn about a coordinate axis: Talos 12,208 -> 11,191 instructions); with a
        # general one (a random tree's rotated frames) it cost 3 % more
        if np.count_nonzero(_snap(L_R @ A)) <= TURN_MAX_NONZEROS:
            turn = Turn(R_z[0, 0], R_z[1, 0], frame)
        r, S = _sx(L_r), _unit_columns([2])
    elif kind == "prismatic":
        E, r, S = _sx((L_R @ A).T), _sx(L_r) + _sx(axis) * q[0], _unit_columns([5])
    elif kind == "cylindrical":
        E = ca.mtimes(_rotation_z(q[1]).T, _sx((L_R @ A).T))
        r, S = _sx(L_r) + _sx(axis) * q[0], _unit_columns([5, 2])
    elif kind == "spherical":
        _, R_rel = jk.relative_transform(joint, q)
        E, r, S = ca.mtimes(_sx(R_rel).T, _sx(L_R.T)), _sx(L_r), _unit_columns([0, 1, 2])
    elif kind == "free" and joint.drive is None:
        return _free_joint_model(joint, q, v, L_R, L_r)
    else:
        return _general_joint_model(joint, q, v, t, L_R, L_r)
    v_J = ca.mtimes(S, v)
    if joint.drive is not None:
        # prescribed motion: its acceleration is known, so it moves into c_J
        _, _, a_drive = jk.drive_values(joint, t)
        return JointMotion(E, r, ca.SX(6, 0), v_J, ca.mtimes(S, _sx(a_drive)), turn=turn)
    return JointMotion(E, r, S, v_J, ZERO6, turn=turn)


def _rotation_z(angle: Any) -> Any:
    """R_z(angle) (3, 3): 4 trigonometric entries, a structural 1, no other entries."""
    c, s = ca.cos(angle), ca.sin(angle)
    R = ca.SX(3, 3)
    R[0, 0], R[0, 1], R[1, 0], R[1, 1], R[2, 2] = c, -s, s, c, 1
    return R


def _free_joint_model(
    joint: Joint, q: Any, v: Any, L_R: np.ndarray, L_r: np.ndarray
) -> JointMotion:
    """A free joint in J_i = C: v = [p'; omega] (p' the rate of C's origin in P, omega the
    angular velocity in C), so with R = R(Euler parameters) the twist is
    v_J = [omega; R^T p'], S = [0 1; R^T 0] and c_J = S' v = [0; -omega x R^T p']
    (R' = R omega~). The articulated-body algorithm takes nu = [R^T p'; omega]
    (:class:`LocalVelocities`): tau_nu = [R^T tau_p; tau_omega] and
    p'' = R (nu'_lin + omega x R^T p'), omega' = nu'_ang."""
    r_rel, R_rel = jk.relative_transform(joint, q)
    R = _sx(R_rel)
    E = ca.mtimes(R.T, _sx(L_R.T))
    r = _sx(L_r) + ca.mtimes(_sx(L_R), _sx(r_rel))
    omega, linear = v[3:6], ca.mtimes(R.T, v[0:3])
    v_J = ca.vertcat(omega, linear)
    S = ca.SX(6, 6)
    S[:3, 3:] = ca.SX.eye(3)
    S[3:, :3] = R.T
    c_J = ca.vertcat(ca.SX.zeros(3), -ca.cross(omega, linear))

    def tau(tau_v: Any) -> Any:
        return ca.vertcat(ca.mtimes(R.T, tau_v[0:3]), tau_v[3:6])

    def rates(nu_dot: Any) -> Any:
        return ca.vertcat(ca.mtimes(R, nu_dot[0:3] + ca.cross(omega, linear)), nu_dot[3:6])

    local = LocalVelocities(_unit_columns([3, 4, 5, 0, 1, 2]), tau, rates)
    return JointMotion(E, r, S, v_J, c_J, local)


def _general_joint_model(
    joint: Joint, q: Any, v: Any, t: Any, L_R: np.ndarray, L_r: np.ndarray
) -> JointMotion:
    """The joint model from the one joint dispatch, J_i = C (universal, planar, free): the
    twist of C relative to P in C coordinates, S its Jacobian in v, c_J its rate."""
    nq, nv = jk.dimensions(joint)
    qs, u = ca.SX.sym("qs", nq), ca.SX.sym("u", nv)
    r_rel, R_rel = jk.relative_transform(joint, qs)
    v_rel, w_rel = jk.relative_twist(joint, qs, u)
    R_rel = _sx(R_rel)
    E = ca.mtimes(R_rel.T, _sx(L_R.T))
    r = _sx(L_r) + ca.mtimes(_sx(L_R), _sx(r_rel))
    xi = ca.vertcat(ca.mtimes(R_rel.T, _sx(w_rel)), ca.mtimes(R_rel.T, _sx(v_rel)))
    S = ca.jacobian(xi, u)
    c_J = ca.mtimes(ca.jacobian(xi, qs), _sx(jk.coordinate_rates(joint, qs, u)))
    E, r, S, c_J = ca.substitute([E, r, S, c_J], [qs, u], [_sx(q), _sx(v)])
    v_J = ca.mtimes(S, _sx(v))
    if joint.drive is not None:
        _, _, a_drive = jk.drive_values(joint, t)
        return JointMotion(E, r, ca.SX(6, 0), v_J, c_J + ca.mtimes(S, _sx(a_drive)))
    return JointMotion(E, r, S, v_J, c_J)


# ---- the tree in spatial notation -------------------------------------------------------


@dataclass
class Link:
    """Tree joint i and its child body, with everything the recursions need."""

    joint: Joint
    body: str
    parent: int  # lambda(i): index of the parent link, -1 for the ground
    E: Any  # X_i: rotation (3, 3) ...
    r: Any  # ... and offset (3), see JointMotion
    S: Any  # (6, n_i); n_i = 0 for driven and fixed joints
    v_J: Any  # (6,)
    c_J: Any  # (6,)
    inertia: Any  # I_i (6, 6): spatial inertia about J_i's origin, J_i coordinates
    f_ext: Any  # f^x_i (6,): applied force on the body, J_i coordinates
    tau: Any  # (n_i,) the model's joint forces
    v_slice: slice | None  # the joint's velocities in v (None if driven or fixed)
    local: LocalVelocities | None = None  # ABA's velocities nu = T v (free joints)
    turn: Turn | None = None  # X_i = X_z(q) X_F of a revolute joint
    body_parts: tuple[float, np.ndarray, np.ndarray] | None = None  # m, c, I_c: I_i's

    def bias_force(self, V: Any) -> Any:
        """V x* I_i V (6): the body's velocity-product force at its velocity V (6),
        through its centre of mass (:func:`~workbench.numerics.spatial.rigid_bias_force`:
        36 products against 42 through I_i V)."""
        if self.body_parts is None:
            return force_cross(V, ca.mtimes(self.inertia, V))
        return rigid_bias_force(*self.body_parts, V)

    def congruence(self, inertia: Any) -> Any:
        """X_i^T I X_i (6, 6) for a symmetric I in J_i coordinates: I in the parent's
        joint frame (a revolute joint's turned about z first, :class:`Turn`)."""
        if self.turn is None:
            return congruence(self.E, self.r, inertia)
        turned = rotate_z_inertia(self.turn.cos, self.turn.sin, inertia)
        return congruence(self.turn.frame, self.r, turned)

    @property
    def nv(self) -> int:
        return 0 if self.v_slice is None else self.v_slice.stop - self.v_slice.start


class SpatialTree:
    """The tree of ``model`` in spatial notation at symbolic (t, q, v).

    ``links`` in parents-first order, each with its joint model (X_i, S_i, v_J,i, c_J,i),
    body inertia I_i, applied force f^x_i and joint forces; ``base_acceleration``
    a_0 = [0; -g] (6,): gravity as an upward acceleration of the ground, so ``f_ext``
    holds only the other applied wrenches (:func:`~workbench.mechanics.forces.body_wrenches`
    without gravity, from the world poses of ``kinematics.bodies``).
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
        frames: dict[str, Placement] = {}  # J_i in body coordinates
        self.links: list[Link] = []
        for joint in k.order:
            q_j, v_j = joint_coordinates[joint.name]
            X = joint_model(joint, q_j, v_j, k.t, frames.get(joint.parent))
            frames[joint.child] = J_R, J_p = joint_frame(joint, frames.get(joint.parent))
            v_slice = k.joint_slices[joint.name][1] if X.S.size2() else None
            body = model.bodies[joint.child]
            com = _snap(J_R.T @ (np.asarray(body.com, dtype=float) - J_p))
            com_inertia = _snap(J_R.T @ body.inertia @ J_R)
            inertia = spatial_inertia(body.mass, com, com_inertia)
            rotation = k.bodies[joint.child].rotation
            force, torque = wrenches[joint.child]
            force = ca.mtimes(rotation.T, force)
            torque = ca.mtimes(rotation.T, torque) - ca.cross(_sx(J_p), force)
            f_ext = ca.vertcat(ca.mtimes(_sx(J_R.T), torque), ca.mtimes(_sx(J_R.T), force))
            tau = joint_forces.get(joint.name, 0) if v_slice is not None else 0
            tau = _sx(tau) if not isinstance(tau, int) else ca.SX.zeros(X.S.size2())
            self.links.append(
                Link(
                    joint=joint,
                    body=joint.child,
                    parent=-1 if joint.parent == GROUND else index[joint.parent],
                    E=X.E,
                    r=X.r,
                    S=X.S,
                    v_J=X.v_J,
                    c_J=X.c_J,
                    inertia=_sx(_snap(inertia)),
                    f_ext=f_ext,
                    tau=tau,
                    v_slice=v_slice,
                    local=X.local,
                    turn=X.turn,
                    body_parts=(float(body.mass), com, com_inertia),
                )
            )
            index[joint.child] = len(self.links) - 1

    def joint_forces(self) -> Any:
        """tau (nv): the joint forces of the model's joint springs and joint forces."""
        tau = ca.SX.zeros(self.nv)
        for link in self.links:
            if link.v_slice is not None:
                tau[link.v_slice] = link.tau
        return tau


# ---- articulated-body algorithm (forward dynamics) -------------------------------------


def _unit_rows(S: Any) -> tuple[int, ...]:
    """k of every column e_k of S (6, n) if all of its columns are unit vectors, else ()."""
    rows = []
    for column in range(S.size2()):
        entries = S[:, column]
        if entries.nnz() != 1 or not entries.nonzeros()[0].is_one():
            return ()
        rows.append(entries.sparsity().row()[0])
    return tuple(rows)


def _reciprocal(x: Any) -> Any:
    """1 / x as a value to multiply by: one division for many products (a division costs
    several multiplications). Written 2 / (x + x) because CasADi turns y * (1 / x) back
    into y / x; doubling is exact, so this is 1 / x to the last bit."""
    return 2 / (x + x)


def _solve_symmetric(D: Any, B: Any) -> Any:
    """D^-1 B for a symmetric positive definite D (n, n) without a linear-solve node: a
    division for n = 1, cofactors for n = 2, 3 (a spherical joint's 3 x 3 articulated
    block), else D = L diag(d) L^T eliminated entry by entry (a free joint's 6 x 6)."""
    n = D.size1()
    if n == 1:
        return B * _reciprocal(D)  # one division, then products
    if n == 2:
        inverse = ca.vertcat(ca.horzcat(D[1, 1], -D[0, 1]), ca.horzcat(-D[0, 1], D[0, 0]))
        return ca.mtimes(inverse * _reciprocal(D[0, 0] * D[1, 1] - D[0, 1] * D[0, 1]), B)
    if n == 3:
        cofactor = symmetric(
            lambda i, j: (
                D[(i + 1) % 3, (j + 1) % 3] * D[(i + 2) % 3, (j + 2) % 3]
                - D[(i + 1) % 3, (j + 2) % 3] * D[(i + 2) % 3, (j + 1) % 3]
            ),
            3,
        )
        return ca.mtimes(cofactor * _reciprocal(ca.dot(D[0, :].T, cofactor[:, 0])), B)
    # W = L diag(d) column by column (W_jj = d_j), so each update is one product
    W, L, d_inv = [[None] * n for _ in range(n)], [[None] * n for _ in range(n)], [None] * n
    for j in range(n):
        for i in range(j, n):
            W[i][j] = D[i, j] - sum((W[i][k] * L[j][k] for k in range(j)), ca.SX(0))
        d_inv[j] = _reciprocal(W[j][j])
        for i in range(j + 1, n):
            L[i][j] = W[i][j] * d_inv[j]
    x = [B[j, :] for j in range(n)]
    for j in range(n):  # L y = B
        x[j] = x[j] - sum((L[j][k] * x[k] for k in range(j)), ca.SX.zeros(1, B.size2()))
    for j in reversed(range(n)):  # diag(d) L^T x = y
        x[j] = x[j] * d_inv[j] - sum(
            (L[k][j] * x[k] for k in range(j + 1, n)), ca.SX.zeros(1, B.size2())
        )
    return ca.vertcat(*x)


def _other_rows(rows: tuple[int, ...]) -> list[int]:
    """The rows of a spatial vector (6) that are not in ``rows``."""
    return [k for k in range(6) if k not in rows]


def _joint_solve(D: Any, U: Any, u: Any, rows: tuple[int, ...]) -> tuple[Any, Any]:
    """(D^-1 U^T (n, 6), D^-1 u (n)) of a joint with D = S^T U (n, n), U = I^A S (6, n),
    u (n). Where S's columns are unit vectors e_k (``rows``: the k), U's rows k are D, so
    D^-1 U^T has unit columns there: exact ones and zeros, not solved for."""
    others = _other_rows(rows)
    D_inv = _solve_symmetric(D, ca.horzcat(U[others, :].T, u))
    D_inv_U = ca.SX(D.size1(), 6)
    D_inv_U[:, others] = D_inv[:, :-1]
    for column, row in enumerate(rows):
        D_inv_U[column, row] = 1
    return D_inv_U, D_inv[:, -1]


def _unit_joint_accelerations(a_prime: Any, a_rows: Any, rows: tuple[int, ...]) -> tuple[Any, Any]:
    """(a_i (6), v'_i (n)) of a joint whose S has unit columns e_k (``rows``: the k), from
    a' (6) and ``a_rows`` (n), a_i's rows k. a_i = a' + S v' differs from a' only in rows
    k, and v' = D^-1 (u - U^T a') where U's rows k are D: so a_i,k = D^-1 (u - U_o^T a'_o)
    over the other rows o (a'_k cancels, and a free base's U^T a' is not formed at all),
    and v' = a_i,k - a'_k."""
    a = ca.SX(a_prime)
    for column, row in enumerate(rows):
        a[row] = a_rows[column]
    return a, a_rows - a_prime[list(rows)]


def _aba_subspace(link: Link) -> Any:
    """The motion subspace the articulated-body algorithm works with: S_nu of a joint's
    local velocities (:class:`LocalVelocities`), else S."""
    return link.local.S if link.local else link.S


def articulated_body_accelerations(tree: SpatialTree, tau: Any) -> Any:
    """v' (nv) by the articulated-body algorithm for joint forces ``tau`` (nv), O(n).

    The three passes of the module docstring; ``tau`` replaces the model's joint forces
    (pass ``tree.joint_forces()`` for those).
    """
    links = tree.links
    n = len(links)
    V, c, I_A, p_A = [None] * n, [None] * n, [None] * n, [None] * n

    # 1. outward: velocities, velocity-product accelerations, rigid-body inertias and biases
    for i, link in enumerate(links):
        V_parent = ZERO6 if link.parent < 0 else V[link.parent]
        V[i] = transform_motion(link.E, link.r, V_parent) + link.v_J
        c_J = ZERO6 if link.local else link.c_J  # c_J = 0 in a joint's local velocities
        # a root's V_i is v_J,i, and v x v = 0: CasADi would not see it for a free joint
        c[i] = c_J if link.parent < 0 else c_J + motion_cross(V[i], link.v_J)
        I_A[i] = link.inertia
        p_A[i] = link.bias_force(V[i]) - link.f_ext

    # 2. inward: articulated inertias and bias forces, each handed to the parent (a root
    # hands nothing on: its D_i and u_i are kept for pass 3, I^a_i is not formed)
    U, D_inv_U, D_inv_u, rows = [None] * n, [None] * n, [None] * n, [()] * n
    root_D, root_u = {}, {}
    for i in reversed(range(n)):
        link, S = links[i], _aba_subspace(links[i])
        if link.nv:
            U[i] = ca.mtimes(I_A[i], S)
            D = ca.mtimes(S.T, U[i])
            tau_i = link.local.tau(tau[link.v_slice]) if link.local else tau[link.v_slice]
            u = tau_i - ca.mtimes(S.T, p_A[i])
            rows[i] = _unit_rows(S)
            if link.parent < 0:
                root_D[i], root_u[i] = D, u
                continue
            D_inv_U[i], D_inv_u[i] = _joint_solve(D, U[i], u, rows[i])
            I_a = articulated_update(I_A[i], U[i], D_inv_U[i], rows[i])
            p_a = p_A[i] + ca.mtimes(I_a, c[i]) + ca.mtimes(U[i], D_inv_u[i])
            for column, row in enumerate(rows[i]):  # S^T p^a = tau exactly
                p_a[row] = tau_i[column]
        else:  # no unknown (fixed or driven joint): the whole inertia passes to the parent
            I_a, p_a = I_A[i], p_A[i] + ca.mtimes(I_A[i], c[i])
        if link.parent >= 0:
            I_A[link.parent] = symmetric_sum(I_A[link.parent], link.congruence(I_a))
            p_A[link.parent] = p_A[link.parent] + transform_force_back(link.E, link.r, p_a)

    # 3. outward: accelerations
    vdot = ca.SX.zeros(tree.nv)
    a = [None] * n
    for i, link in enumerate(links):
        a_parent = tree.base_acceleration if link.parent < 0 else a[link.parent]
        a_prime = transform_motion(link.E, link.r, a_parent) + c[i]
        if link.nv:
            if rows[i]:  # S's columns are unit vectors e_k: a_i differs from a' in rows k only
                others = _other_rows(rows[i])
                if i in root_D:
                    rest = root_u[i] - ca.mtimes(U[i][others, :].T, a_prime[others])
                    a_rows = _solve_symmetric(root_D[i], rest)
                else:
                    a_rows = D_inv_u[i] - ca.mtimes(D_inv_U[i][:, others], a_prime[others])
                a[i], vdot_i = _unit_joint_accelerations(a_prime, a_rows, rows[i])
            else:
                if i in root_D:
                    vdot_i = _solve_symmetric(root_D[i], root_u[i] - ca.mtimes(U[i].T, a_prime))
                else:
                    vdot_i = D_inv_u[i] - ca.mtimes(D_inv_U[i], a_prime)
                a[i] = a_prime + ca.mtimes(_aba_subspace(link), vdot_i)
            vdot[link.v_slice] = link.local.rates(vdot_i) if link.local else vdot_i
        else:
            a[i] = a_prime
    return vdot


# ---- recursive Newton-Euler (inverse dynamics) -----------------------------------------


def recursive_newton_euler(tree: SpatialTree, vdot: Any) -> Any:
    """tau = M v' + h - Q (nv): joint forces that, added to the model's, give ``vdot``
    (nv), O(n).

    With vdot = 0 it is h - Q: gyroscopic and centrifugal terms minus applied forces.
    """
    links = tree.links
    n = len(links)
    V, a, f = [None] * n, [None] * n, [None] * n

    # outward: velocities, accelerations and the force each body needs for them
    for i, link in enumerate(links):
        if link.parent < 0:
            V_parent, a_parent = ZERO6, tree.base_acceleration
        else:
            V_parent, a_parent = V[link.parent], a[link.parent]
        V[i] = transform_motion(link.E, link.r, V_parent) + link.v_J
        c_i = link.c_J + motion_cross(V[i], link.v_J)
        a[i] = transform_motion(link.E, link.r, a_parent) + c_i
        if link.nv:
            a[i] = a[i] + ca.mtimes(link.S, vdot[link.v_slice])
        I = link.inertia
        f[i] = ca.mtimes(I, a[i]) + link.bias_force(V[i]) - link.f_ext

    # inward: joint forces, and each body's force handed to its parent
    tau = ca.SX.zeros(tree.nv)
    for i in reversed(range(n)):
        link = links[i]
        if link.nv:
            tau[link.v_slice] = ca.mtimes(link.S.T, f[i]) - link.tau
        if link.parent >= 0:
            f[link.parent] = f[link.parent] + transform_force_back(link.E, link.r, f[i])
    return tau


# ---- composite rigid bodies (mass matrix) ----------------------------------------------


def composite_rigid_body_mass(tree: SpatialTree) -> Any:
    """M (nv, nv) by the composite-rigid-body algorithm, O(n d) for tree depth d."""
    links = tree.links

    # inward: composite inertias of the subtrees
    I_C = [link.inertia for link in links]
    for i in reversed(range(len(links))):
        link = links[i]
        if link.parent >= 0:
            I_C[link.parent] = I_C[link.parent] + link.congruence(I_C[i])

    # each joint i against itself and every joint j on its path to the root
    M = ca.SX.zeros(tree.nv, tree.nv)
    for i, link in enumerate(links):
        if not link.nv:
            continue
        F = ca.mtimes(I_C[i], link.S)
        M[link.v_slice, link.v_slice] = ca.mtimes(link.S.T, F)
        j = i
        while links[j].parent >= 0:
            F = transform_force_back(links[j].E, links[j].r, F)
            j = links[j].parent
            if links[j].nv:
                M_ij = ca.mtimes(F.T, links[j].S)
                M[link.v_slice, links[j].v_slice] = M_ij
                M[links[j].v_slice, link.v_slice] = M_ij.T
    return M


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


def ode_function(model: Model, algorithm: str = "aba", kernels: bool | None = False) -> ca.Function:
    """f(t, y) = [q'; v'] of the tree (closure constraints ignored): the ode right-hand
    side exactly as :func:`build_equations` builds it, without the other forms (for
    benchmarks of large models). ``kernels``: True, the graph of joint-type kernels
    (:mod:`~workbench.plugins.formalisms.recursive_kernels`); None, the graph a compiled
    build compiles (kernels above their size threshold); False, the unrolled graph."""
    from workbench.plugins.formalisms import recursive_kernels

    k = TreeKinematics(model.validate())
    tree = SpatialTree(model, k)
    if algorithm == "aba":
        acceleration = articulated_body_accelerations(tree, tree.joint_forces())
    else:
        mass = composite_rigid_body_mass(tree)
        acceleration = ca.solve(mass, -recursive_newton_euler(tree, ca.SX.zeros(k.nv)))
    y = ca.vertcat(k.q, k.v)
    unrolled = ca.Function("ode_rhs", [k.t, y], [ca.densify(ca.vertcat(k.qdot, acceleration))])
    if kernels is None and algorithm == "aba":
        kernels = recursive_kernels.use_kernels(model, unrolled.n_instructions())
    return recursive_kernels.ode_function_kernels(model) if kernels else unrolled


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
    capabilities = frozenset(
        {"planar", "spatial", "closed-loops", "rheonomic", "point-masses", "contacts"}
    )  # the contact form comes from build_equations, on the tree's body states

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
            self.name, model, kinematics, system, options, ode=True, notes=notes,
            ode_rhs_for_c=self._kernels_for_c(model, kinematics, system, options),
        )  # fmt: skip

    @staticmethod
    def _kernels_for_c(
        model: Model, kinematics: TreeKinematics, system: MechanicalSystem, options: Any
    ) -> Callable[[Any, Any], Any] | None:
        """The joint-type kernels' graph of the ode right-hand side, to compile in place of
        the unrolled one when that is too large to stay in cache (None otherwise): the VM
        keeps the unrolled graph (:mod:`~workbench.plugins.formalisms.recursive_kernels`)."""
        from workbench.plugins.formalisms import recursive_kernels

        if getattr(options, "compile", "none") == "none" or system.acceleration is None:
            return None
        if system.n_constraints:
            return None
        k = kinematics
        size = ca.Function("aba", [k.t, k.q, k.v], [system.acceleration]).n_instructions()
        if not recursive_kernels.use_kernels(model, size):
            return None
        return lambda t, y: recursive_kernels.ode_rhs_kernels(model, k, t, y)
