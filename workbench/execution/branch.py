"""Did a run leave the assembly branch it started on? Followed by continuation, not sampling.

Through a singular configuration of a closed loop (IFToMM A02's horizontal position: the
constraint Jacobian loses rank) a run can go on along another branch of the constraint
manifold with small drift and status ok. How small the Jacobian's singular values get at
the output samples depends on where the samples fall, and on rounding when the run
passes close to the singular point: no threshold on them tells a branch change from a
passage that stays on its branch (the exact motion itself passes through the singular
point). What a branch change does change is the manifold the configuration lies on, so
this follows the starting branch itself, by pseudo-arclength continuation of
g(t, q) = 0 (the position constraints), from the start towards each output sample in
turn: the branch point nearest to the sample (along the branch) is reached by steps
q + s u (u: the tangent-space projection of the way to the sample) corrected by Newton's
method in the hyperplane orthogonal to u. A simple bifurcation point is stepped over on
the branch the continuation is on, because the branch's tangent is continuous there and
a step whose direction, or the tangent at whose end, turns by more than :data:`MAX_TURN`
(a jump onto the crossing branch) is refused and halved.

The run has left the branch at the first sample farther from the followed branch than
:data:`DRIFT_FACTOR` times its own distance from the constraint manifold (its drift) plus
:data:`FLOOR` (relative): on the branch that distance is the drift; on another branch it
grows with the distance travelled from the crossing. Coordinates are the formalism's q
(rad and m mixed, as the constraints see them).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from workbench.numerics.linalg import independent_rows

DRIFT_FACTOR = 100.0  # a sample this many times farther than its drift: off the branch
FLOOR = 1e-6  # ... and farther than this times (1 + max |q|)
MAX_TURN = 0.3  # rad: a continuation step turning more than this jumped branches
FIRST_STEP = 0.05  # continuation step (in |q|) to start with; adapted to the curvature
SMALLEST_STEP = 1e-9  # relative to 1 + max |q|: below it the continuation gives up
MOST_STEPS = 200_000  # continuation steps a run at most (then: not decided)
NEWTON = 8  # corrector iterations a step


Constraints = Callable[[float, np.ndarray], tuple[np.ndarray, np.ndarray]]


def branch_departure(constraints: Constraints, times: np.ndarray,
                     q: np.ndarray) -> tuple[float, float]:  # fmt: skip
    """(t, distance): the first output time at which the run's q (n, nq) is off the branch
    it started on (NaN when it stays on it), and its distance from that branch there (the
    largest distance over the run when it stays); (NaN, NaN) when it cannot be decided
    (no position constraints, or the continuation could not go on).

    ``constraints(t, q)`` -> (g (m,), dg/dq (m, nq)).
    """
    if len(times) < 2:
        return math.nan, math.nan
    g0, jacobian0 = constraints(float(times[0]), q[0])
    if np.size(g0) == 0:
        return math.nan, math.nan
    rank = len(independent_rows(np.atleast_2d(jacobian0)))
    if rank == 0:
        return math.nan, math.nan
    follower = _Follower(constraints, rank)
    x = follower.project(float(times[0]), q[0])
    if x is None:
        return math.nan, math.nan
    farthest = 0.0
    for k in range(1, len(times)):
        t = float(times[k])
        x = follower.project(t, x)  # the manifold at t (rheonomic constraints move)
        if x is None:
            return math.nan, math.nan
        x = follower.walk(t, x, q[k])
        if x is None:  # the continuation could not go on: not decided
            return math.nan, math.nan
        sample = follower.project(t, q[k])
        drift = float(np.linalg.norm(q[k] - sample)) if sample is not None else 0.0
        distance = float(np.linalg.norm(q[k] - x))
        farthest = max(farthest, distance)
        if distance > DRIFT_FACTOR * drift + FLOOR * (1.0 + float(np.max(np.abs(q[k])))):
            return t, distance
    return math.nan, farthest


class _Follower:
    """Continuation on g(t, .) = 0 with the rank the constraints had at the start."""

    def __init__(self, constraints: Constraints, rank: int) -> None:
        self.constraints, self.rank = constraints, rank
        self.step = FIRST_STEP
        self.steps = 0

    def _evaluate(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, jacobian = self.constraints(t, x)
        return np.ravel(g), np.atleast_2d(jacobian).reshape(np.size(g), x.size)

    def project(self, t: float, x: np.ndarray) -> np.ndarray | None:
        """x moved onto g(t, .) = 0 by minimum-norm Gauss-Newton steps (None: no)."""
        x = np.array(x, dtype=float)
        scale = 1.0 + float(np.max(np.abs(x)))
        for _ in range(2 * NEWTON):
            g, jacobian = self._evaluate(t, x)
            if not np.all(np.isfinite(g)):
                return None
            if np.max(np.abs(g), initial=0.0) <= 1e-13 * scale:
                return x
            step = _truncated_solve(jacobian, g, self.rank)
            x -= step
            if np.linalg.norm(step) <= 1e-15 * scale:
                return x
        g, _ = self._evaluate(t, x)
        return x if np.max(np.abs(g), initial=0.0) <= 1e-9 * scale else None

    def _tangent_direction(self, t: float, x: np.ndarray, way: np.ndarray) -> np.ndarray:
        """``way`` projected on the tangent space (the null space of the rank-``rank``
        part of dg/dq at x)."""
        _, jacobian = self._evaluate(t, x)
        _, _, vt = np.linalg.svd(jacobian, full_matrices=True)
        normal = vt[: self.rank]
        return way - normal.T @ (normal @ way)

    def walk(self, t: float, x: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        """The point of the branch through x nearest to ``target`` along the branch."""
        scale = 1.0 + float(np.max(np.abs(x)))
        last = math.inf
        while True:
            direction = self._tangent_direction(t, x, target - x)
            length = float(np.linalg.norm(direction))
            if length <= 1e-10 * scale or length >= last * (1 - 1e-6) and length < 1e-6 * scale:
                return x
            last = length
            unit = direction / length
            while True:
                self.steps += 1
                if self.steps > MOST_STEPS or self.step < SMALLEST_STEP * scale:
                    return None
                s = min(self.step, length)
                moved = self._corrected(t, x + s * unit, unit)
                if moved is not None:
                    travelled = moved - x
                    norm = float(np.linalg.norm(travelled))
                    turn = (
                        math.acos(min(1.0, max(-1.0, float(travelled @ unit) / norm)))
                        if norm
                        else 0.0
                    )
                    kept = float(np.linalg.norm(self._tangent_direction(t, moved, unit)))
                    if turn <= MAX_TURN and norm <= 2 * s and kept >= math.cos(MAX_TURN):
                        x = moved
                        if s == self.step:
                            self.step *= 1.5
                        break
                self.step /= 2

    def _corrected(self, t: float, predicted: np.ndarray, unit: np.ndarray) -> np.ndarray | None:
        """Newton on [g(t, y); unit . (y - predicted)] = 0 from ``predicted`` (None: fails)."""
        y = predicted.copy()
        scale = 1.0 + float(np.max(np.abs(y)))
        for _ in range(NEWTON):
            g, jacobian = self._evaluate(t, y)
            if not np.all(np.isfinite(g)):
                return None
            residual = np.concatenate([g, [unit @ (y - predicted)]])
            if np.max(np.abs(residual)) <= 1e-12 * scale:
                return y
            matrix = np.vstack([jacobian, unit[None, :]])
            step = _truncated_solve(matrix, residual, self.rank + 1)
            y -= step
        g, _ = self._evaluate(t, y)
        return y if np.max(np.abs(g), initial=0.0) <= 1e-9 * scale else None


def _truncated_solve(matrix: np.ndarray, rhs: np.ndarray, rank: int) -> np.ndarray:
    """Minimum-norm solution of matrix x = rhs keeping the ``rank`` largest singular
    values (rows redundant at the start stay out, as in the audit's ratio)."""
    u, values, vt = np.linalg.svd(matrix, full_matrices=False)
    keep = min(rank, int(np.sum(values > values[0] * 1e-14))) if values.size else 0
    return vt[:keep].T @ ((u[:, :keep].T @ rhs) / values[:keep])


def constraints_of(equations: Any) -> Constraints | None:
    """(t, q) -> (g, dg/dq) of a run's equations: the mechanical form's holonomic rows, or,
    when the formalism eliminated the loops (minimal velocities), the joints' position
    residuals on the body poses (observables); None without position constraints."""
    mechanical = equations.forms.get("mechanical")
    if mechanical is not None and int(getattr(mechanical, "n_holonomic", 0) or 0) > 0:
        nq = equations.nq

        def holonomic(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            (g,) = mechanical.position_constraints(t, x)
            (jacobian,) = mechanical.position_jacobian(t, x)
            g = np.array(g, dtype=float).ravel()
            return g, np.array(jacobian, dtype=float).reshape(g.size, nq)

        return holonomic
    if equations.model.cut_joints and hasattr(equations.observables, "residuals"):
        function = equations.observables.residuals.function
        names_in, names_out = function.name_in(), function.name_out()
        both = function.factory("residuals_and_jacobian", list(names_in),
                                [names_out[0], f"jac:{names_out[0]}:{names_in[1]}"])  # fmt: skip
        zero_v = np.zeros(equations.nv)

        def residuals(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            g, jacobian = both(t, x, zero_v)
            g = np.array(g, dtype=float).ravel()
            return g, np.array(jacobian, dtype=float).reshape(g.size, x.size)

        return residuals
    return None
