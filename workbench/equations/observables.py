"""Formalism-neutral observables of a state: body poses and twists, energies, residuals.

Metrics, the Rerun recording and the conformance suite measure every formalism on these,
so drift and error mean the same thing whatever coordinates a formalism chose: every
joint's implicit constraint is evaluated on the body poses, not on the formalism's own
constraint rows.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from workbench.equations.evaluate import FastFunction, dense_function, evaluate_along
from workbench.mechanics import forces as fm
from workbench.mechanics import joints as jk
from workbench.mechanics.kinematics import BodyState, contact_rows
from workbench.model import GROUND, Model


@dataclass
class Observables:
    """Formalism-neutral quantities of a state (t, q, v).

    frames(t, q) -> (3, n_bodies) positions and (3, 3 n_bodies) rotations;
    twists(t, q, v) -> (6, n_bodies) [velocity of frame origin; angular velocity];
    energy(t, q, v) -> (2,) [T, V];
    residuals(t, q, v) -> position, velocity and nonholonomic residual vectors.
    :meth:`along` gives them all at many states in one call each.
    """

    frames: FastFunction
    twists: FastFunction
    energy: FastFunction
    residuals: FastFunction
    body_names: list[str]
    _mapped: dict = field(default_factory=dict, repr=False)  # Function.map(n)s: evaluate_along
    _last: tuple = field(default=(), repr=False, compare=False)  # (times, q, poses) of along()

    def poses(self, t: float, q: np.ndarray) -> np.ndarray:
        """(n_bodies, 7): position and unit quaternion (scalar first) of every body."""
        positions, rotations = self.frames(t, q)
        return _poses(positions[None], rotations[None], len(self.body_names))[0]

    def poses_along(self, times: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(n, n_bodies, 7) poses at n configurations in one mapped call (see :meth:`along`)."""
        times = np.asarray(times, dtype=float).reshape(-1)
        if times.size == 0:
            return np.zeros((0, len(self.body_names), 7))
        if self._last and _same(self._last[:2], (times, q)):  # the metrics' states, logged
            return self._last[2].copy()
        positions, rotations = self._map("frames", times.size, times[None], np.atleast_2d(q).T)
        return _poses(positions, rotations, len(self.body_names))

    def poses_of_rows(self, times: np.ndarray, q: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(len(rows), n_bodies, 7) poses at the rows ``rows`` of the n configurations
        ``times``, ``q``: taken from the last :meth:`along` call when it measured these n
        states (a recording logs some samples of the run just measured), else computed at
        those rows only."""
        times = np.asarray(times, dtype=float).reshape(-1)
        if self._last and _same(self._last[:2], (times, q)):
            return self._last[2][rows]
        return self.poses_along(times[rows], np.atleast_2d(q)[rows])

    def along(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> SampledObservables:
        """Every quantity at n states: ``times`` (n,), ``q`` (n, nq), ``v`` (n, nv).

        One evaluation of each function mapped over the n states (``Function.map``):
        metrics of a run with 500 output times called the functions 2,000 times one state
        at a time, which cost more than many integrations.
        """
        times = np.asarray(times, dtype=float).reshape(-1)
        n = times.size
        q, v = np.atleast_2d(q), np.atleast_2d(v)
        if n == 0:
            return SampledObservables.empty(len(self.body_names))
        row = times.reshape(1, n)
        positions, rotations = self._map("frames", n, row, q.T)
        (twists,) = self._map("twists", n, row, q.T, v.T)
        (energy,) = self._map("energy", n, row, q.T, v.T)
        residuals = self._map("residuals", n, row, q.T, v.T)
        n_bodies = len(self.body_names)
        poses = _poses(positions, rotations, n_bodies)
        # kept for poses_along at the same states (a recording of the run just measured):
        # the same mapped call would give the same numbers
        self._last = (times.copy(), np.array(q, dtype=float), poses.copy())
        return SampledObservables(
            poses=poses,
            rotations=rotations.reshape(n, 3, n_bodies, 3).transpose(0, 2, 1, 3),
            twists=twists.reshape(n, 6, -1).transpose(0, 2, 1),  # as reshape(6, -1).T
            energy=energy.reshape(n, -1)[:, :2],
            residuals=[r.reshape(n, -1) for r in residuals],
        )

    def _map(self, name: str, n: int, *args: np.ndarray) -> list[np.ndarray]:
        """Outputs of observable ``name`` at n states, each stacked as (n, rows, cols)."""
        return evaluate_along(getattr(self, name).function, n, list(args), self._mapped)


@dataclass
class SampledObservables:
    """Observables at n states: ``poses`` (n, n_bodies, 7) [position, Euler parameters];
    ``twists`` (n, n_bodies, 6) [velocity of the frame origin, angular velocity];
    ``energy`` (n, 2) [T, V]; ``residuals``: position, velocity and nonholonomic
    residuals, each (n, rows); ``rotations`` (n, n_bodies, 3, 3): the body rotation
    matrices as the formalism gives them (the poses' quaternions are of the nearest
    rotation: an R that is not orthonormal shows only here)."""

    poses: np.ndarray
    twists: np.ndarray
    energy: np.ndarray
    residuals: list[np.ndarray]
    rotations: np.ndarray

    @classmethod
    def empty(cls, n_bodies: int) -> SampledObservables:
        return cls(
            np.zeros((0, n_bodies, 7)), np.zeros((0, n_bodies, 6)), np.zeros((0, 2)), [],
            np.zeros((0, n_bodies, 3, 3)),
        )  # fmt: skip


def _same(arrays: tuple[np.ndarray, ...], others: tuple[Any, ...]) -> bool:
    """Whether each array equals its other bit for bit (shape, and values as float64)."""
    return all(
        np.shape(a) == np.shape(b) and _bits(a) == _bits(b)
        for a, b in zip(arrays, others, strict=True)
    )


def _bits(array: Any) -> bytes:
    return np.ascontiguousarray(array, dtype=float).tobytes()


def _poses(positions: np.ndarray, rotations: np.ndarray, n_bodies: int) -> np.ndarray:
    """(m, n_bodies, 7) poses from m stacked frames outputs: positions (m, 3, n_bodies) and
    rotations (m, 3, 3 n_bodies); quaternions scalar first with p0 >= 0."""
    m = positions.shape[0]
    matrices = rotations.reshape(m, 3, n_bodies, 3).transpose(0, 2, 1, 3)  # (m, nb, 3, 3)
    quats = nearest_quaternions(matrices.reshape(-1, 3, 3))[:, [3, 0, 1, 2]]
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)
    origins = positions.reshape(m, 3, n_bodies).transpose(0, 2, 1)
    return np.concatenate([origins, quats.reshape(m, n_bodies, 4)], axis=2)


_ASSUME_VALID = "assume_valid" in inspect.signature(Rotation.from_matrix).parameters


def nearest_quaternions(matrices: np.ndarray) -> np.ndarray:
    """(m, 4) quaternions (x, y, z, w) of m 3x3 matrices: ``Rotation.from_matrix(matrices)
    .as_quat()``, the same bits, in fewer NumPy passes. SciPy (1.17) checks every matrix's
    determinant (``np.linalg.det``) and, with ``np.isclose``, whether M M^T = I (atol 1e-12,
    rtol 1e-5), replaces the matrices that are not orthogonal by their nearest rotation
    (U V^T of their SVD), then converts; here the determinant is written out (a sign is
    all it decides: any not positive goes to SciPy, which raises), the test is the same
    comparison on the same M M^T, and the conversion SciPy's own (``assume_valid``). The
    checks were 0.2 of 0.24 ms for a tiny run's 201 poses (docs/performance.md)."""
    m = np.asarray(matrices, dtype=float)
    if not _ASSUME_VALID:  # a SciPy without that option: its own call
        return Rotation.from_matrix(m).as_quat()
    det = (
        m[:, 0, 0] * (m[:, 1, 1] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 1])
        - m[:, 0, 1] * (m[:, 1, 0] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 0])
        + m[:, 0, 2] * (m[:, 1, 0] * m[:, 2, 1] - m[:, 1, 1] * m[:, 2, 0])
    )
    if not (det > 0).all():  # a left-handed or degenerate frame (or NaN): SciPy says so
        return Rotation.from_matrix(m).as_quat()
    eye = np.eye(3)
    orthogonal = (np.abs(m @ m.transpose(0, 2, 1) - eye) <= 1e-12 + 1e-5 * eye).all(axis=(1, 2))
    if not orthogonal.all():
        m = m.copy()
        u, _, vt = np.linalg.svd(m[~orthogonal], full_matrices=False)
        m[~orthogonal] = u @ vt
    return Rotation.from_matrix(m, assume_valid=True).as_quat()


