"""Dense products and factorizations summed in a fixed order, against NumPy's own."""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.solvers import fixed_order_dense


def spd_matrix(size: int, seed: int, spread: float = 1.0) -> np.ndarray:
    """A symmetric positive definite matrix whose diagonal spans ``spread`` decades."""
    rng = np.random.default_rng(seed)
    factor = rng.normal(size=(size, size)) / np.sqrt(size)
    scales = np.logspace(0.0, spread, size)
    return (factor @ factor.T + np.eye(size)) * np.sqrt(scales[:, None] * scales[None, :])


@pytest.mark.parametrize("size", [1, 2, 7, 64, 150])
def test_the_symmetric_product_is_q_times_x(size: int) -> None:
    matrix = spd_matrix(size, seed=size)
    x = np.random.default_rng(1).normal(size=size)
    x[::3] = 0.0  # skipped rows change nothing
    expected = matrix @ x
    assert np.allclose(fixed_order_dense.symmetric_product(matrix, x), expected,
                       rtol=1e-12, atol=1e-12 * np.abs(matrix).max() * np.abs(x).sum())


@pytest.mark.parametrize("size", [1, 3, 40, 200])
def test_the_cholesky_factor_solves_a_positive_definite_system(size: int) -> None:
    matrix = spd_matrix(size, seed=size, spread=4.0)
    rhs = np.random.default_rng(2).normal(size=size)
    upper = fixed_order_dense.cholesky(matrix)
    assert np.allclose(np.triu(upper).T @ np.triu(upper), matrix, rtol=1e-12,
                       atol=1e-12 * np.abs(matrix).max())
    x = fixed_order_dense.cholesky_solve(upper, rhs)
    assert np.allclose(x, np.linalg.solve(matrix, rhs), rtol=1e-8, atol=1e-12)


def test_cholesky_refuses_a_matrix_that_is_not_positive_definite() -> None:
    indefinite = np.array([[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        fixed_order_dense.cholesky(indefinite)
    with pytest.raises(np.linalg.LinAlgError):
        fixed_order_dense.cholesky(np.array([[np.nan]]))


@pytest.mark.parametrize("size", [1, 5, 64])
def test_gaussian_elimination_solves_a_general_system_with_row_exchanges(size: int) -> None:
    rng = np.random.default_rng(size)
    matrix = rng.normal(size=(size, size))
    matrix[0, 0] = 0.0  # the first pivot must come from another row
    rhs = rng.normal(size=size)
    if size == 1:
        matrix[0, 0] = 3.0
    x = fixed_order_dense.lu_solve(matrix, rhs)
    assert np.allclose(matrix @ x, rhs, rtol=1e-10, atol=1e-10)


def test_gaussian_elimination_refuses_a_singular_matrix_as_numpy_does() -> None:
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(singular, np.ones(2))
    with pytest.raises(np.linalg.LinAlgError):
        fixed_order_dense.lu_solve(singular, np.ones(2))


def test_read_only_and_strided_operands_give_the_same_answers() -> None:
    """The wrappers hand the compiled functions contiguous writeable copies, so that numba
    never types another variant inside a clock and the answer is the same."""
    matrix = spd_matrix(20, seed=3)
    x = np.arange(40.0)[::2]
    frozen = matrix.copy()
    frozen.flags.writeable = False
    assert np.array_equal(fixed_order_dense.symmetric_product(frozen, x),
                          fixed_order_dense.symmetric_product(matrix, x.copy()))
    assert np.array_equal(fixed_order_dense.cholesky(frozen), fixed_order_dense.cholesky(matrix))


@pytest.mark.parametrize(("size", "rank"), [(1, 1), (6, 6), (6, 2), (40, 25), (120, 119)])
def test_the_least_norm_solve_is_numpys_least_squares_solution(size: int, rank: int) -> None:
    """On a positive semi-definite matrix of any rank: the least-squares solution of least
    norm, as ``np.linalg.lstsq`` (SVD) gives it; at full rank, the solution."""
    rng = np.random.default_rng(size + rank)
    factor = rng.normal(size=(rank, size)) * np.logspace(0.0, 2.0, rank)[:, None]
    matrix = factor.T @ factor
    rhs = rng.normal(size=size)
    x = fixed_order_dense.min_norm_solve(matrix, rhs)
    expected = np.linalg.lstsq(matrix, rhs, rcond=None)[0]
    assert np.allclose(x, expected, rtol=1e-8, atol=1e-10 * np.abs(expected).max())


def test_the_least_norm_solve_of_a_penalized_singular_system_and_of_zero() -> None:
    """A singular Q with a few contacts penalized by kappa = 1e9 (the penalty method's
    systems): the same residual as NumPy's least squares; a zero matrix gives zero."""
    rng = np.random.default_rng(7)
    factor = rng.normal(size=(12, 30))
    Q = factor.T @ factor
    matrix = Q + np.diag(1e9 * np.diag(Q) * (np.arange(30) % 4 == 0))
    rhs = rng.normal(size=30)
    x = fixed_order_dense.min_norm_solve(matrix, rhs)
    expected = np.linalg.lstsq(matrix, rhs, rcond=None)[0]
    assert np.isclose(np.linalg.norm(matrix @ x - rhs), np.linalg.norm(matrix @ expected - rhs),
                      rtol=1e-8)
    assert np.linalg.norm(x) <= np.linalg.norm(expected) * (1.0 + 1e-6)
    assert np.array_equal(fixed_order_dense.min_norm_solve(np.zeros((3, 3)), np.ones(3)),
                          np.zeros(3))
