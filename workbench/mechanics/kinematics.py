"""Kinematics of the spanning tree in joint coordinates (book 10.2, 11.1), symbolically.

:class:`TreeKinematics` builds CasADi SX expressions, in the free (not driven) tree joint
coordinates q, velocities v and time t, for every body's pose and twist (outward
recursion), the loop-closure constraints of the cut joints and the holonomic parts of
rolling contacts g(t, q), and all velocity-level constraint rows W(t, q) v + w(t, q) = 0
(closure rows first, then nonholonomic rows). It is formalism-neutral: the minimal
formalism builds on it, absolute-coordinate formalisms use it to map joint coordinates to
body coordinates, and the core uses it for consistent initial states and DOF counts.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from workbench.errors import ModelError
from workbench.mechanics import joints as jk
from workbench.model import GROUND, Frame, Joint, KnifeEdge, Model, RollingDisk, RollingSphere
from workbench.model.elements import real_array


@dataclass
class BodyState:
    """Symbolic pose and twist of a body's reference frame, inertial coordinates."""

    position: Any  # (3,)
    rotation: Any  # (3, 3)
    velocity: Any  # (3,)
    angular_velocity: Any  # (3,)

    def point(self, local: np.ndarray) -> Any:
        """Position of a point given in the body frame."""
        return self.position + ca.mtimes(self.rotation, ca.DM(local))

    def point_velocity(self, local: np.ndarray) -> Any:
        return self.velocity + ca.cross(self.angular_velocity, ca.mtimes(self.rotation,
                                                                          ca.DM(local)))

    def frame(self, frame: Frame) -> tuple[Any, Any]:
        return self.point(frame.position), ca.mtimes(self.rotation, ca.DM(frame.rotation))


def tree_order(model: Model) -> list[Joint]:
    """Tree joints ordered parents-first; ModelError if a body is unreachable from ground."""
    children: dict[str, list[Joint]] = {}
    for joint in model.tree_joints:
        children.setdefault(joint.parent, []).append(joint)
    ordered, frontier = [], deque([GROUND])
    while frontier:
        body = frontier.popleft()
        for joint in children.get(body, []):
            ordered.append(joint)
            frontier.append(joint.child)
    reached = {j.child for j in ordered}
    missing = [b for b in model.bodies if b not in reached]
    if missing:
        raise ModelError(
            f"model {model.name!r}: body {missing[0]!r} is not connected to ground by tree "
            "joints; add a joint (a 'free' joint for an unconstrained body)"
        )
    return ordered


class JointLayout:
    """Where each free (not driven) tree joint's coordinates sit in q (nq) and v (nv),
    without symbols: ``order`` (tree joints, parents first), ``free_joints``,
    ``joint_slices`` {joint: (q slice, v slice)}, ``q_names``, ``v_names``, ``nq``, ``nv``.
    :class:`TreeKinematics` has the same attributes; this is the cheap part of it (a
    10,000-link chain is laid out in milliseconds)."""

    def __init__(self, model: Model) -> None:
        self.order = tree_order(model)
        self.free_joints = [j for j in self.order if j.drive is None]
        self.joint_slices: dict[str, tuple[slice, slice]] = {}
        q_names: list[str] = []
        v_names: list[str] = []
        for joint in self.free_joints:
            nq, nv = jk.dimensions(joint)
            self.joint_slices[joint.name] = (
                slice(len(q_names), len(q_names) + nq),
                slice(len(v_names), len(v_names) + nv),
            )
            q_names += [f"{joint.name}[{i}]" if nq > 1 else joint.name for i in range(nq)]
            v_names += [f"{joint.name}.v[{i}]" if nv > 1 else f"{joint.name}.v" for i in range(nv)]
        self.q_names, self.v_names = q_names, v_names
        self.nq, self.nv = len(q_names), len(v_names)


