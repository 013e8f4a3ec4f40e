"""The breakdown's floor in compiled code: what is timed is LAPACK's Cholesky and a CSC
product, and they compute what SciPy computes. Correctness only: no wall-clock assertion."""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from qpbench.studies import compiled_floor


def spd(n: int, seed: int = 0) -> np.ndarray:
    factor = np.random.default_rng(seed).standard_normal((n, n))
    return factor @ factor.T + n * np.eye(n)


def test_the_dense_floor_factors_as_numpy_does() -> None:
    matrix = np.asfortranarray(spd(9))
    work = np.empty_like(matrix, order="F")
    assert compiled_floor._repeat_cholesky(matrix, work, 2, True, False) == 0
    np.testing.assert_allclose(np.tril(work), np.linalg.cholesky(matrix), rtol=1e-12)
    with_copy, copy = compiled_floor.cholesky_rounds(matrix, False)()
    assert with_copy > 0 and copy > 0


def test_the_banded_floor_factors_as_scipy_does() -> None:
    n = 12  # tridiagonal [-1, 4, -1] in lower band storage
    band = np.vstack([np.full(n, 4.0), np.append(np.full(n - 1, -1.0), 0.0)])
    work = np.empty_like(np.asfortranarray(band), order="F")
    assert compiled_floor._repeat_cholesky(np.asfortranarray(band), work, 3, True, True) == 0
    np.testing.assert_allclose(work, la.cholesky_banded(band, lower=True), rtol=1e-14)
    with_copy, copy = compiled_floor.cholesky_rounds(band, True)()
    assert with_copy > 0 and copy > 0


def test_a_matrix_that_is_not_positive_definite_has_no_floor() -> None:
    indefinite = np.array([[1.0, 2.0], [2.0, 1.0]])
    assert compiled_floor.cholesky_rounds(indefinite, False) is None


def test_the_timed_product_is_q_times_l() -> None:
    Q = sp.random(15, 15, density=0.3, format="csc", random_state=1)
    impulses = np.random.default_rng(3).random(15)
    product = np.empty(15)
    compiled_floor._repeat_product(Q.indptr, Q.indices, Q.data, impulses, product, 2)
    np.testing.assert_allclose(product, Q @ impulses, rtol=1e-14)
    assert compiled_floor.product_rounds(Q.indptr, Q.indices, Q.data, impulses)() > 0
