"""Shared pieces of catalog problems: mass properties of simple bodies and momenta.

Not a problem module (the leading underscore keeps the registry from importing it as
one). Everything is in SI units; vectors are NumPy arrays of shape (3,).
"""

from __future__ import annotations

import numpy as np

from workbench.model import Model
from workbench.numerics.rotations import quaternion_to_matrix


def rod(
    mass: float, start: np.ndarray, end: np.ndarray, radius: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """(centre of mass (3,), inertia (3, 3) about it) of a uniform solid cylinder.

    The cylinder of ``radius`` (m) runs from ``start`` to ``end`` (m, body frame); its
    axial moment is m r^2 / 2 and its transverse moment m (3 r^2 + L^2) / 12, so the
    tensor is positive definite and satisfies the triangle inequality for any length.
    """
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    axis = end - start
    length = float(np.linalg.norm(axis))
    direction = axis / length
    axial = mass * radius**2 / 2
    transverse = mass * (3 * radius**2 + length**2) / 12
    inertia = transverse * np.eye(3) + (axial - transverse) * np.outer(direction, direction)
    return (start + end) / 2, inertia


def planar_rod(mass: float, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre of mass (3,), Izz about it) of a thin uniform bar in the x-y plane (m, kg)."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    length = float(np.linalg.norm(end - start))
    return (start + end) / 2, mass * length**2 / 12


def rotation_matrices(quaternions: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of Euler parameters (..., 4), scalar first."""
    matrices = quaternion_to_matrix(np.moveaxis(np.asarray(quaternions, dtype=float), -1, 0))
    return np.moveaxis(matrices, (0, 1), (-2, -1))


def angular_momentum(
    model: Model, poses: np.ndarray, twists: np.ndarray, point: np.ndarray | None = None
) -> np.ndarray:
    """Total angular momentum (..., 3) in kg m^2/s about a fixed ``point`` (default origin).

    poses (..., n_bodies, 7) [position, quaternion scalar-first] and twists
    (..., n_bodies, 6) [velocity of the body-frame origin, angular velocity], inertial,
    bodies in ``model.bodies`` order; leading axes are samples (metrics pass a whole
    trajectory at once): sum of m (r_c - point) x v_c + R I_c R^T omega.
    """
    point = np.zeros(3) if point is None else np.asarray(point, dtype=float)
    bodies = list(model.bodies.values())
    nb = len(bodies)
    poses, twists = np.asarray(poses, dtype=float), np.asarray(twists, dtype=float)
    rotations = rotation_matrices(poses[..., :nb, 3:7])
    omega = twists[..., :nb, 3:6]
    centres = np.array([b.com for b in bodies], dtype=float)
    offset = np.einsum("...bij,bj->...bi", rotations, centres)
    r_c = poses[..., :nb, :3] + offset
    v_c = twists[..., :nb, :3] + np.cross(omega, offset)
    masses = np.array([b.mass for b in bodies], dtype=float)
    total = np.einsum("b,...bi->...i", masses, np.cross(r_c - point, v_c))
    inertia = np.array([np.zeros((3, 3)) if b.point_mass else b.inertia for b in bodies])
    body_omega = np.einsum("...bji,...bj->...bi", rotations, omega)  # R^T omega
    spin = np.einsum("...bij,bjk,...bk->...i", rotations, inertia, body_omega)
    return total + spin


def quaternion_product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Product p q of quaternions (scalar first), broadcasting over leading axes."""
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    p0, pv = p[..., :1], p[..., 1:]
    q0, qv = q[..., :1], q[..., 1:]
    scalar = p0 * q0 - np.sum(pv * qv, axis=-1, keepdims=True)
    vector = p0 * qv + q0 * pv + np.cross(pv, qv)
    return np.concatenate([scalar, vector], axis=-1)


def axis_angle_quaternion(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4), scalar first, of rotations by ``angle`` (rad) about unit ``axis``."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    half = np.asarray(angle, dtype=float)[..., None] / 2
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)
