"""Spatial (6D) vector algebra in Featherstone's notation, for NumPy and CasADi alike.

A motion vector (twist, acceleration) is m = [omega; v] (6): angular part first, then the
linear velocity of the point at the frame's origin. A force vector (wrench) is
f = [n; f] (6): the moment about the frame's origin first, then the force. Both are
expressed in the coordinates of one frame.

A Pluecker transform X from frame P (the parent) to frame C (the child) is given by the
rotation E (3, 3) from P to C coordinates (x_C = E x_P) and the position r (3) of C's
origin in P coordinates:

    X = [E, 0; -E r~, E]    (motion vectors:  m_C = X m_P)
    X^T                     (force vectors, back from C to P:  f_P = X^T f_C)

with r~ the cross-product matrix (r~ x = r x x). A spatial inertia I (6, 6) about a
frame's origin maps a motion to a momentum; moved from C to P it becomes X^T I X.

Every function works on NumPy arrays (vectors (6,), matrices (6, 6) or (6, k)) and on
CasADi SX/MX/DM expressions (vectors 6 x 1); a CasADi argument makes the result CasADi.
The block forms (:func:`transform_motion`, :func:`transform_force_back`,
:func:`congruence`, :func:`articulated_update`) compute what the dense 6 x 6 products
compute with fewer symbolic instructions: they are what the recursive algorithms call, so
an algorithm reads in the notation X m, X^T f, X^T I X.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from workbench.numerics import rotations

_CASADI_TYPES = (ca.SX, ca.MX, ca.DM)


def _is_casadi(*values: Any) -> bool:
    # DM counts as CasADi here: np.cross and np.concatenate do not take it
    return any(isinstance(v, _CASADI_TYPES) for v in values)


def _stack(top: Any, bottom: Any) -> Any:
    """[top; bottom]: two 3-vectors (or 3 x k blocks) one above the other."""
    if _is_casadi(top, bottom):
        return ca.vertcat(top, bottom)
    return np.concatenate([np.asarray(top), np.asarray(bottom)])


def _blocks(rows: list[list[Any]]) -> Any:
    """A matrix from 3 x 3 blocks."""
    if any(_is_casadi(*row) for row in rows):
        return ca.vertcat(*[ca.horzcat(*row) for row in rows])
    return np.block([[np.asarray(b, dtype=float) for b in row] for row in rows])


def _zeros(n: int, m: int, *like: Any) -> Any:
    """An n x m matrix of zeros of the kind of ``like``: SX, MX or NumPy."""
    if any(isinstance(v, ca.MX) for v in like):
        return ca.MX.zeros(n, m)
    return ca.SX.zeros(n, m) if _is_casadi(*like) else np.zeros((n, m))


def _cross(a: Any, b: Any) -> Any:
    return ca.cross(a, b) if _is_casadi(a, b) else np.cross(a, b)


def _dot(a: Any, b: Any) -> Any:
    return ca.dot(a, b) if _is_casadi(a, b) else np.dot(a, b)


def _mtimes(a: Any, b: Any) -> Any:
    return ca.mtimes(a, b) if _is_casadi(a, b) else np.asarray(a) @ np.asarray(b)


def _skew(r: Any) -> Any:
    """r~ (3, 3), the cross-product matrix: r~ x = r x x."""
    return ca.skew(r) if _is_casadi(r) else rotations.skew(r)


def motion_cross(v: Any, m: Any) -> Any:
    """v x m (6): the spatial cross product of two motion vectors v, m (6).

    With v = [w; v0]: v x m = [w x m_w; w x m_v + v0 x m_w] (the rate of m carried
    by a frame moving with v)."""
    w, v0 = v[:3], v[3:]
    return _stack(_cross(w, m[:3]), _cross(w, m[3:]) + _cross(v0, m[:3]))


def force_cross(v: Any, f: Any) -> Any:
    """v x* f (6): the spatial cross product of a motion vector v (6) with a force vector
    f (6), the dual of :func:`motion_cross`: v x* = -(v x)^T.

    With v = [w; v0], f = [n; f]: v x* f = [w x n + v0 x f; w x f]."""
    w, v0 = v[:3], v[3:]
    return _stack(_cross(w, f[:3]) + _cross(v0, f[3:]), _cross(w, f[3:]))


def transform_motion(E: Any, r: Any, m: Any) -> Any:
    """X m (6): the motion vector m (6) from parent to child coordinates.

    E (3, 3): rotation from parent to child coordinates; r (3): the child's origin in
    parent coordinates. X m = [E m_w; E (m_v - r x m_w)]."""
    return _stack(_mtimes(E, m[:3]), _mtimes(E, m[3:] - _cross(r, m[:3])))


def transform_force_back(E: Any, r: Any, f: Any) -> Any:
    """X^T f: force vectors from child back to parent coordinates (E, r as in
    :func:`transform_motion`).

    f (6) or (6, k), one force a column. For one force the block form
    X^T f = [E^T f_n + r x E^T f_f; E^T f_f]; for k > 1 columns (the composite-rigid-body
    algorithm's I^C S) the dense product plucker(E, r)^T f, whose instructions the
    columns share.
    """
    columns = f.shape[1] if len(f.shape) > 1 else 1
    if columns != 1:
        return _mtimes(plucker(E, r).T, f)
    force = _mtimes(E.T, f[3:])
    return _stack(_mtimes(E.T, f[:3]) + _cross(r, force), force)


def plucker(E: Any, r: Any) -> Any:
    """X (6, 6) = [E 0; -E r~ E], the motion transform from parent to child coordinates
    (E, r as in :func:`transform_motion`)."""
    lower = -_mtimes(E, _skew(r))
    return _blocks([[E, _zeros(3, 3, E, r)], [lower, E]])


def symmetric(entry: Callable[[int, int], Any], n: int) -> Any:
    """The symmetric n x n matrix A with A[i, j] = A[j, i] = ``entry(i, j)``, computed for
    i <= j only (the lower triangle shares the same expressions: no extra instructions).

    CasADi if the entries are, else NumPy."""
    first = entry(0, 0)
    if _is_casadi(first):
        out = (ca.MX if isinstance(first, ca.MX) else ca.SX).zeros(n, n)
    else:
        out = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            out[i, j] = first if i == j == 0 else entry(i, j)
            if j != i:
                out[j, i] = out[i, j]
    return out


def symmetric_sum(A: Any, B: Any) -> Any:
    """A + B for symmetric n x n A and B, its upper triangle summed once and mirrored
    (an elementwise sum would add both triangles: 36 sums for 6 x 6, not 21)."""
    return symmetric(lambda i, j: A[i, j] + B[i, j], A.shape[0])


def rotate_symmetric(E: Any, A: Any) -> Any:
    """E^T A E (3, 3) for a symmetric A (3, 3) and a rotation E (3, 3): the six unique
    entries only."""
    T = _mtimes(A, E)
    return symmetric(lambda i, j: _dot(E[:, i], T[:, j]), 3)


def congruence(E: Any, r: Any, inertia: Any) -> Any:
    """X^T I X (6, 6) for a symmetric 6 x 6 (articulated) inertia I in child coordinates,
    X = plucker(E, r): I moved from child to parent coordinates.

    With I = [A B; B^T C] and the rotated blocks A' = E^T A E, B' = E^T B E,
    C' = E^T C E, X = diag(E, E) [1 0; -r~ 1] gives
    X^T I X = [A' + K + K^T - r~ C' r~, P; P^T, C'] with P = B' + r~ C', K = r~ B'^T.
    Only the unique entries of the symmetric blocks are formed: about 60 % of the
    instructions of the dense product (255 against 410 for a revolute link of a chain).
    """
    A, B, C = inertia[:3, :3], inertia[:3, 3:], inertia[3:, 3:]
    A1, C1 = rotate_symmetric(E, A), rotate_symmetric(E, C)
    B1 = _mtimes(_mtimes(E.T, B), E)
    r_tilde = _skew(r)
    Q = _mtimes(r_tilde, C1)
    P = B1 + Q
    K = _mtimes(r_tilde, B1.T)
    QR = _mtimes(Q, r_tilde)
    top = symmetric(lambda i, j: A1[i, j] + K[i, j] + K[j, i] - QR[i, j], 3)
    return _blocks([[top, P], [P.T, C1]])


def rotate_z_inertia(cos: Any, sin: Any, inertia: Any) -> Any:
    """R I R^T (6, 6) blockwise, R = R_z(angle) given by its ``cos`` and ``sin``: a
    symmetric 6 x 6 (articulated) inertia I turned about z, as the congruence of a
    revolute joint's rotation (X = diag(R^T, R^T)). Each 2 x 2 block B of the xy plane
    keeps its trace and its antisymmetric part, so it needs only
    e = s^2 (B_yy - B_xx) - c s (B_xy + B_yx) and g = c s (B_yy - B_xx) + s^2 (B_xy + B_yx)
    (B'_xx = B_xx + e, B'_yy = B_yy - e, B'_xy = B_xy - g, B'_yx = B_yx - g); the z rows
    and columns turn as vectors. About half the products of the general congruence, and
    zero entries (an articulated inertia's rows of its joint axis) stay zero."""
    ss, cs = sin * sin, cos * sin

    def plane(xx: Any, xy: Any, yx: Any, yy: Any) -> tuple[Any, Any, Any, Any]:
        delta, sigma = yy - xx, xy + yx
        e = ss * delta - cs * sigma
        g = cs * delta + ss * sigma
        return xx + e, xy - g, yx - g, yy - e

    def turn(x: Any, y: Any) -> tuple[Any, Any]:  # R [x; y] in the plane
        return cos * x - sin * y, sin * x + cos * y

    out = ca.SX(6, 6)
    for i0, j0 in ((0, 0), (0, 3), (3, 3)):
        block = [[inertia[i0 + i, j0 + j] for j in range(3)] for i in range(3)]
        (xx, xy, yx, yy), z = plane(*block[0][:2], *block[1][:2]), 2
        rows = [[xx, xy, None], [yx, yy, None], [None, None, block[z][z]]]
        rows[0][z], rows[1][z] = turn(block[0][z], block[1][z])
        if i0 == j0:  # a symmetric block: its lower triangle is its upper
            rows[1][0], (rows[z][0], rows[z][1]) = rows[0][1], (rows[0][z], rows[1][z])
        else:
            rows[z][0], rows[z][1] = turn(block[z][0], block[z][1])
        for i in range(3):
            for j in range(3):
                out[i0 + i, j0 + j] = rows[i][j]
                if i0 != j0:
                    out[j0 + j, i0 + i] = rows[i][j]
    return out


def articulated_update(I_A: Any, U: Any, D_inv_U: Any, zero: tuple[int, ...] = ()) -> Any:
    """I^a = I^A - U D^-1 U^T (6, 6): an articulated inertia I^A (6, 6) seen through a
    joint with motion subspace S (6, n): U = I^A S (6, n), D = S^T U (n, n), and
    ``D_inv_U`` = D^-1 U^T (n, 6). Symmetric: 21 entries formed, not 36.

    I^a S = 0; ``zero``: rows k with S's columns unit vectors e_k (a joint in its own
    frame), whose rows and columns of I^a are exactly 0 and are not formed."""

    def entry(i: int, j: int) -> Any:
        if i in zero or j in zero:
            return 0 * I_A[i, j]
        return I_A[i, j] - _dot(U[i, :].T, D_inv_U[:, j])

    return symmetric(entry, 6)


def rigid_bias_force(mass: float, com: Any, com_inertia: Any, V: Any) -> Any:
    """V x* I V (6) for a rigid body's spatial inertia I = :func:`spatial_inertia` of
    ``mass`` m, centre of mass c (3) and inertia tensor I_c (3, 3) about it (numbers), and
    a motion V = [w; v] (6), through the centre of mass: with the momentum
    h = m (v + w x c) (m times the centre of mass's velocity), f = w x h and
    V x* I V = [w x I_c w + c x f; f] (the moment of the dense form
    w x (I_o w + m c x v) + v x h reduced by Jacobi's identity, since v_c x h = 0).
    36 products and 24 sums for a general body, against 42 and 30 through I V."""
    w, v = V[:3], V[3:]
    first_moment = _constant(mass * np.asarray(com, dtype=float), V)
    com, com_inertia = _constant(com, V), _constant(com_inertia, V)
    momentum = mass * v + _cross(w, first_moment)
    force = _cross(w, momentum)
    return _stack(_cross(w, _mtimes(com_inertia, w)) + _cross(com, force), force)


def _constant(value: Any, like: Any) -> Any:
    """Numbers as a constant of ``like``'s kind (SX: structural zeros folded)."""
    if isinstance(like, ca.SX):
        return ca.SX(ca.DM(np.asarray(value, dtype=float)))
    return value if _is_casadi(like) else np.asarray(value, dtype=float)


def spatial_inertia(mass: Any, com: Any, inertia: Any) -> Any:
    """I (6, 6) = [I_c + m c~ c~^T, m c~; m c~^T, m 1]: the spatial inertia of a body of
    ``mass`` m (kg) about its frame's origin, from its centre of mass c (3, m) and its
    inertia tensor I_c (3, 3, kg m^2) about the centre of mass, in the body frame."""
    if _is_casadi(mass, com, inertia):
        c_tilde = ca.skew(com)
        upper = ca.horzcat(inertia + ca.mtimes(mass * c_tilde, c_tilde.T), mass * c_tilde)
        return ca.vertcat(upper, ca.horzcat(mass * c_tilde.T, mass * ca.DM.eye(3)))
    c_tilde = _skew(com)
    return np.block(
        [
            [np.asarray(inertia, float) + mass * c_tilde @ c_tilde.T, mass * c_tilde],
            [mass * c_tilde.T, mass * np.eye(3)],
        ]
    )