def build_observables(
    model: Model,
    t: Any,
    q: Any,
    v: Any,
    qdot: Any,
    bodies: dict[str, BodyState],
    joint_coordinates: dict[str, Any] | None = None,
) -> Observables:
    """Poses, twists, energies and constraint residuals from symbolic body states."""
    names = list(model.bodies)
    zero_v = ca.DM.zeros(v.numel())  # poses depend on (t, q) only; see build_equations
    positions = ca.substitute(ca.horzcat(*[bodies[b].position for b in names]), v, zero_v)
    rotations = ca.substitute(ca.horzcat(*[bodies[b].rotation for b in names]), v, zero_v)
    twists = ca.horzcat(
        *[ca.vertcat(bodies[b].velocity, bodies[b].angular_velocity) for b in names]
    )
    spring_joints = {f.joint for f in model.forces if isinstance(f, fm.JointSpringDamper)}
    coordinates = dict(joint_coordinates or {})
    for joint in spring_joints - set(coordinates):
        coordinates[joint] = fm.relative_joint_coordinates(model, bodies, joint)
    energy = ca.vertcat(
        fm.kinetic_energy(model, bodies), fm.potential_energy(model, bodies, coordinates)
    )
    position_residual = ca.substitute(joint_residuals(model, t, bodies), v, zero_v)
    velocity_residual = ca.mtimes(ca.jacobian(position_residual, q), qdot) + ca.jacobian(
        position_residual, t
    )
    nonholonomic = [
        contact_rows(model.kind == "planar", bodies[c.body], c)[1] for c in model.nonholonomic
    ]
    nh_residual = ca.vertcat(*nonholonomic) if nonholonomic else ca.DM.zeros(0, 1)
    return Observables(
        frames=dense_function("frames", [t, q], [positions, rotations]),
        twists=dense_function("twists", [t, q, v], [twists]),
        energy=dense_function("energy", [t, q, v], [energy]),
        residuals=dense_function(
            "residuals", [t, q, v], [position_residual, velocity_residual, nh_residual]
        ),
        body_names=names,
    )


