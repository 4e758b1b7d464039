"""Formalism ``absolute-dae``: absolute body coordinates and implicit joint constraints.

Book 5.6.1 (point masses), 6.6.1 (planar), 7.6.1 (spatial), 8.2.1 (nonholonomic). Every
body gets its own coordinates, independent of the joints:

* planar model: q_b = (x, y, angle), v_b = (x', y', angle');
* spatial model: q_b = (r (3), p (4)), the body frame origin in the inertial frame and
  Euler parameters (scalar first); v_b = (r' (3), omega_b (3)), with omega_b the angular
  velocity in the *body* frame, and q_b' = (r', H(p) omega_b), H from
  :func:`workbench.numerics.rotations.quaternion_rate_matrix` (p, "body").

The Newton-Euler equations of each body (:mod:`workbench.mechanics.newton_euler`, shared
with minimal-ode and nonholonomic-projection), through the Jacobians
J_T = d v_com / d v and J_R = d omega / d v of its own twist (so the centre of mass need
not be at the body frame origin), give a block-diagonal

    M = blockdiag(m J_T^T J_T + J_R^T I J_R),   Q - h = sum J^T F - (m J_T^T a_bias + ...),

and every joint, tree and cut alike, becomes implicit holonomic constraints g(t, q) = 0
(book 9.4, :func:`workbench.mechanics.joints.implicit_constraints` between the world frames P and
C, P moved by the drive of a driven joint), plus contact heights and nonholonomic rows of
rolling and knife-edge constraints. The velocity constraints are d/dt g followed by the
nonholonomic rows; the equations are M v' = Q - h - W^T lambda.

Why omega in the body frame and not p' as velocities: with v_b = (r', omega_b) there are 6
velocities a body and M is nonsingular for a rigid body (the book's choice with p' as
velocities has 7 and needs the normalization p^T p = 1 as a constraint row to fix the
singular direction along p). With omega_b, d/dt (p^T p) = 2 p^T H(p) omega_b = 0
identically: the normalization has a zero velocity Jacobian, so it is *not* a constraint
row (it would make W rank deficient) but an invariant of the kinematics q' = H v. Its
numerical drift shows in the joint residuals observable (R(p) is not orthogonal when
|p| != 1) wherever a joint constrains orientation or sits off the body frame origin (a
spherical joint at the origin does not see it). Nothing renormalizes p: an integrator
that wants to may project |p| = 1 between steps.

Redundant constraints (a planar four-bar built with spatial revolute joints, all axes
parallel) are found at build time: W is evaluated where ``workbench describe`` evaluates
it, at the model's initial configuration (the problem's), assembled, and at a few random
assembled ones (:func:`workbench.mechanics.topology.rank_configurations`; the highest rank
wins, so a singular initial configuration is outvoted); rows depending on earlier rows are removed
(:func:`workbench.numerics.linalg.independent_rows`, the test ``workbench describe`` uses;
option ``redundant="remove"``, recorded in ``notes``) or reported (``"error"``).

Point masses keep full body coordinates; their rotational directions have zero inertia
(M is singular there) but model validation forbids attachments that leave their spin free,
so the augmented matrix [M W^T; W 0] is nonsingular.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from workbench.equations import Equations, MechanicalSystem, build_equations, joint_residuals
from workbench.equations.compiled import Compiler
from workbench.errors import ModelError
from workbench.mechanics import forces as fm
from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import BodyState, TreeKinematics, contact_rows
from workbench.mechanics.newton_euler import newton_euler_forces
from workbench.mechanics.topology import independent_rows_at, rank_configurations
from workbench.model import GROUND, Joint, Model, RollingDisk, RollingSphere
from workbench.numerics import rotations as rot
from workbench.numerics.rotations import axis_angle_to_quaternion, quaternion_multiply
from workbench.plugin.formalism import ConstraintOptions, Formalism, constrained_forms
from workbench.plugin.registry import formalism


@dataclass(frozen=True)
class AbsoluteOptions(ConstraintOptions):
    redundant: Literal["remove", "error"] = "remove"


# ---- coordinates ------------------------------------------------------------------------


class AbsoluteCoordinates:
    """Symbols t, q, v of all bodies, q' = H(q) v, and every body's symbolic state.

    Per body: planar (x, y, angle) / (x', y', angle'); spatial (r (3), p (4)) /
    (r' (3), omega in the body frame (3)). ``slices`` {body: (q slice, v slice)}.
    """

    def __init__(self, model: Model) -> None:
        self.planar = model.kind == "planar"
        nq_body, nv_body = (3, 3) if self.planar else (7, 6)
        names = list(model.bodies)
        self.t = ca.SX.sym("t")
        self.q = ca.SX.sym("q", nq_body * len(names))
        self.v = ca.SX.sym("v", nv_body * len(names))
        self.slices: dict[str, tuple[slice, slice]] = {}
        self.bodies: dict[str, BodyState] = {}
        self.quaternions: dict[str, Any] = {}  # spatial: Euler parameters of each body
        self.q_names: list[str] = []
        self.v_names: list[str] = []
        rates = []
        if self.planar:
            q_labels, v_labels = ("x", "y", "angle"), ("vx", "vy", "omega")
        else:
            q_labels = ("x", "y", "z", "p0", "p1", "p2", "p3")
            v_labels = ("vx", "vy", "vz", "wx", "wy", "wz")
        for i, name in enumerate(names):
            q_slice = slice(i * nq_body, (i + 1) * nq_body)
            v_slice = slice(i * nv_body, (i + 1) * nv_body)
            self.slices[name] = (q_slice, v_slice)
            self.q_names += [f"{name}.{label}" for label in q_labels]
            self.v_names += [f"{name}.{label}" for label in v_labels]
            q_b, v_b = self.q[q_slice], self.v[v_slice]
            zero = ca.SX(1, 1)
            if self.planar:
                position = ca.vertcat(q_b[0], q_b[1], zero)
                rotation = rot.axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), q_b[2])
                velocity = ca.vertcat(v_b[0], v_b[1], zero)
                angular_velocity = ca.vertcat(zero, zero, v_b[2])
                rates.append(v_b)
            else:
                p, omega_body = q_b[3:7], v_b[3:6]
                self.quaternions[name] = p
                rotation = rot.quaternion_to_matrix(p)
                position, velocity = q_b[0:3], v_b[0:3]
                angular_velocity = ca.mtimes(rotation, omega_body)
                p_rate = ca.mtimes(rot.quaternion_rate_matrix(p, "body"), omega_body)
                rates.append(ca.vertcat(velocity, p_rate))
            self.bodies[name] = BodyState(position, rotation, velocity, angular_velocity)
        self.qdot = ca.vertcat(*rates) if rates else ca.SX(0, 1)


def constraint_row_names(model: Model) -> list[str]:
    """Names of the rows of :func:`workbench.equations.joint_residuals`, in its order."""
    names = []
    for joint in model.joints.values():
        kind = "fixed" if joint.drive is not None else joint.type
        n = jk.CONSTRAINT_ROWS[model.kind].get(kind, 0)
        names += [f"{joint.name}[{i}]" for i in range(n)]
    for constraint in model.nonholonomic:
        if isinstance(constraint, RollingSphere | RollingDisk):  # they have a contact height
            names.append(f"{constraint.name}.height")
    return names


def joint_coordinates_from_poses(
    model: Model, coords: AbsoluteCoordinates
) -> dict[str, tuple[Any, Any]]:
    """(q_joint, v_joint) of every joint carrying a spring or force, from the body poses.

    Driven joints take the drive's values (their velocities do not depend on v, so a joint
    force on them does no virtual work, as in joint-coordinate formalisms). Spherical and
    free joints: see :func:`quaternion_joint_coordinates`; the others' v_joint is the rate
    of q_joint.
    """
    result = {}
    for name in fm.joints_with_forces(model):
        joint = model.joints[name]
        if joint.drive is not None:
            q_d, v_d, _ = jk.drive_values(joint, coords.t)
            result[name] = (q_d, v_d)
            continue
        if joint.type in ("spherical", "free"):
            result[name] = quaternion_joint_coordinates(joint, coords)
            continue
        q_joint = fm.relative_joint_coordinates(model, coords.bodies, name)
        v_joint = ca.mtimes(ca.jacobian(q_joint, coords.q), coords.qdot) + ca.jacobian(
            q_joint, coords.t
        )
        result[name] = (q_joint, v_joint)
    return result


def quaternion_joint_coordinates(joint: Joint, coords: AbsoluteCoordinates) -> tuple[Any, Any]:
    """(q_joint, v_joint) of a spherical or free joint, as the tree defines them.

    q' = H(p) omega is not v for Euler parameters, so v_joint is not the rate of q_joint
    but the joint's own velocities (:mod:`workbench.mechanics.joints`): the angular velocity
    of C relative to P in C, preceded for a free joint by the rate of C's origin in P
    coordinates. The Euler parameters of C in P invert :func:`joint_space_map`'s
    composition p_child = p_parent (x) P's rotation (x) q_joint (x) C's rotation^-1
    exactly, sign included, so a joint force sees the same q as in joint coordinates.
    """

    def body_quaternion(body: str) -> Any:
        return ca.DM([1.0, 0.0, 0.0, 0.0]) if body == GROUND else coords.quaternions[body]

    def conjugate(p: Any) -> Any:
        return ca.vertcat(p[0], -p[1], -p[2], -p[3])

    parent_side = quaternion_multiply(
        body_quaternion(joint.parent), _constant_quaternion(joint.parent_frame.rotation)
    )
    # the conjugate of the very constant joint_space_map uses (SciPy may return either
    # sign for the quaternion of a transposed matrix)
    child_side = quaternion_multiply(
        body_quaternion(joint.child),
        conjugate(_constant_quaternion(joint.child_frame.rotation.T)),
    )
    p_joint = quaternion_multiply(conjugate(parent_side), child_side)
    parent = fm.GROUND_STATE if joint.parent == GROUND else coords.bodies[joint.parent]
    child = coords.bodies[joint.child]
    r_p, rot_p = parent.frame(joint.parent_frame)
    r_c, rot_c = child.frame(joint.child_frame)
    omega = ca.mtimes(rot_c.T, child.angular_velocity - parent.angular_velocity)
    if joint.type == "spherical":
        return p_joint, omega
    r_rel = ca.mtimes(rot_p.T, r_c - r_p)
    r_rate = ca.mtimes(ca.jacobian(r_rel, coords.q), coords.qdot) + ca.jacobian(r_rel, coords.t)
    return ca.vertcat(r_rel, p_joint), ca.vertcat(r_rate, omega)


# ---- joint space -> absolute coordinates --------------------------------------------------


def _constant_quaternion(matrix: np.ndarray) -> ca.DM:
    x, y, z, w = Rotation.from_matrix(matrix).as_quat()
    return ca.DM([w, x, y, z])


def joint_quaternion(joint: Joint, q: Any) -> Any:
    """Euler parameters of C relative to P for joint coordinates q (cf. relative_transform)."""
    a = jk.unit(joint.axis)
    identity = ca.DM([1.0, 0.0, 0.0, 0.0])
    kind = joint.type
    if kind in ("prismatic", "fixed"):
        return identity
    if kind == "revolute":
        return axis_angle_to_quaternion(a, q[0])
    if kind == "cylindrical":
        return axis_angle_to_quaternion(a, q[1])
    if kind == "universal":
        return quaternion_multiply(
            axis_angle_to_quaternion(a, q[0]), axis_angle_to_quaternion(jk.unit(joint.axis2), q[1])
        )
    if kind == "spherical":
        return q[0:4]
    if kind == "planar":
        return axis_angle_to_quaternion(np.array([0.0, 0.0, 1.0]), q[2])
    if kind == "free":
        return q[3:7]
    raise ValueError(f"joint {joint.name!r}: unknown joint type {kind!r}")


def joint_space_map(model: Model, tree: TreeKinematics) -> list[Any]:
    """[q, v] absolute coordinates as expressions of the tree's (t, q, v).

    Orientations are composed as quaternions along the tree (no matrix -> quaternion
    conversion of symbols); planar angles are 2 atan2(p3, p0), continuous for |angle| <
    2 pi.
    """
    quaternions: dict[str, Any] = {GROUND: ca.DM([1.0, 0.0, 0.0, 0.0])}
    for joint in tree.order:
        q_joint, _ = tree.joint_coordinates(joint)
        p = quaternion_multiply(
            quaternions[joint.parent], _constant_quaternion(joint.parent_frame.rotation)
        )
        p = quaternion_multiply(p, joint_quaternion(joint, q_joint))
        child_inverse = _constant_quaternion(joint.child_frame.rotation.T)
        quaternions[joint.child] = quaternion_multiply(p, child_inverse)
    q_parts, v_parts = [], []
    for name in model.bodies:
        state, p = tree.bodies[name], quaternions[name]
        if model.kind == "planar":
            q_parts.append(
                ca.vertcat(state.position[0], state.position[1], 2 * ca.atan2(p[3], p[0]))
            )
            v_parts.append(
                ca.vertcat(state.velocity[0], state.velocity[1], state.angular_velocity[2])
            )
        else:
            q_parts.append(ca.vertcat(state.position, p))
            omega_body = ca.mtimes(state.rotation.T, state.angular_velocity)
            v_parts.append(ca.vertcat(state.velocity, omega_body))
    return [ca.vertcat(*q_parts), ca.vertcat(*v_parts)]


# ---- redundancy -------------------------------------------------------------------------


def select_rows(
    model: Model, tree: TreeKinematics, to_absolute: ca.Function, w_matrix: ca.Function
) -> list[int]:
    """Independent rows of W where ``workbench describe`` decides the rank: the model's
    initial configuration, assembled, confirmed at random assembled ones (the first of
    highest rank wins; :func:`workbench.mechanics.topology.rank_configurations`)."""

    def w_at(q_joint: np.ndarray) -> np.ndarray:
        q_abs = np.asarray(to_absolute(0.0, q_joint, np.zeros(tree.nv))[0]).reshape(-1)
        return np.asarray(w_matrix(0.0, q_abs))

    rows, _ = independent_rows_at(w_at, rank_configurations(model, tree))
    return rows


# ---- the formalism ----------------------------------------------------------------------


@formalism
class AbsoluteDae(Formalism):
    name = "absolute-dae"
    summary = "Absolute body coordinates (Euler parameters), implicit joint constraints, DAE"
    Options = AbsoluteOptions
    capabilities = frozenset(
        {"planar", "spatial", "closed-loops", "rheonomic", "point-masses", "nonholonomic"}
    ) | {"contacts"}  # the contact form comes from build_equations

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        options = cls.parse_options(options)
        return constrained_forms(options)

    def build(self, model: Model, options: Any = None) -> Equations:
        options = self.parse_options(options)
        model.validate()
        self.check(model)
        coords = AbsoluteCoordinates(model)
        t, q, v, qdot = coords.t, coords.q, coords.v, coords.qdot
        planar = coords.planar

        mass, forces = newton_euler_forces(
            model, coords.bodies, joint_coordinates_from_poses(model, coords), t, q, v, qdot
        )

        g = ca.SX(joint_residuals(model, t, coords.bodies))
        g_names = constraint_row_names(model)
        assert g.numel() == len(g_names), "constraint row names out of step with residuals"
        g_rate = ca.mtimes(ca.jacobian(g, q), qdot) + ca.jacobian(g, t)
        nh_rows, nh_names = [], []
        for constraint in model.nonholonomic:
            _, rows = contact_rows(planar, coords.bodies[constraint.body], constraint)
            nh_rows.append(rows)
            nh_names += [f"{constraint.name}[{i}]" for i in range(rows.numel())]
        velocity_rows = ca.vertcat(g_rate, *nh_rows)
        names = g_names + nh_names

        tree = TreeKinematics(model)
        map_outputs = joint_space_map(model, tree)
        notes = []
        if not planar:
            notes.append(
                "velocities: origin velocity (inertial) and angular velocity in the body "
                "frame; the Euler-parameter normalization p^T p = 1 is an invariant of "
                "q' = H(p) omega (zero velocity Jacobian), not a constraint row: its drift "
                "shows in the joint residuals"
            )
        if velocity_rows.numel():
            to_absolute = ca.Function("to_absolute", [tree.t, tree.q, tree.v], map_outputs)
            w_function = ca.Function("W", [t, q], [ca.densify(ca.jacobian(velocity_rows, v))])
            kept = select_rows(model, tree, to_absolute, w_function)
            removed = [names[i] for i in range(len(names)) if i not in kept]
            if removed:
                if options.redundant == "error":
                    raise ModelError(
                        f"model {model.name!r}: redundant constraint rows {', '.join(removed)} "
                        "(they depend on the other joint constraints); remove or loosen the "
                        "joints, or use the absolute-dae option redundant='remove'"
                    )
                notes.append(f"removed redundant constraint rows: {', '.join(removed)}")
            n_h = g.numel()
            kept_h = [i for i in kept if i < n_h]
            g = g[kept_h] if kept_h else ca.SX(0, 1)
            velocity_rows = velocity_rows[kept] if kept else ca.SX(0, 1)
            names = [names[i] for i in kept]

        system = MechanicalSystem(
            t=t,
            q=q,
            v=v,
            qdot=qdot,
            mass=mass,
            forces=forces,
            q_names=coords.q_names,
            v_names=coords.v_names,
            position_constraints=g,
            velocity_constraints=velocity_rows,
            constraint_names=names,
            rotation_blocks=[
                (slice(q_slice.start + 3, q_slice.stop), slice(v_slice.start + 3, v_slice.stop))
                for name, (q_slice, v_slice) in coords.slices.items()
                if name in coords.quaternions
            ],
        )
        return build_equations(
            self.name,
            model,
            system,
            coords.bodies,
            ([tree.t, tree.q, tree.v], map_outputs),
            dae_index=options.index,
            baumgarte=(options.baumgarte_alpha, options.baumgarte_beta),
            ode=system.n_constraints == 0 or options.index == 1,
            notes=notes,
            compiler=Compiler.from_options(options),
        )
