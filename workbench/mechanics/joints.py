"""Joint kinematics, one dispatch over all joint types (book ch. 9).

A joint moves its child frame C relative to its parent frame P. For each type:

=============  ===  ===  ============================================================
type           nq   nv   coordinates q / velocities v
=============  ===  ===  ============================================================
revolute        1    1   angle about ``axis`` / its rate
prismatic       1    1   displacement along ``axis`` / its rate
cylindrical     2    2   (displacement, angle) along/about ``axis``
universal       2    2   angles about ``axis`` then about ``axis2`` (co-rotating)
spherical       4    3   Euler parameters of C in P / angular velocity of C in C
planar          3    3   (x, y, angle) in P's x-y plane, angle about P's z
free            7    6   (position of C in P, Euler parameters) / (its rate in P,
                         angular velocity of C in C)
fixed           0    0
=============  ===  ===  ============================================================

All functions work on NumPy values and CasADi symbols alike. ``implicit_constraints``
gives the book's elementary implicit constraints (9.4) between the world poses of P and
C, used for loop-closing joints and by absolute-coordinate formalisms.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from workbench.model import Joint
from workbench.model.elements import JOINT_DIMENSIONS
from workbench.numerics import rotations as rot
from workbench.numerics.backend import is_symbolic, matmul, ops, vector

DIMENSIONS: dict[str, tuple[int, int]] = JOINT_DIMENSIONS
# Number of implicit constraint rows of a loop-closing joint.
CONSTRAINT_ROWS: dict[str, dict[str, int]] = {
    "spatial": {t: 6 - nv for t, (_, nv) in DIMENSIONS.items()},
    "planar": {"revolute": 2, "prismatic": 2, "planar": 0, "fixed": 3},
}


def dimensions(joint: Joint) -> tuple[int, int]:
    """(nq, nv) of a joint; a driven joint has none left free, but keeps these sizes."""
    return DIMENSIONS[joint.type]


def unit(axis: Any) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return axis / np.linalg.norm(axis)


def neutral_coordinates(joint: Joint) -> np.ndarray:
    """The joint coordinates at which C coincides with P."""
    nq, _ = DIMENSIONS[joint.type]
    q = np.zeros(nq)
    if joint.type == "spherical":
        q[0] = 1.0
    elif joint.type == "free":
        q[3] = 1.0
    return q


def _zero3(*values: Any) -> Any:
    return ca.SX.zeros(3, 1) if is_symbolic(*values) else np.zeros(3)


def _col(v: Any) -> Any:
    """A 3-vector as a CasADi column when symbolic, else a flat NumPy array."""
    return v if is_symbolic(v) else np.asarray(v, dtype=float).reshape(3)


def relative_transform(joint: Joint, q: Any) -> tuple[Any, Any]:
    """(r, R): position and orientation of C relative to P, in P coordinates."""
    kind = joint.type
    a = unit(joint.axis)
    if kind == "revolute":
        return _zero3(q), rot.axis_angle_to_matrix(a, q[0])
    if kind == "prismatic":
        return a * q[0], np.eye(3)
    if kind == "cylindrical":
        return a * q[0], rot.axis_angle_to_matrix(a, q[1])
    if kind == "universal":
        r1 = rot.axis_angle_to_matrix(a, q[0])
        r2 = rot.axis_angle_to_matrix(unit(joint.axis2), q[1])
        return _zero3(q), matmul(r1, r2)
    if kind == "spherical":
        return _zero3(q), rot.quaternion_to_matrix(q)
    if kind == "planar":
        return vector([q[0], q[1], 0.0 * q[0]]), rot.axis_angle_to_matrix([0, 0, 1.0], q[2])
    if kind == "free":
        return vector([q[0], q[1], q[2]]), rot.quaternion_to_matrix(q[3:7])
    if kind == "fixed":
        return np.zeros(3), np.eye(3)
    raise ValueError(f"joint {joint.name!r}: unknown joint type {kind!r}")


def relative_twist(joint: Joint, q: Any, v: Any) -> tuple[Any, Any]:
    """(velocity of C's origin, angular velocity of C) relative to P, in P coordinates."""
    kind = joint.type
    a = unit(joint.axis)
    if kind == "revolute":
        return _zero3(q, v), a * v[0]
    if kind == "prismatic":
        return a * v[0], _zero3(q, v)
    if kind == "cylindrical":
        return a * v[0], a * v[1]
    if kind == "universal":
        r1 = rot.axis_angle_to_matrix(a, q[0])
        return _zero3(q, v), a * v[0] + matmul(r1, unit(joint.axis2)) * v[1]
    if kind == "spherical":
        return _zero3(q, v), matmul(rot.quaternion_to_matrix(q), vector([v[0], v[1], v[2]]))
    if kind == "planar":
        zero = 0.0 * v[0]
        return vector([v[0], v[1], zero]), vector([zero, zero, v[2]])
    if kind == "free":
        omega_c = vector([v[3], v[4], v[5]])
        return vector([v[0], v[1], v[2]]), matmul(rot.quaternion_to_matrix(q[3:7]), omega_c)
    if kind == "fixed":
        return np.zeros(3), np.zeros(3)
    raise ValueError(f"joint {joint.name!r}: unknown joint type {kind!r}")


def coordinate_rates(joint: Joint, q: Any, v: Any) -> Any:
    """q' = H(q) v for one joint."""
    kind = joint.type
    if kind == "spherical":
        return matmul(rot.quaternion_rate_matrix(q, "body"), vector([v[0], v[1], v[2]]))
    if kind == "free":
        pdot = matmul(rot.quaternion_rate_matrix(q[3:7], "body"), vector([v[3], v[4], v[5]]))
        return vector([v[0], v[1], v[2]] + [pdot[i] for i in range(4)])
    return v


def _perpendicular_pair(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``a`` to an orthonormal basis."""
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    b1 = np.cross(a, helper)
    b1 /= np.linalg.norm(b1)
    return b1, np.cross(a, b1)


def _rows(items: list[Any]) -> Any:
    return vector(items) if items else np.zeros(0)


def _inner(a: np.ndarray, m: Any, b: np.ndarray) -> Any:
    """a^T m b for constant vectors a, b and a (symbolic) matrix m."""
    total = 0
    for i in range(3):
        for j in range(3):
            if a[i] != 0.0 and b[j] != 0.0:
                total = total + a[i] * m[i, j] * b[j]
    return total


def implicit_constraints(
    joint: Joint, planar: bool, r_p: Any, rot_p: Any, r_c: Any, rot_c: Any
) -> Any:
    """Residual vector of the joint's implicit constraints (book 9.4) between frames P and C.

    ``r_p``, ``rot_p`` and ``r_c``, ``rot_c``: world position (3,) and rotation (3, 3) of P
    and C. Zero exactly when C is reachable from P by the joint. The number of rows is
    ``CONSTRAINT_ROWS[kind][type]``. A driven joint is treated as fixed relative to the
    driven pose (the caller passes P already moved by the drive).
    """
    kind = "fixed" if joint.drive is not None else joint.type
    d_world = r_c - r_p
    d = matmul(rot_p.T, d_world)  # C's origin in P coordinates
    rel = matmul(rot_p.T, rot_c)  # C's orientation in P coordinates
    a = unit(joint.axis)
    ex, ey, ez = np.eye(3)
    if planar:
        if kind == "revolute":
            return _rows([d[0], d[1]])
        if kind == "prismatic":
            return _rows([_perp(a, d), rel[1, 0]])
        if kind == "fixed":
            return _rows([d[0], d[1], rel[1, 0]])
        if kind == "planar":
            return _rows([])
        raise ValueError(f"joint {joint.name!r}: a {kind} joint does not fit a planar model")
    b1, b2 = _perpendicular_pair(a)
    align = [_inner(b1, rel, a), _inner(b2, rel, a)]  # C's axis stays along P's axis
    no_twist = [_inner(ex, rel, ey), _inner(ey, rel, ez), _inner(ez, rel, ex)]
    on_axis = [_lin(b1, d), _lin(b2, d)]
    point = [d[0], d[1], d[2]]
    if kind == "revolute":
        rows = point + align
    elif kind == "prismatic":
        rows = on_axis + no_twist
    elif kind == "cylindrical":
        rows = on_axis + align
    elif kind == "universal":
        a2 = unit(joint.axis2)
        rows = point + [_inner(a, rel, a2) - float(a @ a2)]
    elif kind == "spherical":
        rows = point
    elif kind == "planar":
        rows = [d[2], _inner(ex, rel, ez), _inner(ey, rel, ez)]
    elif kind == "free":
        rows = []
    elif kind == "fixed":
        rows = point + no_twist
    else:
        raise ValueError(f"joint {joint.name!r}: unknown joint type {kind!r}")
    return _rows(rows)


def constraint_units(joint: Joint, planar: bool) -> set[str]:
    """The units of the rows of :func:`implicit_constraints`: 'm' for a distance, 'rad'
    for an entry of the relative rotation (the sine of a small angle); empty for none."""
    kind = "fixed" if joint.drive is not None else joint.type
    if kind == "free" or (planar and kind == "planar"):
        return set()
    return {"m"} if kind == "spherical" or (planar and kind == "revolute") else {"m", "rad"}


def _lin(b: np.ndarray, d: Any) -> Any:
    return b[0] * d[0] + b[1] * d[1] + b[2] * d[2]


def _in_plane_normal(a: np.ndarray) -> np.ndarray:
    return np.array([-a[1], a[0], 0.0]) / np.hypot(a[0], a[1])


def _perp(a: np.ndarray, d: Any) -> Any:
    n = _in_plane_normal(a)
    return n[0] * d[0] + n[1] * d[1]


def relative_coordinates(joint: Joint, rel_r: Any, rel_rot: Any) -> Any:
    """Joint coordinates from C's pose relative to P (inverse of relative_transform).

    For revolute, prismatic, cylindrical, universal and planar joints (angles in
    (-pi, pi]), spherical and free (Euler parameters with p0 >= 0, which may be the
    negative of the tree's); used for joint forces and springs in absolute-coordinate
    formalisms and for energies.
    """
    xp = ops(rel_r, rel_rot)
    a = unit(joint.axis)
    if joint.type in ("revolute", "cylindrical"):
        b1, b2 = _perpendicular_pair(a)
        # angle of b1 rotated about a: atan2(b2 . R b1, b1 . R b1)
        angle = xp.arctan2(_inner(b2, rel_rot, b1), _inner(b1, rel_rot, b1))
        if joint.type == "revolute":
            return vector([angle])
        return vector([_lin(a, rel_r), angle])
    if joint.type == "prismatic":
        return vector([_lin(a, rel_r)])
    if joint.type == "universal":
        return vector(_universal_angles(a, unit(joint.axis2), rel_rot, xp))
    if joint.type == "planar":
        return vector([rel_r[0], rel_r[1], xp.arctan2(rel_rot[1, 0], rel_rot[0, 0])])
    if joint.type == "spherical":  # either sign of the Euler parameters: springs use both
        return rot.matrix_to_quaternion(rel_rot)
    if joint.type == "free":
        p = rot.matrix_to_quaternion(rel_rot)
        return vector([rel_r[0], rel_r[1], rel_r[2], p[0], p[1], p[2], p[3]])
    if joint.type == "fixed":
        return np.zeros(0)
    raise ValueError(
        f"joint {joint.name!r}: coordinates of a {joint.type} joint cannot be recovered from "
        "poses here; joint forces and springs are supported on revolute, prismatic, "
        "cylindrical, universal and planar joints"
    )


def _universal_angles(a: np.ndarray, b: np.ndarray, rel_rot: Any, xp: Any) -> list[Any]:
    """The two angles of a universal joint, R = R_a(q0) R_b(q1), from R (a, b unit, not
    parallel; perpendicular or not).

    R b = R_a(q0) b: q0 is the angle of b's part normal to a turned about a. R^T a =
    R_b(-q1) a: q1 is the angle of a's part normal to b turned back about b.
    """
    normal = np.cross(a, b)
    b_normal_to_a = b - (a @ b) * a
    a_normal_to_b = a - (a @ b) * b
    first = xp.arctan2(_inner(normal, rel_rot, b), _inner(b_normal_to_a, rel_rot, b))
    second = xp.arctan2(_inner(a, rel_rot, normal), _inner(a, rel_rot, a_normal_to_b))
    return [first, second]


def drive_values(joint: Joint, t: Any) -> tuple[Any, Any, Any]:
    """(q, v, v') prescribed by a driven joint at time t, as vectors."""
    drive = joint.drive
    assert drive is not None and drive.velocity is not None and drive.acceleration is not None
    return (_as_vector(drive.position(t)), _as_vector(drive.velocity(t)),
            _as_vector(drive.acceleration(t)))


def _as_vector(value: Any) -> Any:
    if is_symbolic(value):
        return ca.vec(value)
    if isinstance(value, ca.DM):
        return np.asarray(value).reshape(-1)
    if np.ndim(value) == 0:
        return vector([value])
    if isinstance(value, list | tuple):
        return vector(list(value))
    return np.asarray(value, dtype=float).reshape(-1)
