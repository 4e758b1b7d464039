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
angular momentum components ``angular_momentum_x/y/z`` (kg m^2/s). Reference: stored
(``workbench reference torque-free-gyro``); the closed form (Euler-Poinsot: body rates by
Jacobi elliptic functions, orientation up to one quadrature, :func:`torque_free_body_rates`
and :func:`torque_free_quaternions`) checks it in the tests.

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
from scipy.integrate import quad
from scipy.special import ellipj, ellipkinc

import workbench.plugin.registry
from workbench.model import Frame, Model, Shape
from workbench.numerics.rotations import (
    euler_zxz_to_matrix,
    matrix_to_quaternion,
    quaternion_to_matrix,
)
from workbench.plugin.problem import Invariant, Problem, Reference
from workbench.problems._parts import angular_momentum, axis_angle_quaternion, quaternion_product

ASYMMETRIC_INERTIA = (0.02, 0.03, 0.04)  # kg m^2, principal (A, B, C)
ASYMMETRIC_OMEGA = (0.2, 6.0, 0.2)  # rad/s, body frame, near the intermediate axis
SYMMETRIC_INERTIA = (0.02, 0.02, 0.04)  # kg m^2, (A, A, C)
SYMMETRIC_OMEGA = (2.0, 0.0, 10.0)  # rad/s, body frame
SYMMETRIC_TILT = 0.3  # rad, initial rotation about the inertial x axis
MASS = 1.0  # kg (does not enter the rotational motion)


def angular_momentum_component(
    axis: int, model: Model, t: float, poses: np.ndarray, twists: np.ndarray
) -> np.ndarray:
    """Component ``axis`` (0, 1, 2 = x, y, z) of the angular momentum about the origin
    (vectorized)."""
    return angular_momentum(model, poses, twists)[..., axis]


def angular_momentum_invariants() -> list[Invariant]:
    return [
        Invariant(
            f"angular_momentum_{'xyz'[i]}",
            partial(angular_momentum_component, i),
            vectorized=True,
        )
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


@workbench.plugin.registry.problem
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


def torque_free_body_rates(
    times: np.ndarray, inertia: tuple[float, float, float], omega0: np.ndarray
) -> np.ndarray:
    """Body angular velocity (n_times, 3) rad/s of a torque-free body, in closed form.

    Principal moments ``inertia`` = (I1, I2, I3), I1 < I2 < I3 (kg m^2), body rates
    ``omega0`` at t = 0. Landau & Lifshitz, Mechanics, 37: with 2T = sum I w^2 and
    M^2 = sum I^2 w^2, for M^2 > 2T I2 (w3 keeps its sign)
    w = (a1 cn u, a2 sn u, a3 dn u), u = lambda t + u0, modulus
    k^2 = (I2 - I1)(2T I3 - M^2) / ((I3 - I2)(M^2 - 2T I1)); for M^2 < 2T I2 the roles
    of axes 1 and 3 swap (w1 ~ dn, w3 ~ cn). Signs: Euler's equations need s1 s2 = s3 and
    permutations; the phase u0 = F(atan2(sn0, cn0) | k^2) matches omega0.
    """
    i1, i2, i3 = (float(x) for x in inertia)
    if not i1 < i2 < i3:
        raise ValueError(f"principal moments must be distinct and ascending, not {inertia}")
    w = np.asarray(omega0, dtype=float)
    energy2 = float(np.dot(inertia, w**2))  # 2 T
    momentum2 = float(np.dot(np.square(inertia), w**2))  # M^2
    high, low = energy2 * i3 - momentum2, momentum2 - energy2 * i1  # both >= 0
    if min(high, low) <= 1e-15 * energy2 * i3:  # steady rotation about axis 3 or 1
        return np.tile(w, (np.size(times), 1))
    if momentum2 >= energy2 * i2:  # about axis 3: w1 ~ cn, w2 ~ sn, w3 ~ dn
        amplitude = np.sqrt(
            [high / (i1 * (i3 - i1)), high / (i2 * (i3 - i2)), low / (i3 * (i3 - i1))]
        )
        rate = np.sqrt((i3 - i2) * low / (i1 * i2 * i3))
        k2 = (i2 - i1) * high / ((i3 - i2) * low)
        sign = np.sign(w[2]) or 1.0
        signs, cn_axis, dn_axis = np.array([1.0, sign, sign]), 0, 2
    else:  # about axis 1: w1 ~ dn, w2 ~ sn, w3 ~ cn
        amplitude = np.sqrt(
            [high / (i1 * (i3 - i1)), low / (i2 * (i2 - i1)), low / (i3 * (i3 - i1))]
        )
        rate = np.sqrt((i2 - i1) * high / (i1 * i2 * i3))
        k2 = (i3 - i2) * low / ((i2 - i1) * high)
        sign = np.sign(w[0]) or 1.0
        signs, cn_axis, dn_axis = np.array([sign, sign, 1.0]), 2, 0
    scale = signs * amplitude
    u0 = ellipkinc(np.arctan2(w[1] / scale[1], w[cn_axis] / scale[cn_axis]), k2)
    sn, cn, dn, _ = ellipj(rate * np.asarray(times, dtype=float) + u0, k2)
    columns = {cn_axis: cn, 1: sn, dn_axis: dn}
    return scale * np.stack([columns[0], columns[1], columns[2]], axis=-1)


def torque_free_quaternions(
    times: np.ndarray, inertia: tuple[float, float, float], omega0: np.ndarray, q0: np.ndarray
) -> np.ndarray:
    """Orientation (n_times, 4), scalar first, of a torque-free body from ``q0`` at t = 0.

    With Z along the fixed angular momentum, R = G Rz(phi) Rx(theta) Rz(psi): theta and psi
    point the body's momentum direction I w / M (cos theta = I3 w3 / M,
    tan psi = I1 w1 / (I2 w2)), and phi' = M (I1 w1^2 + I2 w2^2) / (I1^2 w1^2 + I2^2 w2^2)
    (Landau & Lifshitz 37) is integrated by quadrature; G fixes R(0) = R(q0).
    """
    inertia_array = np.asarray(inertia, dtype=float)
    times = np.asarray(times, dtype=float)
    momentum = float(np.linalg.norm(inertia_array * np.asarray(omega0, dtype=float)))

    def angles(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        direction = inertia_array * torque_free_body_rates(t, inertia, omega0) / momentum
        return np.arccos(np.clip(direction[..., 2], -1, 1)), np.arctan2(
            direction[..., 0], direction[..., 1]
        )

    def precession_rate(t: float) -> float:
        w1, w2, _ = torque_free_body_rates(np.array([t]), inertia, omega0)[0]
        i1, i2 = inertia_array[:2]
        return momentum * (i1 * w1**2 + i2 * w2**2) / (i1**2 * w1**2 + i2**2 * w2**2)

    bounds = np.concatenate([[0.0], times])  # phi(0) = 0
    steps = [
        quad(precession_rate, a, b, epsabs=1e-14, epsrel=1e-13)[0]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    phi = np.cumsum(steps)
    theta, psi = angles(times)
    theta0, psi0 = angles(np.array([0.0]))
    start = euler_zxz_to_matrix([0.0, theta0[0], psi0[0]])
    fixed = quaternion_to_matrix(np.asarray(q0, dtype=float)) @ start.T
    return np.array(
        [
            matrix_to_quaternion(fixed @ euler_zxz_to_matrix([a, b, c]))
            for a, b, c in zip(phi, theta, psi, strict=True)
        ]
    )


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


@workbench.plugin.registry.problem
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
