"""Rotation parameterizations (book ch. 3), for NumPy arrays and CasADi symbols alike.

Conventions: rotation matrices map body-frame coordinates to inertial ones (active
rotation, r = R r'); Euler parameters (unit quaternions) are scalar-first
p = (p0, p1, p2, p3) as in the book; SciPy and Rerun use scalar-last and are converted
only at those boundaries. Angular velocities are given in the body frame ("body") or the
inertial frame ("inertial") as each function states.

Each minimal parameterization x (Cardan xyz, Euler zxz, Rodrigues vector) comes with
``*_to_matrix``, ``matrix_to_*``, the rate matrix K with x' = K(x) omega and the angular
velocity matrix G with omega = G(x) x' (G K = K G = I away from singularities).

Singularities: with NumPy input, ``matrix_to_*`` and the rate matrices raise
:class:`SingularityError` when the quantity that vanishes at the singular configuration
(|cos b| for Cardan xyz, |sin b| for Euler zxz, p0 = cos(angle/2) for the Rodrigues vector;
all dimensionless and at most 1) is <= ``tol`` (default 1e-9). CasADi symbols cannot be
checked: the formula is returned and evaluates to inf/nan (or an arbitrary split of the
angles) at the singularity. Euler parameters have no singularity.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError
from workbench.numerics.backend import entries, is_symbolic, matmul, matrix, ops, vector

SINGULAR_TOL = 1e-9
"""Default ``tol`` of the singularity checks (see the module docstring)."""


class SingularityError(WorkbenchError, ValueError):
    """A minimal rotation parameterization is evaluated at (or within tol of) its singularity."""


def skew(w: Any) -> Any:
    """The cross-product matrix: skew(w) @ x == w x x. w: (3,)."""
    w1, w2, w3 = entries(w, 3)
    return matrix([[0.0, -w3, w2], [w3, 0.0, -w1], [-w2, w1, 0.0]])


def axis_angle_to_matrix(axis: Any, angle: Any) -> Any:
    """Rodrigues' formula (book 3.3.2): rotation by ``angle`` (rad) about unit ``axis`` (3,)."""
    xp = ops(axis, angle)
    e1, e2, e3 = entries(axis, 3)
    c, s = xp.cos(angle), xp.sin(angle)
    v = 1 - c
    return matrix(
        [
            [c + e1 * e1 * v, e1 * e2 * v - e3 * s, e1 * e3 * v + e2 * s],
            [e2 * e1 * v + e3 * s, c + e2 * e2 * v, e2 * e3 * v - e1 * s],
            [e3 * e1 * v - e2 * s, e3 * e2 * v + e1 * s, c + e3 * e3 * v],
        ]
    )


def quaternion_to_matrix(p: Any) -> Any:
    """Rotation matrix of Euler parameters p = (p0, p1, p2, p3), scalar first (3.7.1).

    Written homogeneous and divided by p^T p, so R(s p) = R(p) for s > 0: Euler parameters
    that an integrator lets drift off the unit sphere still give a rotation (the unit-sphere
    form 2 (p0^2 + p1^2) - 1 ... is not one off the sphere, and the drift then fed back into
    the dynamics: issue 17 item 8, the rolling ball under IDA). For unit p the two agree.
    """
    p0, p1, p2, p3 = entries(p, 4)
    a, b, c, d = p0 * p0, p1 * p1, p2 * p2, p3 * p3
    norm2 = a + b + c + d
    inverse = 2 / (norm2 + norm2)  # 1 / p^T p; CasADi would turn x * (1 / y) into 9 x / y
    rows = [
        [a + b - c - d, 2 * (p1 * p2 - p0 * p3), 2 * (p1 * p3 + p0 * p2)],
        [2 * (p1 * p2 + p0 * p3), a - b + c - d, 2 * (p2 * p3 - p0 * p1)],
        [2 * (p1 * p3 - p0 * p2), 2 * (p2 * p3 + p0 * p1), a - b - c + d],
    ]
    return matrix([[entry * inverse for entry in row] for row in rows])