class TreeKinematics:
    """Symbolic kinematics of ``model`` in free tree-joint coordinates (see module doc).

    Attributes: ``t``, ``q`` (nq), ``v`` (nv) SX symbols; ``q_names``, ``v_names``;
    ``joint_slices`` {joint: (q slice, v slice)} for free joints; ``bodies``
    {name: BodyState}; ``qdot`` (nq) = H(q) v; ``closure_constraints`` g(t, q) with
    ``closure_names``; ``velocity_constraint_matrix`` W and ``velocity_constraint_bias``
    w with ``velocity_constraint_names`` (closure rows, then nonholonomic rows).
    """

    def __init__(self, model: Model) -> None:
        self.model = model
        self.planar = model.kind == "planar"
        layout = JointLayout(model)
        self.order, self.free_joints = layout.order, layout.free_joints
        self.joint_slices = layout.joint_slices
        self.q_names, self.v_names = layout.q_names, layout.v_names
        self.nq, self.nv = layout.nq, layout.nv
        self.t = ca.SX.sym("t")
        self.q = ca.SX.sym("q", self.nq)
        self.v = ca.SX.sym("v", self.nv)
        self._joint_q: dict[str, Any] = {}
        self._joint_v: dict[str, Any] = {}
        self.bodies: dict[str, BodyState] = {}
        self._forward()
        self.qdot = ca.vertcat(
            *[jk.coordinate_rates(j, self._joint_q[j.name], self._joint_v[j.name])
              for j in self.free_joints]
        ) if self.free_joints else ca.SX(0, 1)
        self._constraints()

    # -- forward kinematics, outward ---------------------------------------------------
    def joint_coordinates(self, joint: Joint) -> tuple[Any, Any]:
        """Symbolic (q, v) of a tree joint: free symbols, or the drive's functions of t."""
        return self._joint_q[joint.name], self._joint_v[joint.name]

    def _forward(self) -> None:
        ground = BodyState(ca.SX.zeros(3), ca.SX.eye(3), ca.SX.zeros(3), ca.SX.zeros(3))
        for joint in self.order:
            if joint.drive is None:
                q_slice, v_slice = self.joint_slices[joint.name]
                q_j, v_j = self.q[q_slice], self.v[v_slice]
            else:
                q_j, v_j, _ = jk.drive_values(joint, self.t)
                q_j, v_j = ca.SX(q_j) if not isinstance(q_j, ca.SX) else q_j, v_j
            self._joint_q[joint.name], self._joint_v[joint.name] = q_j, v_j
            parent = ground if joint.parent == GROUND else self.bodies[joint.parent]
            r_p, rot_p = parent.frame(joint.parent_frame)
            v_p = parent.point_velocity(joint.parent_frame.position)
            r_rel, rot_rel = jk.relative_transform(joint, q_j)
            v_rel, w_rel = jk.relative_twist(joint, q_j, v_j)
            r_c = r_p + ca.mtimes(rot_p, r_rel)
            rot_c = ca.mtimes(rot_p, rot_rel)
            omega = parent.angular_velocity + ca.mtimes(rot_p, w_rel)
            v_c = v_p + ca.cross(parent.angular_velocity, r_c - r_p) + ca.mtimes(rot_p, v_rel)
            rot_b = ca.mtimes(rot_c, ca.DM(joint.child_frame.rotation.T))
            r_b = r_c - ca.mtimes(rot_b, ca.DM(joint.child_frame.position))
            v_b = v_c + ca.cross(omega, r_b - r_c)
            self.bodies[joint.child] = BodyState(r_b, rot_b, v_b, omega)
        self._ground = ground

    def body(self, name: str) -> BodyState:
        return self._ground if name == GROUND else self.bodies[name]

    # -- constraints -------------------------------------------------------------------
    def _constraints(self) -> None:
        rows, names, nh_rows, nh_names = [], [], [], []
        for joint in self.model.cut_joints:
            r_p, rot_p = self.body(joint.parent).frame(joint.parent_frame)
            if joint.drive is not None:
                q_d, _, _ = jk.drive_values(joint, self.t)
                r_rel, rot_rel = jk.relative_transform(joint, q_d)
                r_p, rot_p = r_p + ca.mtimes(rot_p, r_rel), ca.mtimes(rot_p, rot_rel)
            r_c, rot_c = self.body(joint.child).frame(joint.child_frame)
            residual = jk.implicit_constraints(joint, self.planar, r_p, rot_p, r_c, rot_c)
            residual = ca.vec(ca.SX(residual)) if not isinstance(residual, ca.SX) else residual
            rows.append(residual)
            names += [f"{joint.name}[{i}]" for i in range(residual.numel())]
        for constraint in self.model.nonholonomic:
            holonomic, nonholonomic = contact_rows(self.planar, self.body(constraint.body),
                                                   constraint)
            if holonomic is not None:
                rows.append(holonomic)
                names.append(f"{constraint.name}.height")
            nh_rows.append(nonholonomic)
            nh_names += [f"{constraint.name}[{i}]" for i in range(nonholonomic.numel())]
        self.closure_constraints = ca.vertcat(*rows) if rows else ca.SX(0, 1)
        self.closure_names = names
        g = self.closure_constraints
        g_q = ca.jacobian(g, self.q)
        self.closure_jacobian = g_q  # dg/dq (m x nq)
        w_hol = ca.mtimes(g_q, self.qdot) + ca.jacobian(g, self.t)  # d/dt g
        nh = ca.vertcat(*nh_rows) if nh_rows else ca.SX(0, 1)
        velocity_rows = ca.vertcat(w_hol, nh)
        self.velocity_constraints = velocity_rows  # W v + w, linear in v
        self.velocity_constraint_matrix = ca.jacobian(velocity_rows, self.v)
        self.velocity_constraint_bias = ca.substitute(velocity_rows, self.v, ca.SX.zeros(self.nv))
        self.velocity_constraint_names = names + nh_names
        self.n_holonomic = len(names)
        self.n_nonholonomic = len(nh_names)

    def function(self, name: str, outputs: list[Any], with_v: bool = True) -> ca.Function:
        """A CasADi Function of (t, q[, v]) with dense outputs."""
        inputs = [self.t, self.q, self.v] if with_v else [self.t, self.q]
        return ca.Function(name, inputs, [ca.densify(o) for o in outputs])


