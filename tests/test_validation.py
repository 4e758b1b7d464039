"""Every bad model raises a ModelError naming the element and the fix
(workbench.model.validation)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from workbench.errors import ModelError
from workbench.model import (
    AppliedForce,
    Drive,
    Frame,
    JointForce,
    JointSpringDamper,
    KnifeEdge,
    Model,
    RollingDisk,
    RollingSphere,
    Shape,
    SpringDamper,
)
from workbench.model.validation import validate_model
from workbench.numerics.rotations import axis_angle_to_matrix

CUBE = np.diag([0.1, 0.1, 0.1])


def pendulum(kind: str = "spatial") -> Model:
    """A valid one-link pendulum: body 'link' on revolute 'hinge' from the ground."""
    model = Model("pendulum", kind=kind)
    model.add_body("link", 1.0, com=(0.0, -0.5, 0.0), inertia=CUBE)
    model.add_joint("hinge", "revolute", "ground", "link")
    return model


def chain(kind: str = "spatial") -> Model:
    model = pendulum(kind)
    model.add_body("link2", 1.0, com=(0.0, -0.5, 0.0), inertia=CUBE)
    model.add_joint("hinge2", "revolute", "link", "link2", parent_frame=Frame.at(0, -1, 0))
    return model


# ---- valid models pass ---------------------------------------------------------------


def test_valid_spatial_model_passes() -> None:
    model = chain()
    model.add_body("ball", 2.0, inertia=(0.1, 0.1, 0.1), shapes=[Shape("sphere", (0.1,))])
    model.add_joint("float", "free", "ground", "ball")
    model.add_joint("loop", "spherical", "link2", "ball", parent_frame=Frame.at(0, -1, 0), cut=True)
    model.add_force(
        SpringDamper("spring", "ground", np.zeros(3), "link", np.zeros(3), 10.0, 0.5, 0.2)
    )
    model.add_force(JointSpringDamper("torsion", "hinge", 1.0, 0.1))
    model.add_force(JointForce("motor", "hinge2", lambda t, q, v: 0.0 * t))
    model.add_force(
        AppliedForce("push", "link", np.zeros(3), lambda t, p, r, v, w: (np.zeros(3), np.zeros(3)))
    )
    model.add_nonholonomic(RollingSphere("roll", "ball", 0.1))
    model.add_nonholonomic(KnifeEdge("knife", "link2", np.zeros(3), np.array([1.0, 0, 0])))
    assert model.validate() is model


def test_valid_planar_model_passes() -> None:
    model = Model("planar-ok", kind="planar")
    model.add_body("crank", 1.0, com=(0.05, 0, 0), inertia=0.01)
    model.add_joint("crank-joint", "revolute", "ground", "crank", axis=(0, 0, -1))
    model.add_body("slider", 1.0, inertia=0.01)
    model.add_joint(
        "slide",
        "prismatic",
        "ground",
        "slider",
        axis=(1, 1, 0),
        parent_frame=Frame(np.zeros(3), axis_angle_to_matrix((0, 0, 1), 0.3)),
    )
    model.add_point_mass("bob", 0.5)
    model.add_joint("bob-joint", "revolute", "crank", "bob", child_frame=Frame.at(0, 0.3, 0))
    model.add_nonholonomic(RollingDisk("disk", "slider", 0.2))
    validate_model(model)


def test_driven_joint_with_derivatives_passes() -> None:
    model = pendulum()
    model.add_body("arm", 1.0, inertia=CUBE)
    drive = Drive(lambda t: (t, 0.0), lambda t: (1.0, 0.0), lambda t: (0.0, 0.0))
    model.add_joint("wrist", "universal", "link", "arm", drive=drive)
    validate_model(model)


# ---- bodies ------------------------------------------------------------------------


@pytest.mark.parametrize("mass", [0.0, -1.0])
def test_nonpositive_mass(mass: float) -> None:
    model = pendulum()
    model.add_body("bad", mass, inertia=CUBE)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*mass must be > 0"):
        model.validate()


def test_nan_mass() -> None:
    model = pendulum()
    model.add_body("bad", math.nan, inertia=CUBE)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*mass.*not finite"):
        model.validate()


def test_nan_com() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, com=(0, math.inf, 0), inertia=CUBE)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*com.*NaN or inf"):
        model.validate()


def test_planar_com_out_of_plane() -> None:
    model = pendulum("planar")
    model.add_body("bad", 1.0, com=(0, 0, 0.1), inertia=1.0)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*x-y plane"):
        model.validate()


def test_missing_inertia() -> None:
    model = pendulum()
    model.add_body("bad", 1.0)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*give a 3x3 inertia tensor"):
        model.validate()


def test_scalar_inertia_in_spatial_model() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=0.2)
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*scalar.*give a 3x3 inertia tensor"):
        model.validate()


def test_inertia_with_inf() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=(1.0, math.inf, 1.0))
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*NaN or inf"):
        model.validate()


def test_inertia_not_symmetric() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]])
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*not symmetric"):
        model.validate()


def test_inertia_not_positive_definite() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=(1.0, 1.0, 0.0))
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*not positive definite"):
        model.validate()


def test_inertia_violates_triangle_inequality() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=(1.0, 1.0, 2.5))
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*triangle inequality"):
        model.validate()


def test_triangle_inequality_limit_passes() -> None:
    model = pendulum()
    model.add_body("disk", 1.0, inertia=(0.5, 0.5, 1.0 + 1e-12))  # thin disk
    model.add_joint("j", "revolute", "link", "disk")
    model.validate()


def test_bad_shape_size() -> None:
    model = pendulum()
    model.add_body("bad", 1.0, inertia=CUBE, shapes=[Shape("box", (1.0, -1.0, 1.0))])
    model.add_joint("j", "revolute", "link", "bad")
    with pytest.raises(ModelError, match=r"body 'bad'.*box shape size"):
        model.validate()


def test_bad_gravity() -> None:
    model = pendulum()
    model.gravity = np.array([0.0, 0.0, math.nan])
    with pytest.raises(ModelError, match=r"gravity.*NaN or inf"):
        model.validate()


def test_planar_gravity_out_of_plane() -> None:
    model = pendulum("planar")
    model.gravity = np.array([0.0, 0.0, -9.81])
    with pytest.raises(ModelError, match=r"gravity.*x-y plane"):
        model.validate()


def test_empty_model() -> None:
    with pytest.raises(ModelError, match=r"no bodies.*add_body"):
        Model("empty").validate()


def test_duplicate_name_at_add_time() -> None:
    model = pendulum()
    with pytest.raises(ModelError, match=r"duplicate name 'link'"):
        model.add_joint("link", "revolute", "ground", "link")


# ---- joints ----------------------------------------------------------------------


def test_unknown_joint_type_lists_valid_ones() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("weird", "helical", "link", "b")
    with pytest.raises(ModelError, match=r"joint 'weird'.*'helical'.*revolute, prismatic"):
        model.validate()


@pytest.mark.parametrize("role", ["parent", "child"])
def test_unknown_body_in_joint(role: str) -> None:
    model = pendulum()
    names = (
        {"parent": "nowhere", "child": "link"}
        if role == "parent"
        else {"parent": "link", "child": "nowhere"}
    )
    model.add_joint("j", "revolute", names["parent"], names["child"], cut=True)
    with pytest.raises(ModelError, match=rf"joint 'j'.*{role} 'nowhere' is not a body"):
        model.validate()


def test_tree_joint_child_ground() -> None:
    model = pendulum()
    model.add_joint("j", "revolute", "link", "ground")
    with pytest.raises(ModelError, match=r"joint 'j'.*child cannot be 'ground'"):
        model.validate()


def test_parent_equals_child() -> None:
    model = pendulum()
    model.add_joint("self", "revolute", "link", "link", cut=True)
    with pytest.raises(ModelError, match=r"joint 'self'.*parent and child are both 'link'"):
        model.validate()


def test_zero_axis() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("j", "prismatic", "link", "b", axis=(0, 0, 0))
    with pytest.raises(ModelError, match=r"joint 'j'.*axis has zero length"):
        model.validate()


def test_zero_axis2_of_universal() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("u", "universal", "link", "b", axis2=(0, 0, 0))
    with pytest.raises(ModelError, match=r"joint 'u'.*axis2 has zero length"):
        model.validate()


def test_parallel_universal_axes() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("u", "universal", "link", "b", axis=(0, 1, 0), axis2=(0, 2, 0))
    with pytest.raises(ModelError, match=r"joint 'u'.*parallel"):
        model.validate()


def test_nan_axis() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("j", "revolute", "link", "b", axis=(0, math.nan, 1))
    with pytest.raises(ModelError, match=r"joint 'j'.*axis.*NaN or inf"):
        model.validate()


def test_nan_frame_position() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("j", "revolute", "link", "b", parent_frame=Frame.at(math.nan, 0, 0))
    with pytest.raises(ModelError, match=r"joint 'j'.*parent_frame position.*NaN or inf"):
        model.validate()


def test_frame_rotation_not_orthonormal() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint(
        "j", "revolute", "link", "b", child_frame=Frame(np.zeros(3), np.diag([1.0, 2.0, 1.0]))
    )
    with pytest.raises(ModelError, match=r"joint 'j'.*child_frame rotation is not a rotation"):
        model.validate()


def test_frame_rotation_reflection() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint(
        "j", "revolute", "link", "b", child_frame=Frame(np.zeros(3), np.diag([1.0, 1.0, -1.0]))
    )
    with pytest.raises(ModelError, match=r"joint 'j'.*determinant \+1"):
        model.validate()


@pytest.mark.parametrize("joint_type", ["spherical", "universal", "cylindrical", "free"])
def test_joint_type_not_planar(joint_type: str) -> None:
    model = pendulum("planar")
    model.add_body("b", 1.0, inertia=1.0)
    model.add_joint("j", joint_type, "link", "b")
    with pytest.raises(ModelError, match=rf"joint 'j'.*{joint_type} joint does not fit a planar"):
        model.validate()


def test_planar_revolute_axis_not_z() -> None:
    model = pendulum("planar")
    model.add_body("b", 1.0, inertia=1.0)
    model.add_joint("j", "revolute", "link", "b", axis=(1, 0, 0))
    with pytest.raises(ModelError, match=r"joint 'j'.*revolute axis must be along \+z"):
        model.validate()


def test_planar_prismatic_axis_out_of_plane() -> None:
    model = pendulum("planar")
    model.add_body("b", 1.0, inertia=1.0)
    model.add_joint("j", "prismatic", "link", "b", axis=(1, 0, 1))
    with pytest.raises(ModelError, match=r"joint 'j'.*prismatic axis must lie in the x-y"):
        model.validate()


def test_planar_frame_z_offset() -> None:
    model = pendulum("planar")
    model.add_body("b", 1.0, inertia=1.0)
    model.add_joint("j", "revolute", "link", "b", parent_frame=Frame.at(0, 0, 0.1))
    with pytest.raises(ModelError, match=r"joint 'j'.*parent_frame must have zero z offset"):
        model.validate()


def test_planar_frame_rotation_not_about_z() -> None:
    model = pendulum("planar")
    model.add_body("b", 1.0, inertia=1.0)
    model.add_joint(
        "j",
        "revolute",
        "link",
        "b",
        child_frame=Frame(np.zeros(3), axis_angle_to_matrix((1, 0, 0), 0.2)),
    )
    with pytest.raises(ModelError, match=r"joint 'j'.*child_frame may rotate only about z"):
        model.validate()


def test_drive_without_derivatives() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("motor", "revolute", "link", "b", drive=Drive(lambda t: t))
    with pytest.raises(ModelError, match=r"joint 'motor'.*velocity and acceleration"):
        model.validate()


def test_multi_coordinate_drive_without_acceleration() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: (t, t), lambda t: (1.0, 1.0))
    model.add_joint("wrist", "cylindrical", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'wrist'.*lacks its acceleration"):
        model.validate()


def test_drive_returning_nan() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: t, lambda t: math.nan, lambda t: 0.0)
    model.add_joint("motor", "revolute", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'motor'.*velocity at t = 0.*not finite"):
        model.validate()


def test_drive_with_too_many_values() -> None:
    """A prismatic joint has one coordinate: a drive giving two was run as if it gave one."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: (t, t), lambda t: (1.0, 1.0), lambda t: (0.0, 0.0))
    model.add_joint("shake", "prismatic", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'shake'.*position gives 2 value.*has 1 coord"):
        model.validate()


def test_drive_velocity_not_the_derivative_of_its_position() -> None:
    """x = 0.1 sin 3t with x' = 0: every formalism integrated that incoherent motion."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: 0.1 * ca.sin(3 * t), lambda t: 0 * t, lambda t: 0 * t)
    model.add_joint("shake", "prismatic", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'shake'.*velocity is not the time derivative "
                       r"of its position: at t = 0 s, d\(position\)/dt = \[0.3\]"):
        model.validate()


def test_drive_acceleration_not_the_derivative_of_its_velocity() -> None:
    """Checked on a spherical joint too, whose velocity is not the quaternion's rate."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(
        lambda t: (ca.cos(t / 2), 0, 0, ca.sin(t / 2)),  # about z at 1 rad/s
        lambda t: (0, 0, 1 + 0 * t),
        lambda t: (0, 0, 1 + 0 * t),  # should be 0
    )
    model.add_joint("ball", "spherical", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'ball'.*acceleration is not the time deriv"):
        model.validate()


def test_drive_written_with_the_math_module() -> None:
    """math.sin of a CasADi symbol is nan without a word: minimal-ode then ran 'ok' with no
    error measured, recursive failed with 'array must not contain infs or NaNs'."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: 0.1 * math.sin(3 * t), lambda t: 0.3 * math.cos(3 * t),
                  lambda t: -0.9 * math.sin(3 * t))
    model.add_joint("shake", "prismatic", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'shake'.*position gives \[nan\] at t = 0 when "
                       r"t is a CasADi symbol.*casadi.sin"):
        model.validate()


def test_forces_written_with_the_math_module() -> None:
    """A motor torque 0.5 sin 2t written with math.sin: nan on the symbols every formalism
    builds with, and runs failed with 'array must not contain infs or NaNs'. Written with
    casadi.sin, and an applied force that is finite, they pass."""
    model = pendulum()
    model.add_force(JointForce("motor", "hinge", lambda t, q, v: 0.5 * math.sin(2 * t)))
    with pytest.raises(ModelError, match=r"force 'motor': the function gives \[nan\] when its "
                       r"arguments are CasADi symbols but \[0.0\] on the same numbers"):
        model.validate()
    model = pendulum()
    model.add_force(AppliedForce("push", "link", np.zeros(3), lambda t, r, rot, v, w: (
        (math.cos(t), 0, 0), (0, 0, 0))))  # fmt: skip
    with pytest.raises(ModelError, match=r"force 'push': the function gives \[nan, 0.0"):
        model.validate()
    model = pendulum()
    model.add_force(JointForce("motor", "hinge", lambda t, q, v: 0.5 * ca.sin(2 * t) - q))
    model.add_force(AppliedForce("push", "link", np.zeros(3), lambda t, r, rot, v, w: (
        ca.vertcat(ca.cos(t), 0, 0) - v, ca.DM.zeros(3))))  # fmt: skip
    model.validate()


def test_consistent_drives_pass() -> None:
    """Exact derivatives pass, on a prismatic and a spherical joint (the quaternion's
    rate gives the angular velocity), and on a free joint tumbling about a tilted axis
    while it moves (its rotation's rate about no body axis alone)."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_body("c", 1.0, inertia=CUBE)
    shake = Drive(lambda t: 0.1 * ca.sin(3 * t), lambda t: 0.3 * ca.cos(3 * t),
                  lambda t: -0.9 * ca.sin(3 * t))
    spin = Drive(lambda t: (ca.cos(t / 2), 0, 0, ca.sin(t / 2)), lambda t: (0, 0, 1 + 0 * t),
                 lambda t: (0, 0, 0 * t))
    model.add_joint("shake", "prismatic", "link", "b", drive=shake)
    model.add_joint("ball", "spherical", "b", "c", drive=spin)
    model.validate()
    model = pendulum()
    model.add_body("d", 1.0, inertia=CUBE)
    model.add_joint("flight", "free", "link", "d", drive=tumbling())
    model.validate()


def tumbling(rate: float = 1.0) -> Drive:
    """A free joint's drive: x = t^2 / 2 along x, turning about (0, 0.6, 0.8) fixed in both
    frames at 1 rad/s, so its angular velocity in the child frame is that axis; ``rate``:
    the angular velocity said (1: the true one)."""
    axis = (0.0, 0.6, 0.8)

    def position(t):
        half = t / 2
        return (t * t / 2, 0, 0, ca.cos(half), *(ca.sin(half) * a for a in axis))

    return Drive(position, lambda t: (t, 0, 0, *(rate * a + 0 * t for a in axis)),
                 lambda t: (1 + 0 * t, 0, 0, 0, 0, 0))  # fmt: skip


def test_drive_angular_velocity_not_the_rate_of_its_euler_parameters() -> None:
    """A free joint's drive saying twice the rotation's rate: the parameters' rate gives
    the angular velocity (2 G(p) p'), and it was never compared."""
    model = pendulum()
    model.add_body("d", 1.0, inertia=CUBE)
    model.add_joint("flight", "free", "link", "d", drive=tumbling(rate=2.0))
    with pytest.raises(ModelError, match=r"joint 'flight'.*velocity is not the time derivative "
                       r"of its position: at t = 0 s, d\(position\)/dt = \[0.0, 0.0, 0.0, 0.0, "
                       r"0.6, 0.8\] but velocity = \[0.0, 0.0, 0.0, 0.0, 1.2, 1.6\]"):
        model.validate()


def test_drive_euler_parameters_not_of_unit_norm() -> None:
    """A spherical drive of norm 2: its rotations came out orthonormal, and the run 'ok'."""
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    drive = Drive(lambda t: (2 * ca.cos(t / 2), 0, 0, 2 * ca.sin(t / 2)),
                  lambda t: (0, 0, 1 + 0 * t), lambda t: (0, 0, 0 * t))
    model.add_joint("ball", "spherical", "link", "b", drive=drive)
    with pytest.raises(ModelError, match=r"joint 'ball'.*Euler parameters at t = 0 s are "
                       r"\[2.0, 0.0, 0.0, 0.0\], of norm 2; give a unit quaternion"):
        model.validate()


def test_driven_cut_joint_passes() -> None:
    model = chain()
    drive = Drive(lambda t: t, lambda t: 1.0, lambda t: 0.0)
    model.add_joint("closure", "revolute", "ground", "link2", cut=True, drive=drive)
    model.validate()


# ---- topology --------------------------------------------------------------------


def test_body_not_connected_to_ground() -> None:
    model = pendulum()
    model.add_body("floating", 1.0, inertia=CUBE)
    with pytest.raises(ModelError, match=r"body 'floating'.*not connected to 'ground'"):
        model.validate()


def test_body_connected_only_by_cut_joint() -> None:
    model = pendulum()
    model.add_body("loose", 1.0, inertia=CUBE)
    model.add_joint("closure", "revolute", "link", "loose", cut=True)
    with pytest.raises(ModelError, match=r"body 'loose'.*not connected.*cut joints do not"):
        model.validate()


def test_body_with_two_parent_joints() -> None:
    model = chain()
    model.add_joint("again", "revolute", "ground", "link2")
    with pytest.raises(ModelError, match=r"body 'link2'.*child of two tree joints.*cut=True"):
        model.validate()


def test_tree_joints_forming_a_loop_off_ground() -> None:
    model = Model("ring")
    model.add_body("a", 1.0, inertia=CUBE)
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("ab", "revolute", "a", "b")
    model.add_joint("ba", "revolute", "b", "a")
    with pytest.raises(ModelError, match=r"body 'a'.*closed loop.*never reaches 'ground'"):
        model.validate()


# ---- point masses ---------------------------------------------------------------


@pytest.mark.parametrize("joint_type", ["spherical", "universal", "cylindrical", "free"])
def test_point_mass_on_spinning_joint(joint_type: str) -> None:
    model = pendulum()
    model.add_point_mass("bob", 1.0)
    model.add_joint("j", joint_type, "link", "bob", child_frame=Frame.at(0, 1, 0))
    with pytest.raises(ModelError, match=r"body 'bob'.*point mass would spin.*add_body"):
        model.validate()


def test_point_mass_on_revolute_without_offset() -> None:
    model = pendulum()
    model.add_point_mass("bob", 1.0)
    model.add_joint("j", "revolute", "link", "bob", child_frame=Frame.at(0, 0, 0.4), axis=(0, 0, 1))
    with pytest.raises(ModelError, match=r"body 'bob'.*revolute joint offset from the mass"):
        model.validate()


def test_point_mass_on_revolute_with_offset_passes() -> None:
    model = pendulum()
    model.add_point_mass("bob", 1.0)
    model.add_joint("j", "revolute", "link", "bob", child_frame=Frame.at(0, 0.4, 0))
    model.validate()


def test_point_mass_on_prismatic_passes() -> None:
    model = pendulum()
    model.add_point_mass("bob", 1.0)
    model.add_joint("j", "prismatic", "link", "bob", axis=(1, 0, 0))
    model.validate()


# ---- force elements and nonholonomic constraints ---------------------------------


def test_spring_unknown_body() -> None:
    model = pendulum()
    model.add_force(SpringDamper("spring", "ground", np.zeros(3), "lnik", np.zeros(3), 1.0))
    with pytest.raises(ModelError, match=r"force 'spring'.*body2 'lnik' is not a body"):
        model.validate()


@pytest.mark.parametrize("field", ["stiffness", "damping"])
def test_spring_negative_parameter(field: str) -> None:
    model = pendulum()
    values = {"stiffness": 1.0, "damping": 0.1, field: -1.0}
    model.add_force(
        SpringDamper(
            "spring",
            "ground",
            np.zeros(3),
            "link",
            np.zeros(3),
            values["stiffness"],
            values["damping"],
        )
    )
    with pytest.raises(ModelError, match=rf"force 'spring'.*{field} must be >= 0"):
        model.validate()


def test_spring_nan_point() -> None:
    model = pendulum()
    model.add_force(
        SpringDamper("spring", "ground", np.array([math.nan, 0, 0]), "link", np.zeros(3), 1.0)
    )
    with pytest.raises(ModelError, match=r"force 'spring'.*point1.*NaN or inf"):
        model.validate()


def test_joint_spring_unknown_joint() -> None:
    model = pendulum()
    model.add_force(JointSpringDamper("torsion", "hnige", 1.0))
    with pytest.raises(ModelError, match=r"force 'torsion'.*joint 'hnige' is not a joint"):
        model.validate()


def test_joint_spring_negative_damping() -> None:
    model = pendulum()
    model.add_force(JointSpringDamper("torsion", "hinge", 1.0, -0.5))
    with pytest.raises(ModelError, match=r"force 'torsion'.*damping must be >= 0"):
        model.validate()


def test_joint_spring_on_spherical_needs_a_rest_orientation() -> None:
    model = pendulum()
    model.add_body("b", 1.0, inertia=CUBE)
    model.add_joint("ball", "spherical", "link", "b")
    model.add_force(JointSpringDamper("torsion", "ball", 1.0))
    with pytest.raises(ModelError, match=r"force 'torsion'.*spherical joint 'ball'.*unit quat"):
        model.validate()
    model.forces[-1] = JointSpringDamper("torsion", "ball", 1.0, rest=(1.0, 0.0, 0.0, 0.0))
    model.validate()


def test_joint_force_unknown_joint() -> None:
    model = pendulum()
    model.add_force(JointForce("motor", "nope", lambda t, q, v: 0.0))
    with pytest.raises(ModelError, match=r"force 'motor'.*joint 'nope'"):
        model.validate()


def test_applied_force_unknown_body() -> None:
    model = pendulum()
    model.add_force(AppliedForce("push", "nope", np.zeros(3), lambda *a: (0, 0)))
    with pytest.raises(ModelError, match=r"force 'push'.*body 'nope' is not a body"):
        model.validate()


def test_applied_force_on_ground() -> None:
    model = pendulum()
    model.add_force(AppliedForce("push", "ground", np.zeros(3), lambda *a: (0, 0)))
    with pytest.raises(ModelError, match=r"force 'push'.*body cannot be 'ground'"):
        model.validate()


@pytest.mark.parametrize("radius", [0.0, -0.1])
def test_nonpositive_radius(radius: float) -> None:
    model = pendulum()
    model.add_nonholonomic(RollingSphere("roll", "link", radius))
    with pytest.raises(ModelError, match=r"constraint 'roll'.*radius must be > 0"):
        model.validate()


def test_nan_radius() -> None:
    model = pendulum()
    model.add_nonholonomic(RollingDisk("wheel", "link", math.nan))
    with pytest.raises(ModelError, match=r"constraint 'wheel'.*radius.*not finite"):
        model.validate()


def test_nonholonomic_unknown_body() -> None:
    model = pendulum()
    model.add_nonholonomic(KnifeEdge("knife", "blade", np.zeros(3), np.array([1.0, 0, 0])))
    with pytest.raises(ModelError, match=r"constraint 'knife'.*body 'blade' is not a body"):
        model.validate()


def test_knife_edge_zero_direction() -> None:
    model = pendulum()
    model.add_nonholonomic(KnifeEdge("knife", "link", np.zeros(3), np.zeros(3)))
    with pytest.raises(ModelError, match=r"constraint 'knife'.*direction has zero length"):
        model.validate()


def test_rolling_sphere_in_planar_model() -> None:
    model = pendulum("planar")
    model.add_nonholonomic(RollingSphere("roll", "link", 0.1))
    with pytest.raises(ModelError, match=r"constraint 'roll'.*needs a spatial model"):
        model.validate()


def test_a_massless_body_must_carry_other_bodies() -> None:
    """Mass 0 is a massless link between joints (a URDF gimbal's); at the end of a chain
    its joint would move nothing (a singular mass matrix)."""
    model = pendulum()
    model.add_point_mass("tip", 0.0)
    model.add_joint("wrist", "revolute", "link", "tip", axis=(0, 1, 0))
    with pytest.raises(ModelError, match=r"body 'tip': a massless body must carry other"):
        model.validate()
    model.add_body("hand", 1.0, com=(0.1, 0, 0), inertia=CUBE)
    model.add_joint("finger", "revolute", "tip", "hand", axis=(1, 0, 0))
    model.validate()
