"""Holonomic spatial multibody systems (book 7.7): the robot with two revolute joints (7.7.2).

(The heavy gyro of 7.7.1 is ``heavy-top`` in :mod:`problems.heavy_top`.)

``two-joint-robot`` — spatial; z up; gravity (0, 0, -9.81) m/s^2.

- body ``turret``: solid cylinder about the vertical, radius 0.1 m, height h = 0.5 m,
  m1 = 5.0 kg; body frame at its foot on the base axis, centre of mass (0, 0, h/2),
  inertia about it diag(m1 (3 r^2 + h^2) / 12, same, m1 r^2 / 2);
- joint ``base``: revolute from the ground at the origin about the vertical z axis;
- body ``arm``: uniform solid rod, length L = 0.8 m, radius 0.02 m, m2 = 2.0 kg, with a
  0.05 m lateral offset of its centre of mass (a clamp), body frame at the shoulder, the
  rod along body x: centre of mass (L/2, 0.05, 0), inertia of the rod about it;
- joint ``shoulder``: revolute at the top of the turret (0, 0, h) about the turret's
  horizontal y axis; angle 0 = arm horizontal, positive = arm tip down.

Joint torques (JointForce, N m): ``base_torque`` prescribed, tau1(t) = 2 sin(2 t);
``shoulder_torque`` a PD law towards the angle 0.3 rad, tau2 = -60 (q2 - 0.3) - 5 q2'
(no gravity compensation: the arm settles about 0.13 rad lower). The PD spring-damper
and the prescribed torque do work, so conservative = False and no invariant holds.
2 DOF, no loops. Initial state: (q1, q2) = (0, 0) rad, (q1', q2') = (1.0, 0) rad/s.
t_end = 3 s. No analytic reference.
"""

from __future__ import annotations

import casadi as ca

import workbench.plugin.registry
from workbench.model import Frame, JointForce, Model, Shape
from workbench.plugin.problem import Problem
from workbench.problems._parts import rod

GRAVITY = 9.81  # m/s^2
TURRET_RADIUS = 0.1  # m
TURRET_HEIGHT = 0.5  # m
TURRET_MASS = 5.0  # kg
ARM_LENGTH = 0.8  # m
ARM_RADIUS = 0.02  # m
ARM_MASS = 2.0  # kg
ARM_COM_OFFSET = 0.05  # m, lateral (body y)
BASE_TORQUE_AMPLITUDE = 2.0  # N m
BASE_TORQUE_FREQUENCY = 2.0  # rad/s
SHOULDER_TARGET = 0.3  # rad
SHOULDER_STIFFNESS = 60.0  # N m / rad
SHOULDER_DAMPING = 5.0  # N m s / rad


def base_torque(t, q, v):
    """Prescribed base torque (N m)."""
    return BASE_TORQUE_AMPLITUDE * ca.sin(BASE_TORQUE_FREQUENCY * t)


def shoulder_torque(t, q, v):
    """PD torque (N m) towards ``SHOULDER_TARGET``."""
    return -SHOULDER_STIFFNESS * (q[0] - SHOULDER_TARGET) - SHOULDER_DAMPING * v[0]


@workbench.plugin.registry.problem
class TwoJointRobot(Problem):
    name = "two-joint-robot"
    summary = "Spatial robot: turret and arm on two revolute joints under joint torques (2 DOF)"
    source = "book 7.7.2"
    t_end = 3.0
    n_samples = 301
    conservative = False

    def model(self) -> Model:
        r, h, m1 = TURRET_RADIUS, TURRET_HEIGHT, TURRET_MASS
        model = Model(self.name, kind="spatial", gravity=(0.0, 0.0, -GRAVITY))
        transverse = m1 * (3 * r**2 + h**2) / 12
        model.add_body(
            "turret",
            m1,
            com=(0.0, 0.0, h / 2),
            inertia=(transverse, transverse, m1 * r**2 / 2),
            shapes=[Shape("cylinder", (r, h), Frame.at(0, 0, h / 2))],
        )
        _, inertia = rod(ARM_MASS, (0, 0, 0), (ARM_LENGTH, 0, 0), ARM_RADIUS)
        model.add_body(
            "arm",
            ARM_MASS,
            com=(ARM_LENGTH / 2, ARM_COM_OFFSET, 0.0),
            inertia=inertia,
            shapes=[
                Shape(
                    "capsule",
                    (ARM_RADIUS, ARM_LENGTH),
                    Frame(
                        (ARM_LENGTH / 2, 0.0, 0.0),
                        [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
                    ),
                    color=(220, 140, 60),
                )
            ],
        )
        model.add_joint("base", "revolute", "ground", "turret", axis=(0.0, 0.0, 1.0))
        model.add_joint(
            "shoulder",
            "revolute",
            "turret",
            "arm",
            parent_frame=Frame.at(0, 0, h),
            axis=(0.0, 1.0, 0.0),
        )
        model.add_force(JointForce("base_torque", "base", base_torque))
        model.add_force(JointForce("shoulder_torque", "shoulder", shoulder_torque))
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"base": 0.0, "shoulder": 0.0}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"base": 1.0, "shoulder": 0.0}