def joint_residuals(model: Model, t: Any, bodies: dict[str, BodyState]) -> Any:
    """Implicit constraints of every joint (tree and cut) and contact height, on body poses."""
    rows = []
    planar = model.kind == "planar"
    ground = BodyState(ca.DM.zeros(3), ca.DM.eye(3), ca.DM.zeros(3), ca.DM.zeros(3))
    for joint in model.joints.values():
        parent = ground if joint.parent == GROUND else bodies[joint.parent]
        r_p, rot_p = parent.frame(joint.parent_frame)
        if joint.drive is not None:
            q_d, _, _ = jk.drive_values(joint, t)
            r_rel, rot_rel = jk.relative_transform(joint, q_d)
            r_p, rot_p = r_p + ca.mtimes(rot_p, r_rel), ca.mtimes(rot_p, rot_rel)
        child = ground if joint.child == GROUND else bodies[joint.child]
        r_c, rot_c = child.frame(joint.child_frame)
        residual = jk.implicit_constraints(joint, planar, r_p, rot_p, r_c, rot_c)
        if np.size(residual) if not isinstance(residual, ca.SX | ca.MX) else residual.numel():
            rows.append(residual)
    for constraint in model.nonholonomic:
        height, _ = contact_rows(planar, bodies[constraint.body], constraint)
        if height is not None:
            rows.append(height)
    return ca.vertcat(*rows) if rows else ca.DM.zeros(0, 1)