def quaternion_rate_matrix(p: Any, frame: str = "body") -> Any:
    """The 4x3 matrix H(p) with p' = H(p) omega (3.7.5).

    frame="body": omega in the body frame (p' = 1/2 p * (0, omega));
    frame="inertial": omega in the inertial frame (p' = 1/2 (0, omega) * p).
    """
    p0, p1, p2, p3 = entries(p, 4)
    if frame == "body":
        rows = [[-p1, -p2, -p3], [p0, -p3, p2], [p3, p0, -p1], [-p2, p1, p0]]
    elif frame == "inertial":
        rows = [[-p1, -p2, -p3], [p0, p3, -p2], [-p3, p0, p1], [p2, -p1, p0]]
    else:
        raise ValueError(f"frame must be 'body' or 'inertial', not {frame!r}")
    return matrix([[0.5 * x for x in row] for row in rows])


# --- helpers ------------------------------------------------------------------------------


def _check_frame(frame: str) -> None:
    if frame not in ("body", "inertial"):
        raise ValueError(f"frame must be 'body' or 'inertial', not {frame!r}")


def _as_matrix(R: Any) -> Any:
    """R unchanged if symbolic, else as a float NumPy array (so nested lists work too)."""
    return R if is_symbolic(R) else np.asarray(R, dtype=float)


def _check_singular(value: Any, tol: float, message: str) -> None:
    """Raise SingularityError if the NumPy number ``value`` (>= 0) is <= tol; skip symbols."""
    if not is_symbolic(value) and value <= tol:
        raise SingularityError(message.format(value=float(value), tol=tol))


_CARDAN_SINGULAR = (
    "xyz Cardan angles are singular at gimbal lock, b = +-pi/2, where the first and third "
    "axes coincide and only a +- c is defined (|cos b| = {value:.3g} <= tol = {tol:g}). "
    "Use Euler parameters (quaternions), or a rotation sequence whose singularity is far "
    "from this orientation."
)
_EULER_SINGULAR = (
    "zxz Euler angles are singular at b = 0 or pi, where the first and third axes coincide "
    "and only a +- c is defined (|sin b| = {value:.3g} <= tol = {tol:g}). Use Euler "
    "parameters (quaternions), or Cardan angles near this orientation."
)
_RODRIGUES_SINGULAR = (
    "the Rodrigues vector tan(angle/2) * axis is infinite at a rotation by pi (180 degrees) "
    "(p0 = cos(angle/2) = {value:.3g} <= tol = {tol:g}). Use Euler parameters (quaternions)."
)


# --- single and multiple rotations (3.3, 3.4) ---------------------------------------------


