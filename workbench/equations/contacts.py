"""The contact form: what a formalism hands an integrator for set-valued contact forces.

Written once here, next to the smooth forms (:mod:`workbench.equations.forms`), from the
symbolic body states every formalism gives :func:`~workbench.equations.forms.build_equations`,
so every formalism that calls it offers the same contact data in its own coordinates.
For each :class:`~workbench.model.PlaneContact` i, with unit plane normal n_i and tangents
t_i (one in a planar model: n x e_z; two in a spatial one):

* the gap g_N,i(t, q) = n_i . (centre - plane point) - radius (>= 0: no penetration);
* the local velocities of the contact point, linear in v: U_N = W_N(t, q) v and
  U_T = W_T(t, q) v (rows: one a contact; one a contact and tangent), so g_N' = U_N
  (Glocker and Pfeiffer write W_N^T for our W_N);
* the biases U_N' = W_N v' + wdot_N(t, q, v), U_T' = W_T v' + wdot_T, for the
  acceleration-level problem between events;
* the friction cone data: Coulomb's mu_i and Newton's restitution e_i of every contact.

A :class:`~workbench.model.SphereContact` between two bodies' spheres enters the same rows:
g_N = |c_B - c_A| - r_A - r_B along n = (c_B - c_A) / |c_B - c_A|, U_N and U_T the
velocity of B's touching point relative to A's (:func:`sphere_pair`), so its impulses act
on both bodies, equal and opposite.

Generalized contact forces are W_N^T lambda_N + W_T^T lambda_T.

Coulomb friction in a one-coordinate joint (:class:`~workbench.model.JointFriction`) is
offered the same way, as the joint's rate U_F = W_F v (a revolute joint's relative angular
velocity about its axis, a prismatic one's relative sliding velocity along it) with its
bias and the friction bound: a contact that never opens, with a given normal force.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations.contract import ContactForm
from workbench.mechanics.kinematics import BodyState
from workbench.model import GROUND, Model, SphereContact


def plane_tangents(normal: np.ndarray, planar: bool) -> list[np.ndarray]:
    """Unit tangents of a plane with unit ``normal``: n x e_z in a planar model (the x-y
    plane's one direction), else two orthonormal ones with t1 x t2 = n."""
    if planar:
        return [np.array([normal[1], -normal[0], 0.0])]
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(helper, normal)
    first /= np.linalg.norm(first)
    return [first, np.cross(normal, first)]


def build_contact_form(
    model: Model,
    t: Any,
    q: Any,
    v: Any,
    qdot: Any,
    bodies: dict[str, BodyState],
    hot: Callable[[str, list, list], Any],
) -> ContactForm | None:
    """The contact form of ``model`` in the coordinates (t, q, v) with q' = ``qdot``;
    None without contacts. ``hot`` makes the numeric functions (the forms' compiler)."""
    if not model.contacts and not model.joint_frictions:
        return None
    planar = model.kind == "planar"
    empty = type(q)(0, 1)  # (q[0:0] of a one-coordinate q is (1, 0))
    gaps, normal_velocity, tangent_velocity = [empty], [empty], [empty]
    for contact in model.contacts:
        if isinstance(contact, SphereContact):
            gap, velocity, normal, tangents = sphere_pair(contact, bodies, planar)
            gaps.append(gap)
            normal_velocity.append(ca.dot(normal, velocity))
            tangent_velocity += [ca.dot(t_k, velocity) for t_k in tangents]
            continue
        body = bodies[contact.body]
        normal = np.asarray(contact.plane_normal, dtype=float)
        normal = normal / np.linalg.norm(normal)
        centre = body.point(np.asarray(contact.point, dtype=float))
        gaps.append(ca.dot(ca.DM(normal), centre - ca.DM(contact.plane_point)) - contact.radius)
        # velocity of the material point touching the plane: centre - radius n
        arm = ca.mtimes(body.rotation, ca.DM(contact.point)) - contact.radius * ca.DM(normal)
        velocity = body.velocity + ca.cross(body.angular_velocity, arm)
        normal_velocity.append(ca.dot(ca.DM(normal), velocity))
        tangent_velocity += [ca.dot(ca.DM(t_k), velocity) for t_k in plane_tangents(normal, planar)]
    g_n, u_n, u_t = ca.vertcat(*gaps), ca.vertcat(*normal_velocity), ca.vertcat(*tangent_velocity)
    zero_v = ca.DM.zeros(v.numel())
    w_n = ca.substitute(ca.jacobian(u_n, v), v, zero_v)
    w_t = ca.substitute(ca.jacobian(u_t, v), v, zero_v)
    u_f = ca.vertcat(empty, *[joint_rate(model, f.joint, bodies) for f in model.joint_frictions])
    w_f = ca.substitute(ca.jacobian(u_f, v), v, zero_v)

    def bias(u: Any) -> Any:  # d/dt of W v at fixed v: dU/dq q' + dU/dt
        return ca.mtimes(ca.jacobian(u, q), qdot) + ca.jacobian(u, t)

    return ContactForm(
        names=[c.name for c in model.contacts],
        restitution=np.array([c.restitution for c in model.contacts]),
        friction=np.array([c.friction for c in model.contacts]),
        n_tangent=1 if planar else 2,
        gaps=hot("contact_gaps", [t, q], [g_n]),
        normal_jacobian=hot("contact_W_N", [t, q], [w_n]),
        tangent_jacobian=hot("contact_W_T", [t, q], [w_t]),
        normal_bias=hot("contact_wdot_N", [t, q, v], [bias(u_n)]),
        tangent_bias=hot("contact_wdot_T", [t, q, v], [bias(u_t)]),
        joint_friction_names=[f.name for f in model.joint_frictions],
        joint_friction_bound=np.array([f.bound for f in model.joint_frictions]),
        joint_rate_jacobian=hot("joint_W_F", [t, q], [w_f]),
        joint_rate_bias=hot("joint_wdot_F", [t, q, v], [bias(u_f)]),
    )


def sphere_pair(
    contact: SphereContact, bodies: dict[str, BodyState], planar: bool
) -> tuple[Any, Any, Any, list[Any]]:
    """(gap, relative velocity of the touching points, normal, tangents) of a sphere pair:
    g_N = |c_B - c_A| - r_A - r_B, n = (c_B - c_A) / |c_B - c_A| from A to B, the velocity
    of B's point c_B - r_B n minus A's c_A + r_A n (so n . it = g_N'), tangents as
    :func:`plane_tangents` makes them from the (configuration-dependent) normal."""
    body_a, body_b = bodies[contact.body_a], _body_or_ground(contact.body_b, bodies)
    centre_a = body_a.point(np.asarray(contact.centre_a, dtype=float))
    centre_b = body_b.point(np.asarray(contact.centre_b, dtype=float))
    distance = ca.norm_2(centre_b - centre_a)
    normal = (centre_b - centre_a) / distance
    touch_a = centre_a + contact.radius_a * normal
    touch_b = centre_b - contact.radius_b * normal
    velocity_b = body_b.velocity + ca.cross(body_b.angular_velocity, touch_b - body_b.position)
    velocity_a = body_a.velocity + ca.cross(body_a.angular_velocity, touch_a - body_a.position)
    velocity = velocity_b - velocity_a
    if planar:
        tangents = [ca.vertcat(normal[1], -normal[0], 0)]
    else:  # the helper axis least along n (as plane_tangents), chosen symbolically
        ax, ay, az = (ca.fabs(normal[i]) for i in range(3))
        helper = ca.if_else(
            ca.logic_and(ax <= ay, ax <= az), ca.DM([1, 0, 0]),
            ca.if_else(ay <= az, ca.DM([0, 1, 0]), ca.DM([0, 0, 1])),
        )  # fmt: skip
        first = ca.cross(helper, normal)
        first = first / ca.norm_2(first)
        tangents = [first, ca.cross(normal, first)]
    return distance - contact.radius_a - contact.radius_b, velocity, normal, tangents


def _body_or_ground(name: str, bodies: dict[str, BodyState]) -> BodyState:
    zero = ca.DM.zeros(3)
    return BodyState(zero, ca.DM.eye(3), zero, zero) if name == GROUND else bodies[name]


def joint_rate(model: Model, name: str, bodies: dict[str, BodyState]) -> Any:
    """The rate of one-coordinate joint ``name`` from its bodies' twists: the relative
    angular velocity about the axis (revolute) or the relative velocity of the joint
    frames' origins along it, seen from the parent (prismatic); the axis in frame P."""
    joint = model.joints[name]
    zero = ca.DM.zeros(3)
    ground = BodyState(zero, ca.DM.eye(3), zero, zero)
    parent = ground if joint.parent == GROUND else bodies[joint.parent]
    child = bodies[joint.child]
    origin_p, rotation_p = parent.frame(joint.parent_frame)
    axis = ca.mtimes(rotation_p, ca.DM(joint.axis / np.linalg.norm(joint.axis)))
    if joint.type == "revolute":
        return ca.dot(axis, child.angular_velocity - parent.angular_velocity)
    origin_c = child.point(joint.child_frame.position)
    relative = (child.point_velocity(joint.child_frame.position)
                - parent.point_velocity(joint.parent_frame.position)
                - ca.cross(parent.angular_velocity, origin_c - origin_p))  # fmt: skip
    return ca.dot(axis, relative)
