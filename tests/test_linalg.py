"""Independent rows and columns, and Gauss-Newton (workbench.numerics.linalg)."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.numerics import linalg
from workbench.numerics.linalg import gauss_newton, independent_columns, independent_rows


def rank_deficient() -> np.ndarray:
    """Rows a, b, a + b, c, 2c, 0 in R^5: rank 3, rows 2, 4 and 5 depend on earlier ones."""
    rng = np.random.default_rng(1)
    a, b, c = rng.standard_normal((3, 5))
    return np.array([a, b, a + b, c, 2 * c, np.zeros(5)])


def test_independent_rows_of_a_rank_deficient_matrix() -> None:
    assert independent_rows(rank_deficient()) == [0, 1, 3]


def test_independent_rows_keep_the_earlier_of_dependent_rows() -> None:
    matrix = rank_deficient()
    assert independent_rows(matrix[::-1]) == [1, 3, 4]  # 2c, a + b, b of the reversed rows


def test_independent_rows_do_not_depend_on_scale_or_units() -> None:
    matrix = rank_deficient()
    assert independent_rows(1e6 * matrix) == independent_rows(1e-6 * matrix) == [0, 1, 3]
    scaled_columns = matrix * np.array([1e3, 1.0, 1e-2, 1.0, 10.0])
    assert independent_rows(scaled_columns) == [0, 1, 3]


def test_independent_rows_tolerance_is_relative() -> None:
    matrix = rank_deficient()
    near = matrix.copy()
    near[2] += 1e-12 * np.linalg.norm(matrix, 2) * np.eye(5)[0]  # dependent to 1e-12
    assert independent_rows(near) == [0, 1, 3]
    apart = matrix.copy()
    apart[2] += 1e-6 * np.linalg.norm(matrix, 2) * np.eye(5)[0]  # independent by 1e-6
    assert independent_rows(apart) == [0, 1, 2, 3]


def test_independent_rows_count_is_the_numerical_rank() -> None:
    rng = np.random.default_rng(2)
    for rank in range(0, 6):
        matrix = rng.standard_normal((8, rank)) @ rng.standard_normal((rank, 7))
        assert len(independent_rows(matrix)) == rank == np.linalg.matrix_rank(matrix)


def test_a_nearly_dependent_early_pair_does_not_hide_a_later_row() -> None:
    # rows 0 and 1 differ by 1e-7 (independent at 1e-9); row 2 is clearly independent
    matrix = np.array([[1.0, 0.0, 0.0], [1.0, 1e-7, 0.0], [0.0, 0.0, 1.0]])
    assert independent_rows(matrix) == [0, 1, 2]


def test_independent_rows_of_empty_and_zero_matrices() -> None:
    assert independent_rows(np.zeros((0, 3))) == []
    assert independent_rows(np.zeros((2, 3))) == []


def test_independent_columns_choose_a_nonsingular_block() -> None:
    matrix = rank_deficient().T  # columns a, b, a + b, c, 2c, 0
    columns = independent_columns(matrix)
    assert columns.size == 3
    assert np.linalg.matrix_rank(matrix[:, columns]) == 3
    assert 5 not in columns


def test_gauss_newton_reaches_the_intersection_of_two_circles() -> None:
    # |x| = 1 and |x - (1, 0)| = 1: x = (1/2, +-sqrt(3)/2)
    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = np.array([x @ x - 1.0, (x - [1.0, 0.0]) @ (x - [1.0, 0.0]) - 1.0])
        return g, np.array([2 * x, 2 * (x - [1.0, 0.0])])

    result = gauss_newton(evaluate, np.array([0.3, 0.6]), lambda x, step: x + step)
    assert result.converged
    np.testing.assert_allclose(result.x, [0.5, np.sqrt(3) / 2], atol=1e-12)
    assert np.max(np.abs(result.residual)) <= 1e-12


def test_gauss_newton_takes_minimum_norm_steps_when_underdetermined() -> None:
    # one linear equation in three unknowns: x0 + x1 + x2 = 3 from 0 -> the nearest point
    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.array([x.sum() - 3.0]), np.ones((1, 3))

    result = gauss_newton(evaluate, np.zeros(3), lambda x, step: x + step)
    assert result.converged
    np.testing.assert_allclose(result.x, [1.0, 1.0, 1.0], atol=1e-14)


def test_gauss_newton_reports_failure() -> None:
    # x^2 + 1 = 0 has no real solution
    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.array([x[0] ** 2 + 1.0]), np.array([[2 * x[0]]])

    result = gauss_newton(evaluate, np.array([0.5]), lambda x, step: x + step)
    assert not result.converged

    def not_finite(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.array([np.nan]), np.array([[1.0]])

    result = gauss_newton(not_finite, np.array([0.5]), lambda x, step: x + step)
    assert not result.converged
    assert result.x[0] == 0.5


def test_extreme_singular_values_are_the_svds_and_its_bits_near_rank_loss():
    """sigma_1 and sigma_rank of stacked matrices (wide, tall, square; redundant rows, a
    zero matrix): within 1e-11 of ``np.linalg.svd`` where well conditioned, to the bit
    where sigma_rank / sigma_1 < EXACT_BELOW; a non-finite matrix raises as the SVD does."""
    rng = np.random.default_rng(7)
    for shape in [(40, 6, 9), (40, 9, 6), (40, 7, 7)]:
        matrices = rng.standard_normal(shape)
        matrices[1] *= np.geomspace(1.0, 1e-7, shape[2])  # near rank loss
        matrices[2, -1] = matrices[2, 0] + matrices[2, 1]  # a redundant row
        matrices[3] = 0.0
        singular = np.linalg.svd(matrices, compute_uv=False)
        for rank in (1, min(shape[1:]) - 1, min(shape[1:])):
            values = linalg.extreme_singular_values(matrices, rank)
            expected = singular[:, [0, rank - 1]]
            near = ~(expected[:, 1] >= linalg.EXACT_BELOW * expected[:, 0]) | (expected[:, 0] == 0)
            assert near[3] and (near[1] or rank == 1)  # (a zero matrix; rank loss)
            np.testing.assert_array_equal(values[near], expected[near])
            np.testing.assert_allclose(values[~near], expected[~near], rtol=1e-11)
    broken = rng.standard_normal((3, 4, 5))
    broken[1, 0, 0] = np.nan
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.svd(broken, compute_uv=False)
    with pytest.raises(np.linalg.LinAlgError):
        linalg.extreme_singular_values(broken, 4)
