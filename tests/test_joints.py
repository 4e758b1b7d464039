"""Joint kinematics: twists are time derivatives of transforms; implicit constraints vanish
exactly on the joint's motion and not off it; coordinates are recovered from poses."""

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.mechanics import joints as jk
from workbench.model import Joint

RNG = np.random.default_rng(7)


def make_joint(kind: str) -> Joint:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    axis2 = np.cross(axis, [1.0, 0, 0])
    return Joint("j", kind, "ground", "b", axis=axis, axis2=axis2 / np.linalg.norm(axis2))


def random_coordinates(joint: Joint) -> tuple[np.ndarray, np.ndarray]:
    nq, nv = jk.dimensions(joint)
    q = RNG.normal(size=nq)
    if joint.type == "spherical":
        q /= np.linalg.norm(q)
    if joint.type == "free":
        q[3:] /= np.linalg.norm(q[3:])
    return q, RNG.normal(size=nv)


SPATIAL = ["revolute", "prismatic", "cylindrical", "universal", "spherical", "planar", "free"]


@pytest.mark.parametrize("kind", SPATIAL)
def test_relative_twist_is_the_derivative_of_the_transform(kind):
    joint = make_joint(kind)
    q, v = random_coordinates(joint)
    qdot = np.asarray(jk.coordinate_rates(joint, q, v), dtype=float).ravel()
    h = 1e-6
    r_plus, rot_plus = jk.relative_transform(joint, q + h * qdot)
    r_minus, rot_minus = jk.relative_transform(joint, q - h * qdot)
    r, rot = jk.relative_transform(joint, q)
    velocity, omega = jk.relative_twist(joint, q, v)
    assert np.allclose(
        (np.ravel(r_plus) - np.ravel(r_minus)) / (2 * h), np.ravel(velocity), atol=1e-7
    )
    rot_dot = (np.asarray(rot_plus) - np.asarray(rot_minus)) / (2 * h)
    omega_skew = rot_dot @ np.asarray(rot).T
    assert np.allclose(
        [omega_skew[2, 1], omega_skew[0, 2], omega_skew[1, 0]], np.ravel(omega), atol=1e-6
    )


@pytest.mark.parametrize("kind", SPATIAL + ["fixed"])
def test_implicit_constraints_vanish_on_the_joint_motion_only(kind):
    joint = make_joint(kind)
    q, _ = random_coordinates(joint)
    rot_p = Rotation.random(random_state=3).as_matrix()
    r_p = RNG.normal(size=3)
    r_rel, rot_rel = jk.relative_transform(joint, q)
    r_c = r_p + rot_p @ np.ravel(r_rel)
    rot_c = rot_p @ np.asarray(rot_rel)
    residual = np.ravel(jk.implicit_constraints(joint, False, r_p, rot_p, r_c, rot_c))
    assert residual.size == jk.CONSTRAINT_ROWS["spatial"][kind]
    assert np.allclose(residual, 0.0, atol=1e-12)
    if residual.size:
        # a generic small displacement of C that the joint does not allow shows up
        moved = Rotation.from_rotvec([0.01, -0.02, 0.015]).as_matrix() @ rot_c
        shifted = r_c + np.array([0.01, 0.02, -0.01])
        off = np.ravel(jk.implicit_constraints(joint, False, r_p, rot_p, shifted, moved))
        assert np.abs(off).max() > 1e-4


@pytest.mark.parametrize("kind", ["revolute", "prismatic", "cylindrical", "planar"])
def test_relative_coordinates_invert_the_transform(kind):
    joint = make_joint(kind) if kind != "planar" else Joint("j", "planar", "ground", "b")
    q, _ = random_coordinates(joint)
    if kind in ("revolute", "cylindrical"):
        q[-1] = np.mod(q[-1] + np.pi, 2 * np.pi) - np.pi
    if kind == "planar":
        q[2] = np.mod(q[2] + np.pi, 2 * np.pi) - np.pi
    r_rel, rot_rel = jk.relative_transform(joint, q)
    recovered = np.ravel(jk.relative_coordinates(joint, np.ravel(r_rel), np.asarray(rot_rel)))
    assert np.allclose(recovered, q, atol=1e-12)


@pytest.mark.parametrize("angle_between_axes", [np.pi / 2, np.pi / 3, 2.5])
def test_universal_angles_are_recovered_from_the_transform(angle_between_axes):
    """Both angles of a universal joint, anywhere in (-pi, pi), perpendicular axes or not."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    normal = np.cross(axis, [1.0, 0, 0]) / np.linalg.norm(np.cross(axis, [1.0, 0, 0]))
    axis2 = np.cos(angle_between_axes) * axis + np.sin(angle_between_axes) * normal
    joint = Joint("j", "universal", "ground", "b", axis=axis, axis2=axis2)
    for q in np.random.default_rng(4).uniform(-np.pi, np.pi, (20, 2)):
        _, rot_rel = jk.relative_transform(joint, q)
        recovered = np.ravel(jk.relative_coordinates(joint, np.zeros(3), np.asarray(rot_rel)))
        assert np.allclose(recovered, q, rtol=0, atol=1e-13)


@pytest.mark.parametrize("kind", SPATIAL)
def test_symbolic_and_numeric_paths_agree(kind):
    joint = make_joint(kind)
    q, v = random_coordinates(joint)
    q_sym, v_sym = ca.SX.sym("q", q.size), ca.SX.sym("v", v.size)
    r, rot = jk.relative_transform(joint, q_sym)
    velocity, omega = jk.relative_twist(joint, q_sym, v_sym)
    function = ca.Function("f", [q_sym, v_sym], [r, rot, velocity, omega])
    symbolic = [np.asarray(x) for x in function(q, v)]
    numeric = [*jk.relative_transform(joint, q), *jk.relative_twist(joint, q, v)]
    for a, b in zip(symbolic, numeric, strict=True):
        assert np.allclose(np.ravel(a), np.ravel(np.asarray(b, dtype=float)), atol=1e-14)


def test_planar_rows_of_a_planar_revolute_and_prismatic_joint():
    revolute = Joint("r", "revolute", "ground", "b")
    prismatic = Joint("p", "prismatic", "ground", "b", axis=np.array([1.0, 0, 0]))
    rot = Rotation.from_rotvec([0, 0, 0.3]).as_matrix()
    assert np.allclose(
        jk.implicit_constraints(revolute, True, np.zeros(3), np.eye(3), np.zeros(3), rot), 0
    )
    # prismatic along x: sliding along x is allowed, sideways or rotating is not
    assert np.allclose(
        jk.implicit_constraints(
            prismatic, True, np.zeros(3), np.eye(3), np.array([0.7, 0, 0]), np.eye(3)
        ),
        0,
    )
    sideways = jk.implicit_constraints(
        prismatic, True, np.zeros(3), np.eye(3), np.array([0.7, 0.1, 0]), rot
    )
    assert np.allclose(np.abs(sideways), [0.1, np.sin(0.3)])
