"""Dense linear algebra for constraint Jacobians: independent rows and columns, Gauss-Newton.

One implementation each, shared by the model analysis (``workbench describe``), every
formalism and the consistent initial state, so that they agree on which constraint rows
are redundant and assemble a closed loop the same way.

* :func:`independent_rows` decides redundancy and rank: which rows of a constraint
  Jacobian W (m, n) add a new constraint to the rows before them.
* :func:`independent_columns` chooses a well-conditioned set of columns to solve for
  (coordinate partitioning): which velocities or coordinates are dependent.
* :func:`gauss_newton` moves a configuration onto g(q) = 0 by minimum-norm steps.
* :func:`extreme_singular_values` gives sigma_1 and sigma_rank of many Jacobians at once
  (a run's samples), as the audit and the branch check measure rank loss.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.linalg

RANK_TOLERANCE = 1e-9
"""A row (column) is dependent when what it adds is below this fraction of the matrix's
size (its 2-norm for rows, the largest pivot for columns)."""


def independent_rows(matrix: np.ndarray, tolerance: float = RANK_TOLERANCE) -> list[int]:
    """Indices of the rows of ``matrix`` (m, n) independent of the rows kept before them.

    Greedy in row order: row i is kept when its distance from the span of the rows kept
    so far exceeds ``tolerance * ||matrix||_2``; the number of rows kept is the numerical
    rank. Why this algorithm:

    * Row order decides which rows are called redundant. Constraint rows come tree and
      closure joints first, cut joints and contacts last, so the redundant rows reported
      are the later ones (those of the cut joint a user would remove or loosen), by name
      the same in ``describe`` and in every formalism. Column-pivoted QR of W^T picks rows
      by size instead, so the answer would change with units (a row in metres competes
      with a dimensionless one).
    * The test is the quantity that matters, how much new constraint the row adds, and is
      relative to ||W||_2, so it does not change when W is scaled. A stacked-SVD test
      sigma_min([kept; row]) is stricter than that: by interlacing it is at most
      sigma_min(kept), so a nearly dependent pair of early rows would make a clearly
      independent later row look redundant.
    * Distances come from classical Gram-Schmidt with one reorthogonalization ("twice is
      enough", Giraud, Langou and Rozloznik 2005): the basis is orthonormal to working
      precision, so the distances are as accurate as from an SVD, at O(m^2 n).
    """
    matrix = np.asarray(matrix, dtype=float)
    if matrix.size == 0:
        return []
    scale = float(np.linalg.norm(matrix, 2))
    if scale == 0.0:
        return []
    basis = np.zeros((0, matrix.shape[1]))  # orthonormal rows spanning the kept rows
    kept = []
    for i, row in enumerate(matrix):
        residual = row.copy()
        for _ in range(2):
            residual -= basis.T @ (basis @ residual)
        distance = np.linalg.norm(residual)
        if distance > tolerance * scale:
            kept.append(i)
            basis = np.vstack([basis, residual / distance])
    return kept


def independent_columns(matrix: np.ndarray, tolerance: float = RANK_TOLERANCE) -> np.ndarray:
    """Indices of a best-conditioned set of rank-many columns of ``matrix`` (m, n).

    Column-pivoted Householder QR (LAPACK geqp3): each step takes the column with the
    largest component outside the span of the columns taken so far, which keeps the
    chosen block well conditioned; it stops where that component (|R_kk|) falls below
    ``tolerance`` times the first pivot |R_00|. Returned in pivot order (callers sort
    when they want the natural order). Used to choose the dependent coordinates or
    velocities to solve for; which constraint *rows* are redundant is
    :func:`independent_rows`.
    """
    matrix = np.asarray(matrix, dtype=float)
    if matrix.size == 0:
        return np.zeros(0, dtype=int)
    _, r, pivots = scipy.linalg.qr(matrix, pivoting=True, mode="economic")
    diagonal = np.abs(np.diag(r))
    scale = max(float(diagonal.max(initial=0.0)), 1e-300)
    return pivots[: int(np.sum(diagonal > tolerance * scale))]


EXACT_BELOW = 1e-2
"""sigma_rank / sigma_1 below which :func:`extreme_singular_values` takes the SVD's values."""


def extreme_singular_values(matrices: np.ndarray, rank: int) -> np.ndarray:
    """(k, 2): sigma_1 and sigma_rank of each stacked matrix (k, m, n), rank >= 1.

    From the eigenvalues of the smaller Gram matrix (A A^T or A^T A), whose rounding
    shifts sigma_rank by about eps (sigma_1 / sigma_rank)^2 / 2 relative (about 1e-12
    at the threshold), and by the SVD itself (``np.linalg.svd``, to the bit) for every
    matrix whose sigma_rank / sigma_1 falls below :data:`EXACT_BELOW` or that is not
    finite: near rank loss, where the figures are read, they are the SVD's. 401
    matrices of 29 x 35 (IFToMM A04's constraint Jacobians in absolute coordinates):
    16 ms against 24 for their SVD (one thread, Zen 3)."""
    matrices = np.asarray(matrices, dtype=float)
    k, m, n = matrices.shape
    values = np.zeros((k, 2))
    if k == 0 or min(m, n) == 0:
        return values
    near = ~np.all(np.isfinite(matrices), axis=(1, 2))  # (the SVD's answer: LinAlgError)
    fine = matrices[~near] if near.any() else matrices
    transposed = fine.transpose(0, 2, 1)
    eigenvalues = np.linalg.eigvalsh(fine @ transposed if m <= n else transposed @ fine)
    size = eigenvalues.shape[1]  # (ascending)
    largest = np.sqrt(np.maximum(eigenvalues[:, -1], 0.0))
    least = np.sqrt(np.maximum(eigenvalues[:, size - rank], 0.0)) if rank <= size else 0 * largest
    values[~near, 0], values[~near, 1] = largest, least
    near[~near] = ~(least >= EXACT_BELOW * largest) | (largest == 0)
    if near.any():
        exact = np.linalg.svd(matrices[near], compute_uv=False)
        values[near, 0] = exact[:, 0]
        values[near, 1] = exact[:, rank - 1] if rank <= exact.shape[1] else 0.0
    return values


class GaussNewtonResult(NamedTuple):
    """``x`` the last iterate, ``converged`` whether max |g(x)| <= the accepted tolerance,
    ``residual`` g at ``x`` (m)."""

    x: np.ndarray
    converged: bool
    residual: np.ndarray


def gauss_newton(
    evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    x0: np.ndarray,
    update: Callable[[np.ndarray, np.ndarray], np.ndarray],
    tolerance: float = 1e-12,
    max_iterations: int = 50,
    accept: float = 1e-9,
) -> GaussNewtonResult:
    """Solve g(x) = 0 (m equations) by minimum-norm Gauss-Newton steps.

    ``evaluate(x)`` returns g (m) and its Jacobian J (m, k) with respect to the step
    variables; the step solves J step = -g in the least-squares, minimum-norm sense (so
    redundant or fewer-than-unknowns equations are fine) and ``update(x, step)`` applies
    it (for instance x + H(x) step, then unit quaternions renormalized). Stops as soon as
    max |g| <= ``tolerance``; after ``max_iterations`` steps the last iterate counts as
    converged if max |g| <= ``accept``. A non-finite g or J stops at once, not converged.
    """
    x = np.asarray(x0, dtype=float)
    for _ in range(max_iterations):
        g, jacobian = evaluate(x)
        g = np.asarray(g, dtype=float).reshape(-1)
        if g.size == 0 or np.max(np.abs(g)) <= tolerance:
            return GaussNewtonResult(x, True, g)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(jacobian))):
            return GaussNewtonResult(x, False, g)
        step, *_ = np.linalg.lstsq(np.reshape(jacobian, (g.size, -1)), -g, rcond=None)
        x = update(x, step)
    g = np.asarray(evaluate(x)[0], dtype=float).reshape(-1)
    converged = bool(np.all(np.isfinite(g)) and np.max(np.abs(g), initial=0.0) <= accept)
    return GaussNewtonResult(x, converged, g)
