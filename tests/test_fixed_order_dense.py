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