def elementary_rotation(axis: str | int, angle: Any) -> Any:
    """3x3 rotation by ``angle`` (rad) about the x, y or z axis ("x"/"y"/"z" or 0/1/2)."""
    index = {"x": 0, "y": 1, "z": 2, 0: 0, 1: 1, 2: 2}.get(axis)
    if index is None:
        raise ValueError(f"axis must be one of 'x', 'y', 'z', 0, 1, 2, not {axis!r}")
    xp = ops(angle)
    c, s = xp.cos(angle), xp.sin(angle)
    if index == 0:
        return matrix([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if index == 1:
        return matrix([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return matrix([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def compose(*matrices: Any) -> Any:
    """The product R1 R2 ... Rn of 3x3 rotation matrices, left to right (3.4); I if none."""
    result = np.eye(3)
    for rotation in matrices:
        result = matmul(result, rotation)
    return result


def matrix_to_axis_angle(R: Any) -> tuple[Any, Any]:
    """Axis (3,) and angle (rad, in [0, pi]) of the rotation matrix R (3.3.4).

    Goes through Euler parameters, so it is accurate near pi as well as near 0. At angle 0
    the axis is undefined and (0, 0, 1) is returned; at exactly pi both e and -e are valid.
    """
    p0, p1, p2, p3 = entries(matrix_to_quaternion(R), 4)
    xp = ops(p0)
    sin_half = xp.sqrt(p1 * p1 + p2 * p2 + p3 * p3)
    angle = 2 * xp.arctan2(sin_half, p0)
    if is_symbolic(sin_half):
        axis = xp.where(sin_half > 0, vector([p1, p2, p3]) / sin_half, vector([0.0, 0.0, 1.0]))
    elif sin_half > 0:
        axis = vector([p1 / sin_half, p2 / sin_half, p3 / sin_half])
    else:
        axis = vector([0.0, 0.0, 1.0])
    return axis, angle


# --- Euler parameters (3.7) ---------------------------------------------------------------


def axis_angle_to_quaternion(axis: Any, angle: Any) -> Any:
    """Euler parameters (4,) p = (cos(angle/2), sin(angle/2) axis) of a unit axis (3,) (3.7.1)."""
    xp = ops(axis, angle)
    e1, e2, e3 = entries(axis, 3)
    c, s = xp.cos(angle / 2), xp.sin(angle / 2)
    return vector([c, s * e1, s * e2, s * e3])


def quaternion_multiply(p: Any, q: Any) -> Any:
    """Quaternion product p * q (4,), scalar first; R(p * q) = R(p) R(q) (3.7.3, 3.7.4)."""
    p0, p1, p2, p3 = entries(p, 4)
    q0, q1, q2, q3 = entries(q, 4)
    return vector(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ]
    )


def quaternion_conjugate(p: Any) -> Any:
    """Conjugate (p0, -p1, -p2, -p3) (4,): the inverse rotation of unit p (3.7.3)."""
    p0, p1, p2, p3 = entries(p, 4)
    return vector([p0, -p1, -p2, -p3])


def normalize_quaternion(p: Any) -> Any:
    """p / |p| (4,); raises ValueError for a zero NumPy quaternion."""
    p0, p1, p2, p3 = entries(p, 4)
    norm = ops(p0, p1, p2, p3).sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    if not is_symbolic(norm) and not norm > 0:
        raise ValueError(f"cannot normalize the quaternion {p!r}: its norm is {norm}")
    return vector([p0 / norm, p1 / norm, p2 / norm, p3 / norm])


def matrix_to_quaternion(R: Any) -> Any:
    """Euler parameters (4,) of the rotation matrix R (3x3) with p0 >= 0 (3.7.2).

    Shepperd's method: the 4x4 table T[i][j] = 4 p_i p_j is formed from R, and p is read
    from the row with the largest diagonal entry, p = T[k] / (2 sqrt(T[k][k])), so no small
    number is ever divided by. NumPy picks the row in Python, CasADi with if_else.
    """
    R = _as_matrix(R)
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    table = [
        [1 + trace, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]],
        [R[2, 1] - R[1, 2], 1 + 2 * R[0, 0] - trace, R[1, 0] + R[0, 1], R[0, 2] + R[2, 0]],
        [R[0, 2] - R[2, 0], R[1, 0] + R[0, 1], 1 + 2 * R[1, 1] - trace, R[2, 1] + R[1, 2]],
        [R[1, 0] - R[0, 1], R[0, 2] + R[2, 0], R[2, 1] + R[1, 2], 1 + 2 * R[2, 2] - trace],
    ]
    xp = ops(trace)
    if is_symbolic(trace):
        best, p = table[0][0], vector(table[0]) / (2 * xp.sqrt(table[0][0]))
        for k in (1, 2, 3):
            larger = table[k][k] > best
            p = xp.where(larger, vector(table[k]) / (2 * xp.sqrt(table[k][k])), p)
            best = xp.where(larger, table[k][k], best)
        return xp.where(p[0] < 0, -p, p)
    k = int(np.argmax([table[i][i] for i in range(4)]))
    p = np.array(table[k], dtype=float) / (2 * np.sqrt(table[k][k]))
    return -p if p[0] < 0 else p


# --- xyz Cardan angles (3.6) --------------------------------------------------------------


def cardan_xyz_to_matrix(angles: Any) -> Any:
    """R = Rx(a) Ry(b) Rz(c) (3x3) of xyz Cardan angles (a, b, c) in rad (3.6.1).

    Rotations about the co-rotating axes: x, then the new y, then the newest z.
    """
    a, b, c = entries(angles, 3)
    return compose(elementary_rotation(0, a), elementary_rotation(1, b), elementary_rotation(2, c))


def matrix_to_cardan_xyz(R: Any, tol: float = SINGULAR_TOL) -> Any:
    """xyz Cardan angles (3,) of R (3.6.2): a, c in (-pi, pi], b in [-pi/2, pi/2].

    Raises SingularityError (NumPy) if |cos b| <= tol.
    """
    R = _as_matrix(R)
    xp = ops(R)
    cos_b = xp.sqrt(R[0, 0] * R[0, 0] + R[0, 1] * R[0, 1])
    _check_singular(cos_b, tol, _CARDAN_SINGULAR)
    return vector(
        [xp.arctan2(-R[1, 2], R[2, 2]), xp.arctan2(R[0, 2], cos_b), xp.arctan2(-R[0, 1], R[0, 0])]
    )


def cardan_xyz_angular_velocity_matrix(angles: Any, frame: str = "body") -> Any:
    """3x3 G with omega = G(angles) angles' (3.6.3); omega (rad/s) in ``frame``. No singularity."""
    _check_frame(frame)
    a, b, c = entries(angles, 3)
    xp = ops(a, b, c)
    sa, ca, sb, cb, sc, cc = xp.sin(a), xp.cos(a), xp.sin(b), xp.cos(b), xp.sin(c), xp.cos(c)
    if frame == "body":
        return matrix([[cb * cc, sc, 0.0], [-cb * sc, cc, 0.0], [sb, 0.0, 1.0]])
    return matrix([[1.0, 0.0, sb], [0.0, ca, -sa * cb], [0.0, sa, ca * cb]])


def cardan_xyz_rate_matrix(angles: Any, frame: str = "body", tol: float = SINGULAR_TOL) -> Any:
    """3x3 K with angles' = K(angles) omega (3.6.3); omega (rad/s) in ``frame``.

    K = G^-1 contains 1/cos(b): raises SingularityError (NumPy) if |cos b| <= tol.
    """
    _check_frame(frame)
    a, b, c = entries(angles, 3)
    xp = ops(a, b, c)
    sa, ca, sb, cb, sc, cc = xp.sin(a), xp.cos(a), xp.sin(b), xp.cos(b), xp.sin(c), xp.cos(c)
    _check_singular(xp.abs(cb), tol, _CARDAN_SINGULAR)
    if frame == "body":
        return matrix([[cc / cb, -sc / cb, 0.0], [sc, cc, 0.0], [-sb * cc / cb, sb * sc / cb, 1.0]])
    return matrix([[1.0, sa * sb / cb, -ca * sb / cb], [0.0, ca, sa], [0.0, -sa / cb, ca / cb]])


# --- zxz Euler angles (3.6.4) -------------------------------------------------------------


def euler_zxz_to_matrix(angles: Any) -> Any:
    """R = Rz(a) Rx(b) Rz(c) (3x3) of zxz Euler angles (a, b, c) (rad), co-rotating axes."""
    a, b, c = entries(angles, 3)
    return compose(elementary_rotation(2, a), elementary_rotation(0, b), elementary_rotation(2, c))


def matrix_to_euler_zxz(R: Any, tol: float = SINGULAR_TOL) -> Any:
    """zxz Euler angles (3,) of R: a, c in (-pi, pi], b in [0, pi].

    Raises SingularityError (NumPy) if sin b <= tol.
    """
    R = _as_matrix(R)
    xp = ops(R)
    sin_b = xp.sqrt(R[2, 0] * R[2, 0] + R[2, 1] * R[2, 1])
    _check_singular(sin_b, tol, _EULER_SINGULAR)
    return vector(
        [xp.arctan2(R[0, 2], -R[1, 2]), xp.arctan2(sin_b, R[2, 2]), xp.arctan2(R[2, 0], R[2, 1])]
    )


def euler_zxz_angular_velocity_matrix(angles: Any, frame: str = "body") -> Any:
    """3x3 G with omega = G(angles) angles'; omega (rad/s) in ``frame``. No singularity."""
    _check_frame(frame)
    a, b, c = entries(angles, 3)
    xp = ops(a, b, c)
    sa, ca, sb, cb, sc, cc = xp.sin(a), xp.cos(a), xp.sin(b), xp.cos(b), xp.sin(c), xp.cos(c)
    if frame == "body":
        return matrix([[sb * sc, cc, 0.0], [sb * cc, -sc, 0.0], [cb, 0.0, 1.0]])
    return matrix([[0.0, ca, sa * sb], [0.0, sa, -ca * sb], [1.0, 0.0, cb]])


def euler_zxz_rate_matrix(angles: Any, frame: str = "body", tol: float = SINGULAR_TOL) -> Any:
    """3x3 K with angles' = K(angles) omega; omega (rad/s) in ``frame``.

    K = G^-1 contains 1/sin(b): raises SingularityError (NumPy) if |sin b| <= tol.
    """
    _check_frame(frame)
    a, b, c = entries(angles, 3)
    xp = ops(a, b, c)
    sa, ca, sb, cb, sc, cc = xp.sin(a), xp.cos(a), xp.sin(b), xp.cos(b), xp.sin(c), xp.cos(c)
    _check_singular(xp.abs(sb), tol, _EULER_SINGULAR)
    if frame == "body":
        return matrix(
            [[sc / sb, cc / sb, 0.0], [cc, -sc, 0.0], [-cb * sc / sb, -cb * cc / sb, 1.0]]
        )
    return matrix([[-sa * cb / sb, ca * cb / sb, 1.0], [ca, sa, 0.0], [sa / sb, -ca / sb, 0.0]])


# --- Rodrigues vector (3.8) ---------------------------------------------------------------


def rodrigues_to_matrix(rho: Any) -> Any:
    """R = I + 2 (S + S^2) / (1 + rho.rho), S = skew(rho), of rho = tan(angle/2) axis (3.8.1)."""
    r1, r2, r3 = entries(rho, 3)
    S = skew(rho)
    S2 = matmul(S, S)
    scale = 2 / (1 + r1 * r1 + r2 * r2 + r3 * r3)
    return matrix(
        [
            [(1.0 if i == j else 0.0) + scale * (S[i, j] + S2[i, j]) for j in range(3)]
            for i in range(3)
        ]
    )


def matrix_to_rodrigues(R: Any, tol: float = SINGULAR_TOL) -> Any:
    """Rodrigues vector rho = (p1, p2, p3) / p0 (3,) of R (3.8.1).

    Raises SingularityError (NumPy) if p0 = cos(angle/2) <= tol (rotation by pi).
    """
    p0, p1, p2, p3 = entries(matrix_to_quaternion(R), 4)
    _check_singular(p0, tol, _RODRIGUES_SINGULAR)
    return vector([p1 / p0, p2 / p0, p3 / p0])


def rodrigues_angular_velocity_matrix(rho: Any, frame: str = "body") -> Any:
    """3x3 G = 2 (I -+ skew(rho)) / (1 + rho.rho) with omega = G rho' (3.8.2).

    Minus sign for omega in the body frame, plus for the inertial frame.
    """
    _check_frame(frame)
    r1, r2, r3 = entries(rho, 3)
    S = skew(rho)
    sign = -1.0 if frame == "body" else 1.0
    scale = 2 / (1 + r1 * r1 + r2 * r2 + r3 * r3)
    return matrix(
        [[scale * ((1.0 if i == j else 0.0) + sign * S[i, j]) for j in range(3)] for i in range(3)]
    )


def rodrigues_rate_matrix(rho: Any, frame: str = "body") -> Any:
    """3x3 K = (I +- skew(rho) + rho rho^T) / 2 with rho' = K omega (3.8.2).

    Plus sign for omega in the body frame, minus for the inertial frame. K is finite for
    every finite rho; the singularity at a rotation by pi is rho itself becoming infinite.
    """
    _check_frame(frame)
    r = entries(rho, 3)
    S = skew(rho)
    sign = 1.0 if frame == "body" else -1.0
    return matrix(
        [
            [0.5 * ((1.0 if i == j else 0.0) + sign * S[i, j] + r[i] * r[j]) for j in range(3)]
            for i in range(3)
        ]
    )


# --- Euler parameters and angular velocity (3.7.5) ----------------------------------------


def quaternion_angular_velocity_matrix(p: Any, frame: str = "body") -> Any:
    """The 3x4 matrix 2 G(p) with omega = 2 G(p) p' (3.7.5); equals 4 H(p)^T for unit p.

    frame="body": omega in the body frame; "inertial": in the inertial frame.
    """
    _check_frame(frame)
    p0, p1, p2, p3 = entries(p, 4)
    if frame == "body":
        rows = [[-p1, p0, p3, -p2], [-p2, -p3, p0, p1], [-p3, p2, -p1, p0]]
    else:
        rows = [[-p1, p0, -p3, p2], [-p2, p3, p0, -p1], [-p3, -p2, p1, p0]]
    return matrix([[2 * x for x in row] for row in rows])


def quaternion_rates(p: Any, omega: Any, frame: str = "body") -> Any:
    """Euler parameter rates p' = H(p) omega (4,) (3.7.5). p: (4,), omega: (3,) in rad/s."""
    return matmul(quaternion_rate_matrix(p, frame), omega)


def quaternion_angular_velocity(p: Any, pdot: Any, frame: str = "body") -> Any:
    """Angular velocity omega = 2 G(p) p' (3,) in rad/s of unit p (4,) moving with p' (4,).

    The component of p' along p (a change of |p|) does not contribute.
    """
    return matmul(quaternion_angular_velocity_matrix(p, frame), pdot)


# --- the exponential map on SO(3) (Lie-group integrators) --------------------------------
# NumPy only: these serve integrators' hot loops, not symbolic graphs.

_SMALL_ANGLE = 1e-3  # rad; below it the Taylor series of T are exact to round-off


def quaternion_exp(theta: np.ndarray) -> np.ndarray:
    """Euler parameters (4,) of the rotation by the rotation vector ``theta`` (3,), rad:
    exp(theta) = (cos(|theta|/2), sin(|theta|/2) theta/|theta|), unit to round-off.

    With body-frame angular velocity omega, p(t + h) = p(t) * quaternion_exp(h omega) for
    constant omega (:func:`quaternion_rate_matrix` with frame="body")."""
    x, y, z = (float(c) for c in theta)
    angle = math.sqrt(x * x + y * y + z * z)
    # sin(angle/2)/angle, smooth through angle = 0 (series below 1e-3 rad: exact to round-off)
    half_sinc = 0.5 - angle * angle / 48.0 if angle < _SMALL_ANGLE else math.sin(angle / 2) / angle
    return np.array([math.cos(angle / 2), half_sinc * x, half_sinc * y, half_sinc * z])


def tangent_operator(theta: np.ndarray) -> np.ndarray:
    """T(theta) (3x3), the tangent operator of the exponential map on SO(3) (right
    trivialization, Bruls-Cardona-Arnold 2012): d/de exp(theta + e d) at e = 0 is
    exp(theta) * skew(T(theta) d), i.e.

        T = I - (1 - cos a)/a^2 skew(theta) + (a - sin a)/a^3 skew(theta)^2,  a = |theta|.
    """
    x, y, z = (float(c) for c in theta)
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < _SMALL_ANGLE:
        a2 = angle * angle
        first, second = 0.5 - a2 / 24.0, 1.0 / 6.0 - a2 / 120.0
    else:
        first = (1.0 - math.cos(angle)) / angle**2
        second = (angle - math.sin(angle)) / angle**3
    s = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) - first * s + second * (s @ s)
