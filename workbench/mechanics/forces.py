"""Force elements and energies from body poses and twists, formalism-neutral (book 4.6, 5.4).

Formalisms pass symbolic :class:`~workbench.mechanics.kinematics.BodyState` objects (pose and twist
of every body in their own coordinates); this module returns the applied wrenches, the
generalized forces Q = sum J^T F (by the Jacobian of the twists with respect to the
velocities) and the kinetic and potential energy, so every formalism sees the same forces
and energy is measured the same way for all of them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import BodyState
from workbench.model import (
    GROUND,
    AppliedForce,
    JointForce,
    JointSpringDamper,
    Model,
    SpringDamper,
)
from workbench.numerics.rotations import quaternion_conjugate, quaternion_multiply

GROUND_STATE = BodyState(ca.DM.zeros(3), ca.DM.eye(3), ca.DM.zeros(3), ca.DM.zeros(3))


def _state(bodies: Mapping[str, BodyState], name: str) -> BodyState:
    return GROUND_STATE if name == GROUND else bodies[name]


def body_wrenches(
    model: Model, t: Any, bodies: Mapping[str, BodyState], gravity: bool = True
) -> dict[str, tuple[Any, Any]]:
    """Applied force and torque on each body, about its frame's origin, inertial coordinates.

    Includes gravity (unless ``gravity=False``: a recursive formalism can apply it as an
    acceleration of the ground instead), point-to-point spring-dampers and applied forces
    (not joint forces: see :func:`joint_generalized_forces`).
    """
    wrenches = {name: [ca.SX.zeros(3), ca.SX.zeros(3)] for name in model.bodies}

    def add(body: str, point_local: np.ndarray, force: Any, torque: Any = None) -> None:
        if body == GROUND:
            return
        state = bodies[body]
        arm = ca.mtimes(state.rotation, ca.DM(np.asarray(point_local, dtype=float)))
        wrenches[body][0] += force
        wrenches[body][1] += ca.cross(arm, force) + (0 if torque is None else torque)

    if gravity:
        g = ca.DM(model.gravity)
        for name, body in model.bodies.items():
            add(name, body.com, body.mass * g)
    for element in model.forces:
        if isinstance(element, SpringDamper):
            s1, s2 = _state(bodies, element.body1), _state(bodies, element.body2)
            p1, p2 = np.asarray(element.point1, float), np.asarray(element.point2, float)
            delta = s2.point(p2) - s1.point(p1)
            length = ca.norm_2(delta)
            direction = delta / length
            rate = ca.dot(s2.point_velocity(p2) - s1.point_velocity(p1), direction)
            tension = element.stiffness * (length - element.rest_length) + element.damping * rate
            add(element.body1, p1, tension * direction)
            add(element.body2, p2, -tension * direction)
        elif isinstance(element, AppliedForce):
            state = bodies[element.body]
            force, torque = element.function(
                t, state.position, state.rotation, state.velocity, state.angular_velocity
            )
            add(element.body, np.asarray(element.point, float), _column(force), _column(torque))
    return {name: (f, tau) for name, (f, tau) in wrenches.items()}


def _column(value: Any) -> Any:
    return ca.vec(value) if isinstance(value, ca.SX | ca.MX) else ca.DM(np.asarray(value, float))


def joint_generalized_forces(
    model: Model, t: Any, joint_coordinates: Mapping[str, tuple[Any, Any]]
) -> dict[str, Any]:
    """Generalized force on each joint with springs/dampers or joint forces, per joint velocity.

    ``joint_coordinates`` maps joint name -> (q_joint, v_joint) expressions.
    """
    totals: dict[str, Any] = {}
    for element in model.forces:
        if isinstance(element, JointSpringDamper):
            q, v = joint_coordinates[element.joint]
            force = -element.stiffness * spring_deflection(model, element, q)
            force = force - element.damping * v
        elif isinstance(element, JointForce):
            q, v = joint_coordinates[element.joint]
            force = _column(element.function(t, q, v))
        else:
            continue
        totals[element.joint] = totals.get(element.joint, 0) + force
    return totals


def spring_deflection(model: Model, element: JointSpringDamper, q: Any) -> Any:
    """How far a joint spring is from its rest, one value per joint velocity: q - rest for
    joints with one coordinate per velocity; for a spherical joint the rotation vector
    (axis times angle in [0, pi], in C) of rest^-1 (x) q, and for a free joint the position
    difference followed by it (MuJoCo's ball and free joint springs, ``mju_subQuat``). Its
    half square times the stiffness is the spring's energy, whose gradient the force is."""
    rest = np.asarray(element.rest, float)
    kind = model.joints[element.joint].type
    if kind not in ("spherical", "free"):
        return q - ca.DM(np.broadcast_to(rest, (q.numel(),)).copy())
    rotation = rotation_vector(
        quaternion_multiply(ca.DM(quaternion_conjugate(rest[-4:])), q[q.numel() - 4 :])
    )
    if kind == "spherical":
        return rotation
    return ca.vertcat(q[0:3] - ca.DM(rest[:3]), rotation)


def rotation_vector(p: Any) -> Any:
    """Axis times angle (angle in [0, pi]) of the rotation of Euler parameters ``p`` (4,),
    the same for p and -p; smooth at the identity (a series below a 1e-6 half-angle)."""
    sign = ca.if_else(p[0] < 0, -1.0, 1.0)
    w, axis = sign * p[0], sign * p[1:4]
    s = ca.norm_2(axis)
    scale = ca.if_else(s < 1e-6, 2.0 / w * (1.0 - s**2 / (3.0 * w**2)), 2.0 * ca.atan2(s, w) / s)
    return scale * axis


def joints_with_forces(model: Model) -> list[str]:
    """Names of joints that carry a joint spring-damper or joint force."""
    return sorted({f.joint for f in model.forces if isinstance(f, JointSpringDamper | JointForce)})


def relative_joint_coordinates(
    model: Model, bodies: Mapping[str, BodyState], joint_name: str
) -> Any:
    """A joint's coordinates recovered from the poses of its two bodies (absolute formalisms)."""
    joint = model.joints[joint_name]
    r_p, rot_p = _state(bodies, joint.parent).frame(joint.parent_frame)
    r_c, rot_c = _state(bodies, joint.child).frame(joint.child_frame)
    return jk.relative_coordinates(joint, ca.mtimes(rot_p.T, r_c - r_p), ca.mtimes(rot_p.T, rot_c))


def generalized_forces(
    model: Model,
    t: Any,
    v: Any,
    bodies: Mapping[str, BodyState],
    joint_coordinates: Mapping[str, tuple[Any, Any]],
) -> Any:
    """Q = sum_i J_i^T F_i + sum_j (dv_j/dv)^T f_j: applied forces in the velocities ``v``.

    ``joint_coordinates``: (q_joint, v_joint) expressions in the formalism's variables for
    every joint in :func:`joints_with_forces` (v_joint must be linear in v).
    """
    q_total = ca.SX.zeros(v.numel()) if isinstance(v, ca.SX) else ca.MX.zeros(v.numel())
    for name, (force, torque) in body_wrenches(model, t, bodies).items():
        state = bodies[name]
        q_total += ca.mtimes(ca.jacobian(state.velocity, v).T, force)
        q_total += ca.mtimes(ca.jacobian(state.angular_velocity, v).T, torque)
    for joint, force in joint_generalized_forces(model, t, joint_coordinates).items():
        q_total += ca.mtimes(ca.jacobian(joint_coordinates[joint][1], v).T, force)
    return q_total


def kinetic_energy(model: Model, bodies: Mapping[str, BodyState]) -> Any:
    """T = sum 1/2 m |v_c|^2 + 1/2 w_b^T I_c w_b (inertia about the centre of mass)."""
    total = 0
    for name, body in model.bodies.items():
        state = bodies[name]
        v_c = state.point_velocity(body.com)
        omega_body = ca.mtimes(state.rotation.T, state.angular_velocity)
        total += 0.5 * body.mass * ca.dot(v_c, v_c)
        if not body.point_mass:
            total += 0.5 * ca.dot(omega_body, ca.mtimes(ca.DM(body.inertia), omega_body))
    return total


def potential_energy(
    model: Model, bodies: Mapping[str, BodyState], joint_coordinates: Mapping[str, Any]
) -> Any:
    """V of gravity, point-to-point springs and joint springs.

    ``joint_coordinates``: joint name -> q_joint for joints with springs. Revolute angles
    recovered from poses lie in (-pi, pi]: a joint spring wound past that is not tracked.
    """
    total = 0
    gravity = ca.DM(model.gravity)
    for name, body in model.bodies.items():
        total -= body.mass * ca.dot(gravity, bodies[name].point(body.com))
    for element in model.forces:
        if isinstance(element, SpringDamper):
            s1, s2 = _state(bodies, element.body1), _state(bodies, element.body2)
            delta = s2.point(np.asarray(element.point2, float)) - s1.point(
                np.asarray(element.point1, float)
            )
            stretch = ca.norm_2(delta) - element.rest_length
            total += 0.5 * element.stiffness * stretch**2
        elif isinstance(element, JointSpringDamper):
            q = joint_coordinates[element.joint]
            total += 0.5 * element.stiffness * ca.sumsqr(spring_deflection(model, element, q))
    return total


def is_conservative_model(model: Model) -> bool:
    """No damping, no applied or joint forces, no drives: T + V is conserved."""
    for element in model.forces:
        if isinstance(element, JointForce | AppliedForce):
            return False
        if isinstance(element, SpringDamper | JointSpringDamper) and element.damping:
            return False
    return all(j.drive is None for j in model.joints.values())
