"""Sparse factors of symmetric positive definite matrices: CHOLMOD, else SuperLU.

pi-robust's sparse path factors ``Q~ + diag(d)`` (the interior point over the contacts),
``I + B B^T`` (the interior point and policy blocks over the degrees of freedom, Woodbury
form) and ``Q_FF + rho D_F`` (policy blocks over the contacts). Here they are factored by
CHOLMOD's simplicial LDL^T in an approximate-minimum-degree order (Chen, Davis, Hager and
Rajamanickam, "Algorithm 887: CHOLMOD, supernodal sparse Cholesky factorization and
update/downdate", ACM TOMS 35(3), 2008; Amestoy, Davis and Duff, "An approximate minimum
degree ordering algorithm", SIAM J. Matrix Anal. Appl. 17(4), 1996), through scikit-sparse,
when it imports; otherwise by SuperLU's LU with a symmetric minimum-degree order and diagonal
pivots (:func:`symmetric_splu`), the same factor in a slower form.

Why simplicial and not supernodal: the supernodal factor calls BLAS, whose kernels (and so
whose rounding) depend on the CPU and the thread count; the simplicial one is the same
arithmetic on every machine. Where the interior point factors one pattern again and again
with new values, :class:`PatternFactor` keeps CHOLMOD's symbolic analysis (ordering,
elimination tree, the pattern of L) and redoes only the numeric factorization.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

try:  # CHOLMOD (SuiteSparse) through scikit-sparse; SuperLU when it is not installed
    from sksparse import cholmod
except ImportError:  # pragma: no cover - the lock installs it
    cholmod = None

# which library factors (the factorization study and the tests read it)
LIBRARY = "SuperLU" if cholmod is None else "CHOLMOD"
# CHOLMOD's settings: simplicial LDL^T in approximate-minimum-degree order (module docstring)
CHOLMOD_MODE = "simplicial"
CHOLMOD_ORDERING = "amd"


def symmetric_splu(matrix: sp.spmatrix) -> spla.SuperLU:
    """SuperLU's factor of a symmetric positive definite sparse matrix.

    A symmetric ordering (minimum degree on A^T + A) and diagonal pivots.

    Parameters
    ----------
    matrix : sp.spmatrix
        The symmetric positive definite matrix.

    Returns
    -------
    spla.SuperLU
        Its factor, whose ``solve`` solves with it.

    Raises
    ------
    np.linalg.LinAlgError
        When it is exactly singular.
    """
    try:
        return spla.splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True})
    except RuntimeError as error:
        raise np.linalg.LinAlgError(str(error)) from error


class _Cholmod:
    """A CHOLMOD factor (scikit-sparse's ``Factor``) behind SuperLU's ``solve`` interface."""

    def __init__(self, factor: Any) -> None:
        self.factor = factor

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """The solution of the factored system.

        Parameters
        ----------
        rhs : np.ndarray
            The right-hand side.

        Returns
        -------
        np.ndarray
            The solution, shaped as ``rhs``.
        """
        return self.factor(rhs)


def _cholmod_call(function: Any, *args: Any, **kwargs: Any) -> Any:
    """``function(*args, **kwargs)`` with CHOLMOD's errors, and its warnings, raised as
    ``np.linalg.LinAlgError``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", cholmod.CholmodWarning)
        try:
            return function(*args, **kwargs)
        except (cholmod.CholmodError, cholmod.CholmodWarning) as error:
            raise np.linalg.LinAlgError(str(error)) from error


def symmetric_factor(matrix: sp.spmatrix) -> _Cholmod | spla.SuperLU:
    """A factor of the symmetric positive definite ``matrix``, made once (a new pattern).

    Parameters
    ----------
    matrix : sp.spmatrix
        The matrix, both triangles stored.

    Returns
    -------
    object
        The factor; its ``solve(rhs)`` solves ``matrix x = rhs``.

    Raises
    ------
    np.linalg.LinAlgError
        When the matrix is not numerically positive definite (CHOLMOD) or exactly singular
        (SuperLU).
    """
    if cholmod is None:
        return symmetric_splu(matrix)
    return _Cholmod(_cholmod_call(cholmod.cholesky, sp.csc_matrix(matrix),
                                  mode=CHOLMOD_MODE, ordering_method=CHOLMOD_ORDERING))


def gram_factor(B: sp.spmatrix) -> _Cholmod | spla.SuperLU:
    """A factor of ``I + B B^T``, made once (a new pattern).

    Parameters
    ----------
    B : sp.spmatrix
        The matrix B, shape (m, k).

    Returns
    -------
    object
        The factor of the (m, m) matrix; its ``solve(rhs)`` solves with it.

    Raises
    ------
    np.linalg.LinAlgError
        When the factorization fails.
    """
    if cholmod is None:
        B = sp.csr_matrix(B)
        return symmetric_splu(sp.identity(B.shape[0], format="csc") + B @ B.T)
    B = sp.csc_matrix(B)
    return _Cholmod(_cholmod_call(cholmod.cholesky_AAt, B, beta=1.0, mode=CHOLMOD_MODE,
                                  ordering_method=CHOLMOD_ORDERING))


class PatternFactor:
    """Factors matrices of one fixed sparsity pattern, one after another.

    ``symmetric`` (the default): ``S + diag(d)`` for a fixed symmetric S and varying d > 0;
    else ``I + B diag(s) diag(s) B^T`` for a fixed B and varying column scales s. With
    CHOLMOD, the symbolic analysis is made once, on the pattern, and each
    :meth:`factorize` redoes only the numeric factorization (values change, the pattern
    never does: the values are written into a fixed copy of the pattern, so that no entry that
    cancels to zero can drop out of it). With SuperLU, every factorization is made whole.
    """

    def __init__(self, matrix: sp.spmatrix, symmetric: bool = True) -> None:
        """``matrix``: S (symmetric) or B (``symmetric=False``)."""
        self.symmetric = symmetric
        if symmetric:
            # S's entries and a zero on every diagonal position, summed: S's values exactly,
            # in a pattern that holds the whole diagonal
            entries = sp.coo_matrix(matrix)
            n = entries.shape[0]
            template = sp.coo_matrix(
                (np.concatenate([entries.data, np.zeros(n)]),
                 (np.concatenate([entries.row, np.arange(n)]),
                  np.concatenate([entries.col, np.arange(n)]))), shape=(n, n)).tocsc()
            template.sort_indices()
            columns = np.repeat(np.arange(n), np.diff(template.indptr))
            self.diagonal_at = np.flatnonzero(template.indices == columns)
            self.base = template.data.astype(float, copy=True)
        else:
            template = sp.csc_matrix(matrix)
            template.sort_indices()
            self.columns = np.repeat(np.arange(template.shape[1]), np.diff(template.indptr))
            self.base = template.data.astype(float, copy=True)
        self.template = template
        self.analysis: Any = None
        if cholmod is not None:
            pattern = template.copy()
            pattern.data = np.ones_like(pattern.data)
            analyze = cholmod.analyze if symmetric else cholmod.analyze_AAt
            self.analysis = _cholmod_call(analyze, pattern, mode=CHOLMOD_MODE,
                                          ordering_method=CHOLMOD_ORDERING)

    def factorize(self, values: np.ndarray) -> _Cholmod | spla.SuperLU:
        """The factor of the pattern's matrix with new values.

        Parameters
        ----------
        values : np.ndarray
            d (``symmetric``: the diagonal added to S) or s (B's column scales), one per
            column.

        Returns
        -------
        object
            The factor, with a ``solve(rhs)``.

        Raises
        ------
        np.linalg.LinAlgError
            When the factorization fails.
        """
        matrix = self.template.copy()
        if self.symmetric:
            matrix.data = self.base.copy()
            matrix.data[self.diagonal_at] += values
        else:
            matrix.data = self.base * values[self.columns]
        if self.analysis is None:
            if self.symmetric:
                return symmetric_splu(matrix)
            return gram_factor(matrix)
        if self.symmetric:
            return _Cholmod(_cholmod_call(self.analysis.cholesky, matrix))
        return _Cholmod(_cholmod_call(self.analysis.cholesky_AAt, matrix, beta=1.0))


def updated_gram_factor(factor: object, added: sp.spmatrix, removed: sp.spmatrix
                        ) -> _Cholmod | None:
    """The factor of ``K + C_a C_a^T - C_r C_r^T`` from a CHOLMOD factor of K.

    CHOLMOD's multiple-rank update and downdate of the factor's copy (Davis and Hager,
    "Multiple-rank modifications of a sparse Cholesky factorization", SIAM J. Matrix Anal.
    Appl. 22(4), 2001; "Row modifications of a sparse Cholesky factorization", 2005), in the
    fill-reducing order of K's analysis: the cost grows with the columns changed and the
    paths they take in the elimination tree, not with K's whole factor.

    Parameters
    ----------
    factor : object
        A factor made here (by :func:`gram_factor`, :class:`PatternFactor` or this function).
    added, removed : sp.spmatrix
        C_a and C_r, each with K's row count (either may have no columns).

    Returns
    -------
    _Cholmod or None
        The new factor (``factor`` itself is left as it was); None where ``factor`` is not a
        CHOLMOD factor (SuperLU's cannot be updated: the caller factors afresh).

    Raises
    ------
    np.linalg.LinAlgError
        When the downdate leaves a matrix that is not numerically positive definite.
    """
    if cholmod is None or not isinstance(factor, _Cholmod):
        return None
    copy = factor.factor.copy()
    for columns, subtract in ((added, False), (removed, True)):
        if columns.shape[1]:
            _cholmod_call(copy.update_inplace, sp.csc_matrix(columns), subtract=subtract)
    return _Cholmod(copy)
