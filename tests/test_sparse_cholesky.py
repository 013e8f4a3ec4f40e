"""The sparse factors of pi-robust's sparse path: CHOLMOD, and SuperLU where it is missing."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.solvers import sparse_cholesky
from qpbench.solvers.sparse_cholesky import PatternFactor, gram_factor, symmetric_factor


def _chain(n: int) -> sp.csc_matrix:
    """The path graph's Laplacian: symmetric, positive semi-definite, singular."""
    main = np.full(n, 2.0)
    main[[0, -1]] = 1.0
    return sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, -1, 1], format="csc")


def _contacts(rows: int, columns: int, seed: int) -> sp.csc_matrix:
    """A sparse B with three entries a column, like L = M^-1/2 G over degrees of freedom."""
    rng = np.random.default_rng(seed)
    picked = np.stack([rng.choice(rows, 3, replace=False) for _ in range(columns)])
    return sp.csc_matrix((rng.normal(size=3 * columns),
                          (picked.ravel(), np.repeat(np.arange(columns), 3))),
                         shape=(rows, columns))


@pytest.fixture(params=["CHOLMOD", "SuperLU"])
def library(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Every test runs with CHOLMOD and with the SuperLU fallback."""
    if request.param == "SuperLU":
        monkeypatch.setattr(sparse_cholesky, "cholmod", None)
    return request.param


def test_the_locked_environment_factors_with_cholmod() -> None:
    assert sparse_cholesky.LIBRARY == "CHOLMOD"
    assert sparse_cholesky.cholmod is not None


def test_a_factor_solves_a_shifted_singular_matrix(library: str) -> None:
    S = _chain(200)
    matrix = S + sp.diags(np.full(200, 1e-6))
    rhs = np.random.default_rng(0).normal(size=200)
    x = symmetric_factor(matrix).solve(rhs)
    backward = np.abs(matrix @ x - rhs).max() / (abs(matrix) @ np.abs(x)).max()
    assert backward <= 1e-13


def test_a_gram_factor_solves_identity_plus_b_b_transpose(library: str) -> None:
    B = _contacts(60, 150, seed=1)
    rhs = np.random.default_rng(2).normal(size=60)
    x = gram_factor(B).solve(rhs)
    dense = np.eye(60) + (B @ B.T).toarray()
    np.testing.assert_allclose(dense @ x, rhs, atol=1e-10)


def test_a_pattern_factor_takes_new_diagonals_on_one_analysis(library: str) -> None:
    S = sp.csc_matrix(_contacts(40, 90, seed=3).T @ _contacts(40, 90, seed=3))
    pattern = PatternFactor(S)
    rng = np.random.default_rng(4)
    for scale in (1e-8, 1.0, 1e4):
        d = scale * rng.uniform(0.5, 2.0, size=90)
        rhs = rng.normal(size=90)
        x = pattern.factorize(d).solve(rhs)
        matrix = S.toarray() + np.diag(d)
        # a backward-stable solve: the residual is rounding's, relative to |matrix| |x|
        backward = np.abs(matrix @ x - rhs).max() / (np.abs(matrix) @ np.abs(x)).max()
        assert backward <= 1e-13


def test_a_pattern_factor_keeps_entries_whose_values_cancel(library: str) -> None:
    # B's two columns touch both rows: with equal scales the off-diagonal of I + B S^2 B^T is
    # 1 - 1 = 0, an entry that cancels; the pattern and the answer must not depend on it
    B = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, -1.0]]))
    pattern = PatternFactor(B, symmetric=False)
    for scales in (np.array([1.0, 1.0]), np.array([2.0, 0.5])):
        rhs = np.array([1.0, 3.0])
        dense = np.eye(2) + (B @ sp.diags(scales ** 2) @ B.T).toarray()
        np.testing.assert_allclose(pattern.factorize(scales).solve(rhs),
                                   np.linalg.solve(dense, rhs), rtol=1e-12)


def test_a_singular_matrix_raises_linalg_error(library: str) -> None:
    singular = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(np.linalg.LinAlgError):
        symmetric_factor(singular)


def test_an_updated_gram_factor_solves_as_a_fresh_one() -> None:
    B = _contacts(60, 150, seed=5)
    added, removed = _contacts(60, 4, seed=6), B[:, :3]
    factor = gram_factor(B)
    updated = sparse_cholesky.updated_gram_factor(factor, added, removed)
    new = sp.hstack([B[:, 3:], added])
    matrix = np.eye(60) + (new @ new.T).toarray()
    rhs = np.random.default_rng(7).normal(size=60)
    x = updated.solve(rhs)
    backward = np.abs(matrix @ x - rhs).max() / (np.abs(matrix) @ np.abs(x)).max()
    assert backward <= 1e-13
    # the factor it started from is left as it was
    original = np.eye(60) + (B @ B.T).toarray()
    np.testing.assert_allclose(original @ factor.solve(rhs), rhs, atol=1e-10)


def test_a_superlu_factor_is_not_updated(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sparse_cholesky, "cholmod", None)
    B = _contacts(30, 60, seed=8)
    assert sparse_cholesky.updated_gram_factor(gram_factor(B), B[:, :1], B[:, 1:2]) is None