def contact_rows(planar: bool, body: BodyState, constraint: Any) -> tuple[Any, Any]:
    """(holonomic row or None, nonholonomic rows) of a rolling or knife-edge constraint.

    Rolling: the material point of the body at the contact moves with the plane (z = 0 in
    space, y = 0 in planar models, rotating about z at ``plane_rate`` for a sphere).
    """
    if isinstance(constraint, KnifeEdge):
        velocity = body.point_velocity(np.asarray(constraint.point, dtype=float))
        direction = ca.mtimes(body.rotation, ca.DM(np.asarray(constraint.direction, float)))
        return None, ca.dot(velocity, direction)
    center = body.point(np.asarray(constraint.center, dtype=float))
    center_velocity = body.point_velocity(np.asarray(constraint.center, dtype=float))
    radius = constraint.radius
    up = ca.DM([0, 1, 0]) if planar else ca.DM([0, 0, 1])
    if isinstance(constraint, RollingSphere):
        to_contact = -radius * up
        height = center[2] - radius
        plane_velocity = ca.cross(ca.DM([0, 0, constraint.plane_rate]), center + to_contact)
    elif isinstance(constraint, RollingDisk):
        if planar:
            to_contact = -radius * up
            height = center[1] - radius
        else:
            normal = ca.mtimes(body.rotation, ca.DM(jk.unit(constraint.axis)))
            down = -up + ca.dot(up, normal) * normal  # towards the ground, in the disk plane
            to_contact = radius * down / ca.norm_2(down)
            height = ca.dot(center + to_contact, up)
        plane_velocity = ca.SX.zeros(3)
    else:
        raise ModelError(f"unknown nonholonomic constraint {constraint!r}")
    slip = center_velocity + ca.cross(body.angular_velocity, to_contact) - plane_velocity
    tangential = slip[0] if planar else ca.vertcat(slip[0], slip[1])
    return height, tangential


def initial_joint_values(model: Model, kinematics: TreeKinematics, values: dict[str, Any],
                         velocities: bool) -> np.ndarray:
    """Stack per-joint initial values into the free-joint vector (neutral/zero if absent)."""
    size = kinematics.nv if velocities else kinematics.nq
    out = np.zeros(size)
    what = "velocity" if velocities else "coordinate"
    if not isinstance(values, Mapping):
        raise ModelError(
            f"model {model.name!r}: the initial joint {what} values must be a mapping of "
            f"joint name -> value(s), not {type(values).__name__}"
        )
    known = {j.name for j in kinematics.free_joints}
    for name in values:
        if name not in known:
            driven = name in model.joints and model.joints[name].drive is not None
            why = "it is driven" if driven else "no free tree joint has that name"
            raise ModelError(
                f"model {model.name!r}: initial {'velocity' if velocities else 'coordinate'} "
                f"given for joint {name!r}, but {why}; free tree joints: {', '.join(known)}"
            )
    for joint in kinematics.free_joints:
        q_slice, v_slice = kinematics.joint_slices[joint.name]
        target = v_slice if velocities else q_slice
        n = target.stop - target.start
        default = np.zeros(n) if velocities else jk.neutral_coordinates(joint)
        where = f"model {model.name!r}, joint {joint.name!r}"
        value = real_array(values.get(joint.name, default), where, f"initial {what}").reshape(-1)
        if value.shape != (n,):
            raise ModelError(
                f"model {model.name!r}: joint {joint.name!r} ({joint.type}) takes {n} "
                f"{'velocities' if velocities else 'coordinates'}, got {value.size}"
            )
        if not np.all(np.isfinite(value)):
            raise ModelError(
                f"{where}: initial {what} {value.tolist()} contains NaN or inf; give finite "
                "numbers"
            )
        if not velocities and joint.type in ("spherical", "free") and not np.any(value[-4:]):
            raise ModelError(
                f"{where}: the initial Euler parameters (the last 4 coordinates) are all "
                "zero; give a unit quaternion, e.g. (1, 0, 0, 0)"
            )
        out[target] = value
    return out


def rotation_blocks(kinematics: TreeKinematics) -> list[tuple[slice, slice]]:
    """(q slice of the Euler parameters, v slice of the angular velocity of C in C) of
    every free spherical and free joint: p' = 1/2 p * (0, omega), omega body-fixed."""
    blocks = []
    for joint in kinematics.free_joints:
        q_slice, v_slice = kinematics.joint_slices[joint.name]
        if joint.type in ("spherical", "free"):
            blocks.append(
                (slice(q_slice.stop - 4, q_slice.stop), slice(v_slice.stop - 3, v_slice.stop))
            )
    return blocks


def quaternion_slices(kinematics: TreeKinematics) -> list[slice]:
    """Slices of q holding the Euler parameters of spherical and free joints (4 each)."""
    return [q_slice for q_slice, _ in rotation_blocks(kinematics)]


def normalize_quaternions(kinematics: TreeKinematics, q: np.ndarray) -> None:
    """Scale the Euler parameters in tree coordinates q (nq) to unit length, in place."""
    for part in quaternion_slices(kinematics):
        q[part] /= np.linalg.norm(q[part])
