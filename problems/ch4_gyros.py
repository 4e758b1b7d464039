"""Torque-free gyros (book 4.8.1): a rigid body turning about its fixed centre of mass.

Two problems, both spatial with no gravity (gravity = (0, 0, 0) m/s^2) and one body
``gyro`` whose body frame sits at its centre of mass, held by a spherical joint ``pivot``
from the ground at the origin (3 DOF; coordinates: the gyro's Euler parameters, scalar
first; velocities: its angular velocity in the body frame). With no applied moment the
kinetic energy and all three components of the angular momentum (inertial) are conserved.

``torque-free-gyro`` — asymmetric body, principal moments (A, B, C) = (0.02, 0.03,
0.04) kg m^2 and mass 1 kg (drawn as the box with these moments). It starts at the
identity orientation turning at (0.2, 6.0, 0.2) rad/s in the body frame: close to the
intermediate axis, so it tumbles (the Dzhanibekov flip: w2 changes sign at t = 2.60 s
and 6.98 s). t_end = 5 s. Invariants: energy (measured by the runner) and the
angular momentum components ``angular_momentum_x/y/z`` (kg m^2/s). No reference given
(the exact solution needs Jacobi elliptic functions and a quadrature).

``torque-free-symmetric-gyro`` — symmetric body, A = B = 0.02 kg m^2 transverse and
C = 0.04 kg m^2 axial (an oblate disk). It starts tilted by 0.3 rad about the inertial x
axis, turning at (2, 0, 10) rad/s in the body frame. Analytic reference (regular
precession): the body angular velocity components (w1, w2) rotate in the body at rate
(C - A) / A * w3 while w3 stays constant; the orientation is

    R(t) = Rot(L / |L|, |L| t / A) R0 Rot(e3, (A - C) / A * w3 t),

a rotation about the fixed angular momentum L at the precession rate |L| / A composed
with a spin about the symmetry axis e3 (from omega = (|L| / A) L/|L| + ((A - C) / A) w3 e3).
Invariants: as above. t_end = 5 s.
"""

from __future__ import annotations

from functools import partial

import numpy as np

import workbench.registry
from problems._parts import angular_momentum, axis_angle_quaternion, quaternion_product
from workbench.model import Frame, Model, Shape
from workbench.problem import Invariant, Problem, Reference
from workbench.rotations import quaternion_to_matrix

ASYMMETRIC_INERTIA = (0.02, 0.03, 0.04)  # kg m^2, principal (A, B, C)
ASYMMETRIC_OMEGA = (0.2, 6.0, 0.2)  # rad/s, body frame, near the intermediate axis
SYMMETRIC_INERTIA = (0.02, 0.02, 0.04)  # kg m^2, (A, A, C)
SYMMETRIC_OMEGA = (2.0, 0.0, 10.0)  # rad/s, body frame
SYMMETRIC_TILT = 0.3  # rad, initial rotation about the inertial x axis
MASS = 1.0  # kg (does not enter the rotational motion)


def angular_momentum_component(
    axis: int, model: Model, t: float, poses: np.ndarray, twists: np.ndarray
) -> float:
    """Component ``axis`` (0, 1, 2 = x, y, z) of the angular momentum about the origin."""
    return float(angular_momentum(model, poses, twists)[axis])


def angular_momentum_invariants() -> list[Invariant]:
    return [
        Invariant(f"angular_momentum_{'xyz'[i]}", partial(angular_momentum_component, i))
        for i in range(3)
    ]


def gyro_model(name: str, inertia: tuple[float, float, float]) -> Model:
    model = Model(name, kind="spatial", gravity=(0.0, 0.0, 0.0))
    # box edges (a, b, c) with these principal moments: a^2 = 6 (B + C - A) / m, ...
    a, b, c = (
        np.sqrt(6 * max(inertia[(i + 1) % 3] + inertia[(i + 2) % 3] - inertia[i], 0.0) / MASS)
        for i in range(3)
    )
    model.add_body("gyro", MASS, inertia=inertia, shapes=[Shape("box", (a, b, max(c, 0.01)))])
    model.add_joint("pivot", "spherical", "ground", "gyro", child_frame=Frame())
    return model


