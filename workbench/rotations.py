"""Rotation parameterizations (book ch. 3), for NumPy arrays and CasADi symbols alike.

Conventions: rotation matrices map body-frame coordinates to inertial ones (active
rotation, r = R r'); Euler parameters (unit quaternions) are scalar-first
p = (p0, p1, p2, p3) as in the book; SciPy and Rerun use scalar-last and are converted
only at those boundaries. Angular velocities are given in the body frame ("body") or the
inertial frame ("inertial") as each function states.
"""

from __future__ import annotations

from typing import Any

from workbench.backend import entries, matrix, ops


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
    """Rotation matrix of unit Euler parameters p = (p0, p1, p2, p3), scalar first (3.7.1)."""
    p0, p1, p2, p3 = entries(p, 4)
    return matrix(
        [
            [2 * (p0 * p0 + p1 * p1) - 1, 2 * (p1 * p2 - p0 * p3), 2 * (p1 * p3 + p0 * p2)],
            [2 * (p1 * p2 + p0 * p3), 2 * (p0 * p0 + p2 * p2) - 1, 2 * (p2 * p3 - p0 * p1)],
            [2 * (p1 * p3 - p0 * p2), 2 * (p2 * p3 + p0 * p1), 2 * (p0 * p0 + p3 * p3) - 1],
        ]
    )


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
