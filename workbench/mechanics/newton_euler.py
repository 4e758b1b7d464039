"""Newton-Euler equations of rigid bodies projected onto generalized velocities (book 5.6, 7.6).

For any coordinates (t, q, v) with q' = H(q) v in which every body's twist is known
symbolically (tree joint coordinates, absolute body coordinates, minimal velocities of a
nonholonomic system), body i's centre-of-mass velocity is v_c = J_T v + ... and its
angular velocity w = J_R v + ..., with J_T = d v_c / d v and J_R = d w / d v (3, nv).
Jourdain's principle projects the Newton-Euler equations m a_c = F, I w' + w x I w = L
onto v:

    M = sum_i m J_T^T J_T + J_R^T I J_R                                  (nv, nv)
    h = sum_i m J_T^T a_c,bias + J_R^T (I alpha_bias + w x I w)           (nv)

with the bias accelerations a_c,bias, alpha_bias the time derivatives of v_c and w at
v' = 0 (along q' = H v and explicit time, for drives), I the inertia tensor about the
centre of mass in inertial coordinates. The equations of motion are M v' = Q - h, Q the
generalized applied forces (:func:`workbench.mechanics.forces.generalized_forces`).
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from workbench.mechanics import forces as fm
from workbench.mechanics.kinematics import BodyState
from workbench.model import Model


def mass_and_bias(
    model: Model, bodies: dict[str, BodyState], t: Any, q: Any, v: Any, qdot: Any
) -> tuple[Any, Any]:
    """(M (nv, nv), h (nv)) of all bodies of ``model`` (see the module docstring).

    ``bodies`` holds each body's symbolic state in (t, q, v); ``qdot`` (nq) is q' = H v.
    A point mass has no rotational terms (its inertia is zero).
    """
    nv = v.numel()
    mass, bias = ca.SX.zeros(nv, nv), ca.SX.zeros(nv)
    for name, body in model.bodies.items():
        state = bodies[name]
        v_com = state.point_velocity(body.com)
        omega = state.angular_velocity
        j_t, j_r = ca.jacobian(v_com, v), ca.jacobian(omega, v)
        a_com = ca.mtimes(ca.jacobian(v_com, q), qdot) + ca.jacobian(v_com, t)
        alpha = ca.mtimes(ca.jacobian(omega, q), qdot) + ca.jacobian(omega, t)
        translational_mass = body.mass * ca.mtimes(j_t.T, j_t)
        translational_bias = body.mass * ca.mtimes(j_t.T, a_com)
        if body.point_mass:
            mass += translational_mass
            bias += translational_bias
            continue
        inertia = ca.mtimes([state.rotation, ca.DM(body.inertia), state.rotation.T])
        gyroscopic = ca.mtimes(inertia, alpha) + ca.cross(omega, ca.mtimes(inertia, omega))
        mass += translational_mass + ca.mtimes([j_r.T, inertia, j_r])
        bias += translational_bias + ca.mtimes(j_r.T, gyroscopic)
    return mass, bias


def newton_euler_forces(
    model: Model,
    bodies: dict[str, BodyState],
    joint_coordinates: dict[str, tuple[Any, Any]],
    t: Any,
    q: Any,
    v: Any,
    qdot: Any,
) -> tuple[Any, Any]:
    """(M (nv, nv), Q - h (nv)): the mass matrix and the right-hand side of M v' = Q - h.

    ``joint_coordinates`` {joint: (q_joint, v_joint)} of the joints carrying springs,
    dampers or forces, in (t, q, v).
    """
    mass, bias = mass_and_bias(model, bodies, t, q, v, qdot)
    applied = fm.generalized_forces(model, t, v, bodies, joint_coordinates)
    return mass, applied - bias