@workbench.registry.problem
class TorqueFreeGyro(Problem):
    name = "torque-free-gyro"
    summary = "Asymmetric torque-free rigid body spun near its intermediate axis (3 DOF)"
    source = "book 4.8.1"
    t_end = 5.0
    n_samples = 501
    conservative = True

    def model(self) -> Model:
        return gyro_model(self.name, ASYMMETRIC_INERTIA)

    def initial_joint_coordinates(self) -> dict[str, np.ndarray]:
        return {"pivot": np.array([1.0, 0.0, 0.0, 0.0])}

    def initial_joint_velocities(self) -> dict[str, np.ndarray]:
        return {"pivot": np.array(ASYMMETRIC_OMEGA)}

    def invariants(self) -> list[Invariant]:
        return angular_momentum_invariants()


def symmetric_gyro_quaternions(
    times: np.ndarray,
    transverse: float = SYMMETRIC_INERTIA[0],
    axial: float = SYMMETRIC_INERTIA[2],
    q0: np.ndarray | None = None,
    omega0: tuple[float, float, float] | np.ndarray = SYMMETRIC_OMEGA,
) -> np.ndarray:
    """Orientation quaternions (n_times, 4), scalar first, of a torque-free symmetric gyro.

    ``transverse`` A and ``axial`` C (kg m^2), initial orientation ``q0`` and initial
    body angular velocity ``omega0`` (rad/s): q(t) = q_L(|L| t / A) q0 q_3((A - C) w3 t / A).
    """
    q0 = axis_angle_quaternion([1.0, 0, 0], SYMMETRIC_TILT) if q0 is None else np.asarray(q0)
    omega0 = np.asarray(omega0, dtype=float)
    momentum = quaternion_to_matrix(q0) @ (np.array([transverse, transverse, axial]) * omega0)
    size = float(np.linalg.norm(momentum))
    times = np.asarray(times, dtype=float)
    precession = axis_angle_quaternion(momentum / size, size / transverse * times)
    spin = axis_angle_quaternion(
        [0.0, 0.0, 1.0], (transverse - axial) / transverse * omega0[2] * times
    )
    quaternions = quaternion_product(quaternion_product(precession, q0), spin)
    return quaternions * np.where(quaternions[..., :1] < 0, -1.0, 1.0)


@workbench.registry.problem
class TorqueFreeSymmetricGyro(Problem):
    name = "torque-free-symmetric-gyro"
    summary = "Symmetric torque-free gyro in regular precession, analytic reference (3 DOF)"
    source = "book 4.8.1"
    t_end = 5.0
    n_samples = 501
    conservative = True

    def model(self) -> Model:
        return gyro_model(self.name, SYMMETRIC_INERTIA)

    def initial_joint_coordinates(self) -> dict[str, np.ndarray]:
        return {"pivot": axis_angle_quaternion([1.0, 0.0, 0.0], SYMMETRIC_TILT)}

    def initial_joint_velocities(self) -> dict[str, np.ndarray]:
        return {"pivot": np.array(SYMMETRIC_OMEGA)}

    def invariants(self) -> list[Invariant]:
        return angular_momentum_invariants()

    def reference(self) -> Reference:
        return Reference(
            "analytic",
            symmetric_gyro_poses,
            "regular precession: rotation about the fixed angular momentum at |L|/A "
            "composed with the spin (A - C)/A w3 about the symmetry axis (book 4.8.1)",
        )


def symmetric_gyro_poses(times: np.ndarray) -> np.ndarray:
    """Reference poses (n_times, 1, 7) of ``torque-free-symmetric-gyro``: at the origin."""
    quaternions = symmetric_gyro_quaternions(np.atleast_1d(times))
    positions = np.zeros((quaternions.shape[0], 3))
    return np.concatenate([positions, quaternions], axis=1)[:, None, :]
