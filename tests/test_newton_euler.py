"""Projected Newton-Euler mass matrix and bias (workbench.mechanics.newton_euler).

Checked against quantities computed another way: M against the Hessian of the kinetic
energy T(q, v) = sum 1/2 m |v_c|^2 + 1/2 w^T I w, and h against Lagrange's equations
d/dt dT/dv - dT/dq = M v' + h for coordinates with q' = v.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from workbench.mechanics.kinematics import TreeKinematics
from workbench.mechanics.newton_euler import mass_and_bias
from workbench.model import Frame, Model


def random_spatial_tree(seed: int = 3) -> Model:
    """Five bodies, revolute / prismatic / cylindrical / universal joints with skew axes and
    rotated frames, centres of mass off the body frame origins, full inertia tensors, a
    branch, and a point mass."""
    rng = np.random.default_rng(seed)
    model = Model("random-tree", kind="spatial")

    def inertia() -> np.ndarray:  # principal moments in [0.1, 0.15] (a physical body)
        rotation = Rotation.random(random_state=rng).as_matrix()
        return rotation @ np.diag(rng.uniform(0.1, 0.15, 3)) @ rotation.T

    def frame() -> Frame:
        return Frame(rng.uniform(-0.5, 0.5, 3), Rotation.random(random_state=rng).as_matrix())

    def axis() -> np.ndarray:
        return rng.standard_normal(3)

    joints = [
        ("b0", "ground", "revolute"),
        ("b1", "b0", "prismatic"),
        ("b2", "b1", "cylindrical"),
        ("b3", "b0", "universal"),
    ]
    for body, parent, kind in joints:
        mass, com = rng.uniform(0.5, 2.0), rng.uniform(-0.3, 0.3, 3)
        model.add_body(body, mass, com=com, inertia=inertia())
        a1 = axis()
        a2 = np.cross(a1, axis())  # a universal joint's axes are perpendicular
        model.add_joint(
            f"{body}-joint", kind, parent, body, parent_frame=frame(), child_frame=frame(),
            axis=a1, axis2=a2,
        )
    model.add_point_mass("tip", 0.7)
    model.add_joint(
        "tip-joint", "revolute", "b2", "tip", parent_frame=frame(), child_frame=Frame.at(0.4),
        axis=axis(),
    )
    return model


def kinetic_energy(model: Model, kinematics: TreeKinematics) -> ca.SX:
    energy = ca.SX(0)
    for name, body in model.bodies.items():
        state = kinematics.bodies[name]
        v_com = state.point_velocity(body.com)
        omega = state.angular_velocity
        inertia = ca.mtimes([state.rotation, ca.DM(body.inertia), state.rotation.T])
        energy += 0.5 * body.mass * ca.dot(v_com, v_com)
        energy += 0.5 * ca.dot(omega, ca.mtimes(inertia, omega))
    return energy


def test_mass_matrix_is_the_hessian_of_the_kinetic_energy() -> None:
    model = random_spatial_tree()
    k = TreeKinematics(model.validate())
    mass, _ = mass_and_bias(model, k.bodies, k.t, k.q, k.v, k.qdot)
    hessian = ca.hessian(kinetic_energy(model, k), k.v)[0]
    f = ca.Function("f", [k.q], [ca.densify(mass), ca.densify(hessian)])
    rng = np.random.default_rng(0)
    for _ in range(3):
        m_value, h_value = (np.asarray(x) for x in f(rng.uniform(-1, 1, k.nq)))
        np.testing.assert_allclose(m_value, h_value, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(m_value, m_value.T, atol=1e-12)
        assert np.linalg.eigvalsh(m_value).min() > 0


def test_bias_follows_lagrange_equations() -> None:
    # all joints of random_spatial_tree have q' = v: h = (d(M v)/dq) v - dT/dq
    model = random_spatial_tree()
    k = TreeKinematics(model.validate())
    mass, bias = mass_and_bias(model, k.bodies, k.t, k.q, k.v, k.qdot)
    energy = kinetic_energy(model, k)
    momentum = ca.gradient(energy, k.v)
    lagrange = ca.mtimes(ca.jacobian(momentum, k.q), k.v) - ca.gradient(energy, k.q)
    f = ca.Function("f", [k.q, k.v], [ca.densify(bias), ca.densify(lagrange)])
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v = rng.uniform(-1, 1, k.nq), rng.uniform(-2, 2, k.nv)
        h_value, l_value = (np.asarray(x).ravel() for x in f(q, v))
        np.testing.assert_allclose(h_value, l_value, rtol=1e-10, atol=1e-10)
        assert np.abs(h_value).max() > 1e-3  # a real check, not 0 = 0


def test_a_point_mass_contributes_only_m_jt_jt() -> None:
    model = Model("point", kind="spatial")
    model.add_point_mass("p", 2.0)
    model.add_joint("j", "revolute", "ground", "p", parent_frame=Frame.at(0, 0, 0),
                    child_frame=Frame.at(0.5, 0, 0))
    k = TreeKinematics(model.validate())
    mass, bias = mass_and_bias(model, k.bodies, k.t, k.q, k.v, k.qdot)
    m_value, h_value = (np.asarray(x) for x in ca.Function("f", [k.q, k.v], [mass, bias])(0.3, 2.0))
    np.testing.assert_allclose(m_value, [[2.0 * 0.5**2]], rtol=1e-14)
    np.testing.assert_allclose(h_value, [[0.0]], atol=1e-14)  # centripetal force is normal
