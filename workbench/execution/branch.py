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

Most of a run is far from any singular configuration, where the continuation is a single
step a sample. :class:`_Shortcut` takes those steps for all samples at once (one mapped
evaluation of the constraints and one stacked solve per Newton iteration, by the Gram
matrix J J^T when the rows are independent, not one SVD per sample and iteration): sample
k's way from the projection of sample k-1 is taken as one step of the continuation, the
step the walk itself would take with its step length uncapped, and is accepted when it
passes the walk's own tests with a third of their turn (:data:`FAST_TURN`), the
constraint Jacobian is far from rank loss at the step's start and at sample k's projection
(sigma_rank / sigma_1 and sigma_rank both at least :data:`FAST_RATIO` times their largest
along the run), and it ends on the sheet of the manifold through sample k's
projection (the chord between them short and within the tangent space). Then sample k's
projection is the followed point and its distance is its drift. Every other sample (near
a singular configuration, a sharp bend, a change of branch) is walked by the continuation
from the point followed before it, as without the shortcut, and the shortcut resumes once
the walk is back on the sample's projection. Those walks too start from the projection
y_{k-1} wherever the sample before was followed to it, so they are first made for several
such samples together (:meth:`_Shortcut.walks`: the walk's own steps and tests, batched; in
windows of samples as the loop reaches them); a sample whose walk ends there on y_k is
followed to y_k as the walk one at a time would follow it, and the walk one at a time
takes the rest (RSRRR in absolute coordinates, 71 of 200 samples walked: its check
0.18-0.29 -> 0.10-0.16 s). When the constraints do not depend on t (found from the
Function's sparsity) and every projection already passes the projection's own first
test, the walk's starts are those projections as they are: projecting them at the next
sample's time would evaluate g at the same points to the same bits and take no
step (one evaluation of all samples saved a run).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from workbench.equations.evaluate import evaluate_along
from workbench.numerics.linalg import extreme_singular_values, independent_rows

DRIFT_FACTOR = 100.0  # a sample this many times farther than its drift: off the branch
FLOOR = 1e-6  # ... and farther than this times (1 + max |q|)
MAX_TURN = 0.3  # rad: a continuation step turning more than this jumped branches
FIRST_STEP = 0.05  # continuation step (in |q|) to start with; adapted to the curvature
SMALLEST_STEP = 1e-9  # relative to 1 + max |q|: below it the continuation gives up
MOST_STEPS = 200_000  # continuation steps a run at most (then: not decided)
NEWTON = 8  # corrector iterations a step
SETTLE = 50  # a sample's walk this many directions long: a step that turns back halves the next
FAST_TURN = MAX_TURN / 3  # rad: a sample's way taken in one step (:class:`_Shortcut`) turns less
FAST_RATIO = 1e-2  # ... and sigma_rank / sigma_1 of dg/dq, and sigma_rank, are at its ends at
# least this fraction of their largest along the run (far from rank loss)
GRAM_RATIO = 1e-5  # below it a sample's projection is by SVD (J J^T squares the condition)
WALK_WINDOW = 2  # samples walked at once first (then twice as many, ...)
WALK_ROUNDS = 48  # steps tried at most by :meth:`_Shortcut.walks` (then: one at a time; at
# 12, IFToMM A01's samples 0.5 s apart, about 2 rad of swing each, were all walked twice)
BATCH_VALUES = 1 << 22  # Jacobian entries evaluated at once (32 MiB): samples in batches


Constraints = Callable[[float, np.ndarray], tuple[np.ndarray, np.ndarray]]
Along = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def branch_departure(constraints: Constraints, times: np.ndarray,
                     q: np.ndarray) -> tuple[float, float]:  # fmt: skip
    """(t, distance): the first output time at which the run's q (n, nq) is off the branch
    it started on (NaN when it stays on it), and its distance from that branch there (the
    largest distance over the run when it stays); (NaN, NaN) when it cannot be decided
    (no position constraints, or the continuation could not go on).

    ``constraints(t, q)`` -> (g (m,), dg/dq (m, nq)); its attribute ``along(times, q)``,
    if it has one, -> (g (n, m), dg/dq (n, m, nq)) at n points in one call.
    """
    left_at, distance, _ = _departure(constraints, times, q)
    return left_at, distance


def _departure(constraints: Constraints, times: np.ndarray, q: np.ndarray,
               shortcut: bool = True) -> tuple[float, float, int]:  # fmt: skip
    """:func:`branch_departure` and the number of samples walked by the continuation
    (the others were taken by :class:`_Shortcut`; none with ``shortcut`` False)."""
    if len(times) < 2:
        return math.nan, math.nan, 0
    g0, jacobian0 = constraints(float(times[0]), q[0])
    if np.size(g0) == 0:
        return math.nan, math.nan, 0
    rank = len(independent_rows(np.atleast_2d(jacobian0)))
    if rank == 0:
        return math.nan, math.nan, 0
    follower = _Follower(constraints, rank)
    along = getattr(constraints, "along", None) or _one_at_a_time(constraints)
    rows = int(np.size(g0))
    fast = _Shortcut(along, np.asarray(times, dtype=float), np.asarray(q, dtype=float), rank, rows)
    if not fast.projected[0]:
        return math.nan, math.nan, 0
    x, on_shortcut = fast.y[0], shortcut  # the point followed: sample 0's projection
    farthest, walked = 0.0, 0
    # the others' walks from y_{k-1}, many at once: taken where they end on y_k (below);
    # made as the loop reaches them, in windows of WALK_WINDOW, 2 WALK_WINDOW, ... samples
    # while every walk of a window ends, WALK_WINDOW again after one that does not (a run
    # found off its branch leaves the rest unwalked; near a singular point few are walked
    # twice, in a window and one at a time)
    ends, refused = np.full_like(q, np.nan, dtype=float), np.flatnonzero(~fast.certified)
    walked_to, window = 0, WALK_WINDOW  # samples below walked_to: their walks made
    for k in range(1, len(times)):
        if on_shortcut and fast.certified[k]:
            x = fast.y[k]
            farthest = max(farthest, float(fast.drift[k]))
            continue
        walked += 1
        t = float(times[k])
        floor = FLOOR * (1.0 + float(np.max(np.abs(q[k]))))
        if on_shortcut and fast.projected[k]:
            if k >= walked_to:
                chosen = refused[refused >= k][:window]
                ends[chosen] = fast.walks(times, q, np.isin(np.arange(len(times)), chosen))[chosen]
                whole = bool(np.all(np.isfinite(ends[chosen])))  # (else: near a singular point)
                walked_to, window = int(chosen[-1]) + 1, 2 * window if whole else WALK_WINDOW
            distance = float(np.linalg.norm(q[k] - ends[k]))  # (NaN: not walked there)
            if distance <= DRIFT_FACTOR * float(fast.drift[k]) + floor and (
                float(np.linalg.norm(ends[k] - fast.y[k])) <= floor
            ):  # what the walk below finds, from the same start; its end within the
                # walk's stopping tolerance of y_k, whose own distance is the drift
                farthest = max(farthest, float(fast.drift[k]))
                x = fast.y[k]
                continue
        x = follower.project(t, x)  # the manifold at t (rheonomic constraints move)
        if x is None:
            return math.nan, math.nan, walked
        x = follower.walk(t, x, q[k])
        if x is None:  # the continuation could not go on: not decided
            return math.nan, math.nan, walked
        drift = float(fast.drift[k])
        distance = float(np.linalg.norm(q[k] - x))
        farthest = max(farthest, distance)
        if distance > DRIFT_FACTOR * drift + floor:
            return t, distance, walked
        # back on the sample's projection (within what the test above resolves)
        on_shortcut = (
            shortcut and bool(fast.projected[k]) and (float(np.linalg.norm(x - fast.y[k])) <= floor)
        )
        if on_shortcut:
            x = fast.y[k]
    return math.nan, farthest, walked


class _Shortcut:
    """All samples' projections, drifts and one-step continuations at once (module
    docstring). ``projected[k]``: sample k's projection ``y[k]`` onto g(t_k, .) = 0
    converged (its ``drift[k]`` = |q_k - y_k|, else 0, as the walk counts it);
    ``certified[k]``: the way from ``y[k-1]`` to sample k is one step the walk accepts,
    within the tighter tests, ending on ``y[k]``'s sheet (never for k = 0)."""

    def __init__(self, along: Along, times: np.ndarray, q: np.ndarray, rank: int,
                 rows: int) -> None:  # fmt: skip
        self.rank = rank
        self.gram = rank == rows  # independent rows: solves by the Gram matrix J J^T
        n = len(times)
        self.along = _Batches(along, n, (rank + 1) * q.shape[1])
        finite = np.all(np.isfinite(q), axis=1)  # (a failed run's last samples: not projected)
        q = np.where(finite[:, None], q, 0.0)
        scale = 1.0 + np.max(np.abs(q), axis=1)
        self.y, self.projected, y_jacobian, y_g = self._project(times, q)
        self.projected &= finite
        values_y = _singular_values(y_jacobian, rank)  # (n, 2): sigma_1, sigma_rank
        redo = ~self.projected | (_ratio(values_y) < GRAM_RATIO)
        if self.gram and redo.any():  # near rank loss: by SVD, as the walk projects
            self.gram, gram = False, self.gram
            again, converged, jacobian, g = self._project(times[redo], q[redo])
            self.gram = gram
            self.y[redo], self.projected[redo] = again, converged & finite[redo]
            values_y[redo] = _singular_values(jacobian, rank)
            y_jacobian[redo], y_g[redo] = jacobian, g
        self.drift = np.where(self.projected, np.linalg.norm(q - self.y, axis=1), 0.0)
        self.certified = np.zeros(n, dtype=bool)
        if n < 2:
            return
        # the walk's start at sample k: y_{k-1} moved onto g(t_k, .) = 0
        before = np.vstack([self.y[:1], self.y[:-1]])
        if getattr(along, "time_invariant", False) and _converged(before, y_g):
            # what _project(times, before) returns without a step: g(t, .) is g(t', .),
            # and every y_{k-1} already passes its test (one evaluation of n samples less)
            start, started = before.copy(), np.ones(n, dtype=bool)
            start_jacobian = np.concatenate([y_jacobian[:1], y_jacobian[:-1]])
        else:
            start, started, start_jacobian, _ = self._project(times, before)
        # (the walk's starts, for :meth:`walks`)
        self.start, self.start_ok, self.start_jacobian = start, started.copy(), start_jacobian
        started &= np.concatenate([[False], self.projected[:-1]]) & self.projected
        values_a = np.vstack([values_y[:1], values_y[:-1]])
        moved_on = np.any(start != before, axis=1)  # rheonomic constraints
        if moved_on.any():
            values_a[moved_on] = _singular_values(start_jacobian[moved_on], rank)
        # both ends far from rank loss: sigma_rank / sigma_1 and sigma_rank (a single row
        # that tends to 0) within FAST_RATIO of their best along the run
        ratio_y, ratio_a = _ratio(values_y), _ratio(values_a)
        best = self.projected & np.isfinite(ratio_y)
        if not best.any():
            return
        ratio_least = FAST_RATIO * float(np.max(ratio_y[best]))
        least = FAST_RATIO * float(np.max(values_y[best, 1]))
        started &= (ratio_a >= ratio_least) & (ratio_y >= ratio_least)
        started &= (values_a[:, 1] >= least) & (values_y[:, 1] >= least)
        way = q - start
        with np.errstate(all="ignore"):
            (normal,) = self._normal_part(start_jacobian, way)
            direction = way - normal
        length = np.linalg.norm(direction, axis=1)
        scale_a = 1.0 + np.max(np.abs(start), axis=1)
        still = length <= 1e-10 * scale_a  # the walk would stay at its start
        started &= np.isfinite(length)
        unit = np.where(started[:, None], direction, 0.0) / np.where(still, 1.0, length)[:, None]
        moved, corrected, moved_jacobian = self._corrected(
            times, start + length[:, None] * unit, unit, started & ~still
        )
        moved = np.where(still[:, None], start, moved)
        corrected |= still
        travelled = moved - start
        norm = np.linalg.norm(travelled, axis=1)
        chord = self.y - moved
        chord_length = np.linalg.norm(chord, axis=1)
        with np.errstate(all="ignore"):
            cosine = np.einsum("ki,ki->k", travelled, unit) / norm
            unit_normal, chord_normal = self._normal_part(moved_jacobian, unit, chord)
            kept = np.linalg.norm(unit - unit_normal, axis=1)
            chord_normal = np.linalg.norm(chord_normal, axis=1)
        turn = np.arccos(np.clip(np.where(norm > 0, cosine, 1.0), -1.0, 1.0))
        step_ok = still | ((turn <= FAST_TURN) & (norm <= 2 * length)
                           & (kept >= math.cos(FAST_TURN)))  # fmt: skip
        # on y_k's sheet: the chord from the step's end to y_k short and in its tangent space
        slack = 1e-9 * scale
        on_sheet = (chord_length <= FAST_TURN * length + slack) & (
            chord_normal <= math.sin(FAST_TURN) * chord_length + slack
        )
        self.certified = started & corrected & step_ok & on_sheet
        self.certified[0] = False

    def walks(self, times: np.ndarray, q: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """:meth:`_Follower.walk` from each ``wanted`` sample's start (y_{k-1} moved onto
        g(t_k, .) = 0) towards q_k, for all of them at once: the same steps, tests and
        stop, the normal space taken as the walk takes it (the first ``rank`` right
        singular vectors of dg/dq, even at a singular point), each sample's first step the
        whole way along its tangent (a walk whose adapted step is that long). Rows of NaN
        for a sample not walked to its end here (refused down to the smallest step, more
        than :data:`SETTLE` directions, or more than :data:`WALK_ROUNDS` steps tried): the
        walk takes those one by one. A round evaluates only the samples still walking
        (padded to a power of 2 of them)."""
        n, nq = q.shape
        ends = np.full((n, nq), np.nan)
        wanted = wanted & self.start_ok & np.all(np.isfinite(q), axis=1)
        wanted[0] = False
        rows = np.flatnonzero(wanted)  # the samples still walking
        if not len(rows):
            return ends
        t, target, x = times[rows], q[rows], self.start[rows].copy()
        jacobian = self.start_jacobian[rows].copy()
        scale = 1.0 + np.max(np.abs(x), axis=1)
        step, last = np.full(len(rows), np.nan), np.full(len(rows), np.inf)
        unit, length = np.zeros_like(x), np.zeros(len(rows))
        directions = np.zeros(len(rows), dtype=int)
        turned = np.ones(len(rows), dtype=bool)  # a new direction wanted (a step taken)
        for _ in range(WALK_ROUNDS):
            if turned.any():
                way = target - x
                new = way - self._walk_normal_part(jacobian, way)
                size = np.linalg.norm(new, axis=1)
                stop = turned & ((size <= 1e-10 * scale)
                                 | (size >= last * (1 - 1e-6)) & (size < 1e-6 * scale))  # fmt: skip
                ends[rows[stop]] = x[stop]
                turned &= ~stop
                last = np.where(turned, size, last)
                length = np.where(turned, size, length)
                unit[turned] = new[turned] / size[turned, None]
                step = np.where(turned & np.isnan(step), size, step)
                directions += turned
                keep = ~stop & (directions <= SETTLE)
                rows, t, target, x, jacobian, scale, step, last, unit, length, directions = (
                    a[keep] for a in (rows, t, target, x, jacobian, scale, step, last, unit,
                                      length, directions)
                )  # fmt: skip
            if not len(rows):
                break
            s = np.minimum(step, length)
            moved, converged, moved_jacobian = self._corrected(
                t, x + s[:, None] * unit, unit, np.ones(len(rows), dtype=bool)
            )
            travelled = moved - x
            norm = np.linalg.norm(travelled, axis=1)
            with np.errstate(all="ignore"):
                cosine = np.einsum("ki,ki->k", travelled, unit) / norm
                kept = np.linalg.norm(unit - self._walk_normal_part(moved_jacobian, unit), axis=1)
            turn = np.arccos(np.clip(np.where(norm > 0, cosine, 1.0), -1.0, 1.0))
            taken = converged & (turn <= MAX_TURN) & (norm <= 2 * s)
            taken &= kept >= math.cos(MAX_TURN)
            x[taken], jacobian[taken] = moved[taken], moved_jacobian[taken]
            step = np.where(taken, np.where(s == step, 1.5 * step, step), step / 2)
            keep = taken | (step >= SMALLEST_STEP * scale)
            turned = taken[keep]
            rows, t, target, x, jacobian, scale, step, last, unit, length, directions = (
                a[keep] for a in (rows, t, target, x, jacobian, scale, step, last, unit,
                                  length, directions)
            )  # fmt: skip
        return ends

    def _walk_normal_part(self, jacobians: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Each w's projection on the span of the first ``rank`` right singular vectors of
        its dg/dq, as the walk takes it: by the Gram matrix J J^T where the rows are
        independent and far from rank loss (its eigenvalues' ratio at least GRAM_RATIO
        squared: the same space), else by the SVD (at a singular point those vectors
        span more than the rows: the walk's choice, kept)."""
        if not self.gram:
            return _normal_part(self._normal_basis(jacobians), w)
        gram = jacobians @ jacobians.transpose(0, 2, 1)
        with np.errstate(all="ignore"):
            values = np.linalg.eigvalsh(_finite(gram))
            apart = values[:, 0] > GRAM_RATIO**2 * values[:, -1]
        part = np.empty_like(w)
        if apart.any():  # (the shortcut's own Gram solve)
            (part[apart],) = self._normal_part(jacobians[apart], w[apart])
        if not apart.all():
            part[~apart] = _normal_part(self._normal_basis(jacobians[~apart]), w[~apart])
        return part

    def _normal_basis(self, jacobians: np.ndarray) -> np.ndarray:
        """(k, rank, nq): the first ``rank`` right singular vectors of each dg/dq, as
        :meth:`_Follower._tangent_direction` takes them."""
        return np.linalg.svd(_finite(jacobians), full_matrices=True)[2][:, : self.rank]

    def _solve(self, matrices: np.ndarray, rhs: np.ndarray, rank: int,
               active: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """Minimum-norm solutions of the stacked systems (:func:`_truncated_solve`); only
        the ``active`` ones (default all) are needed. ``rhs`` (k, m), or (k, m, r): r
        right-hand sides a system, one factorization for them all."""
        columns = rhs if rhs.ndim == 3 else rhs[..., None]
        solved: list[np.ndarray] | None = None
        if self.gram:
            with np.errstate(all="ignore"):
                try:
                    gram = matrices @ matrices.transpose(0, 2, 1)
                    if active is not None:  # (an idle one may be singular: no matter)
                        gram[~active] = np.eye(gram.shape[1])
                    factors = np.linalg.solve(gram, columns)
                    solved = [np.einsum("kmi,km->ki", matrices, factors[..., j])
                              for j in range(columns.shape[2])]  # fmt: skip
                except np.linalg.LinAlgError:  # an exactly singular one
                    pass
        if solved is None:
            solved = [_truncated_solves(matrices, columns[..., j], rank)
                      for j in range(columns.shape[2])]  # fmt: skip
        return np.stack(solved, axis=-1) if rhs.ndim == 3 else solved[0]

    def _normal_part(self, jacobians: np.ndarray, *ws: np.ndarray) -> list[np.ndarray]:
        """Each w's part in the row space of the rank-``rank`` part of its dg/dq (w less
        its projection on the tangent space, as :meth:`_Follower._tangent_direction`),
        for each of ``ws`` (one Gram factorization or SVD of the Jacobians for all of them)."""
        if self.gram:
            rhs = np.stack([np.einsum("kmi,ki->km", jacobians, w) for w in ws], axis=-1)
            solved = self._solve(jacobians, rhs, self.rank)
            return [np.ascontiguousarray(solved[..., j]) for j in range(len(ws))]
        normal = self._normal_basis(jacobians)
        return [_normal_part(normal, w) for w in ws]

    def _project(
        self, times: np.ndarray, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_Follower.project` of every row of x at its time: (points, converged,
        dg/dq at the points, g there)."""
        x = np.array(x, dtype=float)
        scale = 1.0 + np.max(np.abs(x), axis=1)
        active = np.ones(len(x), dtype=bool)
        failed = np.zeros(len(x), dtype=bool)
        for _ in range(2 * NEWTON):
            g, jacobian = self.along(times, x)
            failed |= active & ~np.all(np.isfinite(g), axis=1)
            active &= ~failed & (np.max(np.abs(g), axis=1, initial=0.0) > 1e-13 * scale)
            if not active.any():
                return x, ~failed, jacobian, g
            step = self._solve(jacobian, g, self.rank, active)
            step[~active] = 0.0
            x -= step
            active &= np.linalg.norm(step, axis=1) > 1e-15 * scale  # a stalled one: as it is
        g, jacobian = self.along(times, x)
        with np.errstate(invalid="ignore"):
            close = np.max(np.abs(g), axis=1, initial=0.0) <= 1e-9 * scale
        return x, ~failed & (close | ~active), jacobian, g

    def _corrected(self, times: np.ndarray, predicted: np.ndarray, unit: np.ndarray,
                   wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """:meth:`_Follower._corrected` of the ``wanted`` rows: (points, converged, dg/dq
        there)."""
        y = predicted.copy()
        scale = 1.0 + np.max(np.abs(y), axis=1)
        active = wanted.copy()
        failed = np.zeros(len(y), dtype=bool)
        for _ in range(NEWTON):
            g, jacobian = self.along(times, y)
            failed |= active & ~np.all(np.isfinite(g), axis=1)
            residual = np.concatenate(
                [g, np.einsum("ki,ki->k", unit, y - predicted)[:, None]], axis=1
            )
            active &= ~failed & (np.max(np.abs(residual), axis=1) > 1e-12 * scale)
            if not active.any():
                return y, ~failed, jacobian
            matrix = np.concatenate([jacobian, unit[:, None, :]], axis=1)
            step = self._solve(matrix, residual, self.rank + 1, active)
            step[~active] = 0.0
            y -= step
        g, jacobian = self.along(times, y)
        with np.errstate(invalid="ignore"):
            close = np.max(np.abs(g), axis=1, initial=0.0) <= 1e-9 * scale
        return y, ~failed & close, jacobian


class _Batches:
    """``along`` over all n samples in batches of about :data:`BATCH_VALUES` matrix
    entries at most (each batch the same size, the last padded: one mapped Function);
    fewer points (:meth:`_Shortcut.walks`' last walks) padded to a power of 2."""

    def __init__(self, along: Along, n: int, values_per_point: int) -> None:
        self.along = along
        self.size = max(1, min(n, BATCH_VALUES // max(1, values_per_point)))

    def __call__(self, times: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(x)
        size = min(self.size, 1 << max(0, n - 1).bit_length())  # fewer: a power of 2 of them
        parts = []
        for begin in range(0, n, size):
            end = min(begin + size, n)
            pad = size - (end - begin)
            t_part = np.concatenate([times[begin:end], np.repeat(times[end - 1], pad)])
            x_part = np.concatenate([x[begin:end], np.repeat(x[end - 1 : end], pad, axis=0)])
            g, jacobian = self.along(t_part, x_part)
            parts.append((g[: end - begin], jacobian[: end - begin]))
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def _one_at_a_time(constraints: Constraints) -> Along:
    """``along`` for constraints that have none: one call a point."""

    def along(times: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pairs = [constraints(float(t), x_k) for t, x_k in zip(times, x, strict=True)]
        g = np.array([np.ravel(p[0]) for p in pairs], dtype=float)
        jacobian = np.array([np.reshape(p[1], (g.shape[1], x.shape[1])) for p in pairs])
        return g, jacobian

    return along


def _converged(x: np.ndarray, g_before: np.ndarray) -> bool:
    """Would :meth:`_Shortcut._project` leave every row of x as it is, given g at each
    row's predecessor (row 0: at itself), which is g at the row when g does not depend on
    t? (Its first test: g finite and max |g| <= 1e-13 (1 + max |x|).)"""
    g = np.concatenate([g_before[:1], g_before[:-1]])
    with np.errstate(invalid="ignore"):
        small = np.max(np.abs(g), axis=1, initial=0.0) <= 1e-13 * (1.0 + np.max(np.abs(x), axis=1))
    return bool(np.all(np.isfinite(g)) and np.all(small))


def _normal_part(normal: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Each w's projection on the span of its basis ``normal`` (k, rank, nq)."""
    return np.einsum("kri,kr->ki", normal, np.einsum("kri,ki->kr", normal, w))


def _finite(matrices: np.ndarray) -> np.ndarray:
    """The stacked matrices, those with a non-finite entry replaced by zeros (LAPACK
    refuses NaN; a zero matrix is never well conditioned, so never certified)."""
    bad = ~np.all(np.isfinite(matrices), axis=(1, 2))
    return np.where(bad[:, None, None], 0.0, matrices) if bad.any() else matrices


def _singular_values(matrices: np.ndarray, rank: int) -> np.ndarray:
    """(k, 2): sigma_1 and sigma_rank of each stacked matrix, a non-finite one as zeros
    (:func:`~workbench.numerics.linalg.extreme_singular_values`: the SVD's near rank loss)."""
    return extreme_singular_values(_finite(matrices), rank)


def _ratio(values: np.ndarray) -> np.ndarray:
    """sigma_rank / sigma_1 of each row (sigma_1, sigma_rank) (0 for a zero matrix)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(values[:, 0] > 0, values[:, 1] / values[:, 0], 0.0)


def _truncated_solves(matrices: np.ndarray, rhs: np.ndarray, rank: int) -> np.ndarray:
    """:func:`_truncated_solve` of each stacked system (k, m, n) x = (k, m)."""
    u, values, vt = np.linalg.svd(_finite(matrices), full_matrices=False)
    tiny = values <= values[:, :1] * 1e-14
    keep = (np.arange(values.shape[1]) < rank) & ~tiny
    with np.errstate(divide="ignore", invalid="ignore"):
        coefficients = np.where(keep, np.einsum("kmr,km->kr", u, rhs) / values, 0.0)
    return np.einsum("kri,kr->ki", vt, coefficients)


class _Follower:
    """Continuation on g(t, .) = 0 with the rank the constraints had at the start."""

    def __init__(self, constraints: Constraints, rank: int) -> None:
        self.constraints, self.rank = constraints, rank
        self._normal: tuple[tuple[float, bytes], np.ndarray] | None = None
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
        part of dg/dq at x). The last point's normal space is kept: a step's end is
        asked twice (its tangent test, then the next step's direction)."""
        key = (t, x.tobytes())
        if self._normal is None or self._normal[0] != key:
            _, jacobian = self._evaluate(t, x)
            _, _, vt = np.linalg.svd(jacobian, full_matrices=True)
            self._normal = (key, vt[: self.rank])
        normal = self._normal[1]
        return way - normal.T @ (normal @ way)

    def walk(self, t: float, x: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        """The point of the branch through x nearest to ``target`` along the branch.

        Each direction's step is the way left along the tangent (capped by the adapted
        step): where the branch bends more than the target is near (|target - x| beyond
        its radius of curvature) that step overshoots the nearest point by more than it
        was away, and the walk swings about it for ever (RSRRR after its integrator
        failed: 200,000 steps, 20-30 s, then not decided). After :data:`SETTLE`
        directions at one sample, a direction that turns back from the last one halves
        the longest step from then on, so the walk closes in on the nearest point; the
        walks that end sooner (all those of the catalog's runs but these) are as they
        were, step for step."""
        scale = 1.0 + float(np.max(np.abs(x)))
        last = math.inf
        directions, reach, previous = 0, math.inf, None
        while True:
            direction = self._tangent_direction(t, x, target - x)
            length = float(np.linalg.norm(direction))
            if length <= 1e-10 * scale or length >= last * (1 - 1e-6) and length < 1e-6 * scale:
                return x
            last = length
            unit = direction / length
            directions += 1
            if directions > SETTLE and previous is not None and unit @ previous[0] < 0:
                reach = previous[1] / 2  # it went past the nearest point: at most half that
            while True:
                self.steps += 1
                if self.steps > MOST_STEPS or self.step < SMALLEST_STEP * scale:
                    return None
                s = min(self.step, length, reach)
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
                        x, previous = moved, (unit, s)
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
    """(t, q) -> (g, dg/dq) of a run's equations: their ``position_closure`` if they have
    one (a formalism whose observables solve the loops themselves), the mechanical form's
    holonomic rows, or, when the formalism eliminated the loops (minimal velocities), the
    joints' position residuals on the body poses (observables); None without position
    constraints. Its
    ``along`` evaluates n points in one mapped call of the symbolic Functions (made once
    per equations)."""
    mechanical = equations.forms.get("mechanical")
    made = equations.__dict__.setdefault("_branch_functions", {})
    closure = getattr(equations, "position_closure", None)  # (t, q) -> (g, dg/dq), its own
    if closure is not None and closure.size1_out(0) > 0:

        def own(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            g, jacobian = closure(t, x)
            g = np.array(g, dtype=float).ravel()
            return g, np.array(jacobian, dtype=float).reshape(g.size, x.size)

        own.along = _mapped_along(closure, made, 0)  # type: ignore[attr-defined]
        return own
    if mechanical is not None and int(getattr(mechanical, "n_holonomic", 0) or 0) > 0:
        nq = equations.nq

        def holonomic(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            (g,) = mechanical.position_constraints(t, x)
            (jacobian,) = mechanical.position_jacobian(t, x)
            g = np.array(g, dtype=float).ravel()
            return g, np.array(jacobian, dtype=float).reshape(g.size, nq)

        if "holonomic" not in made:
            g_function = mechanical.position_constraints.function
            jacobian_function = mechanical.position_jacobian.function
            t, x = ca.MX.sym("t"), ca.MX.sym("q", nq)
            made["holonomic"] = ca.Function(
                "g_and_g_q", [t, x], [g_function(t, x), jacobian_function(t, x)]
            )
        holonomic.along = _mapped_along(made["holonomic"], made, 0)  # type: ignore[attr-defined]
        return holonomic
    if equations.model.cut_joints and hasattr(equations.observables, "residuals"):
        if "residuals" not in made:
            function = equations.observables.residuals.function
            names_in, names_out = function.name_in(), function.name_out()
            made["residuals"] = function.factory(
                "residuals_and_jacobian", list(names_in),
                [names_out[0], f"jac:{names_out[0]}:{names_in[1]}"],
            )  # fmt: skip
        both = made["residuals"]
        zero_v = np.zeros(equations.nv)

        def residuals(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            g, jacobian = both(t, x, zero_v)
            g = np.array(g, dtype=float).ravel()
            return g, np.array(jacobian, dtype=float).reshape(g.size, x.size)

        residuals.along = _mapped_along(both, made, equations.nv)  # type: ignore[attr-defined]
        return residuals
    return None


def _mapped_along(function: ca.Function, cache: dict, nv: int) -> Along:
    """``along`` of a Function (t, q[, v]) -> (g, dg/dq): one mapped call (v = 0). Its
    ``time_invariant``: no output depends on t (found once per Function, from its
    sparsity), so g(t, q) is g(t', q) to the last bit."""

    def along(times: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(times)
        args = [np.asarray(times, dtype=float)[None], np.asarray(x, dtype=float).T]
        if nv:
            args.append(np.zeros((nv, n)))
        g, jacobian = evaluate_along(function, n, args, cache)
        return g.reshape(n, -1), jacobian

    key = ("time_invariant", id(function))
    if key not in cache or cache[key][0] is not function:  # (an unpickled cache's ids)
        depends = function.which_depends(function.name_in(0), function.name_out(), 1, False)
        cache[key] = (function, not any(depends))
    along.time_invariant = cache[key][1]  # type: ignore[attr-defined]
    return along
