"""Lemke's method for the frictional references (:mod:`qpbench.problem.friction_reference`).

A dense tableau with the lexicographic ratio test, qpbench's own, so that the references do
not depend on the solvers under test (:mod:`qpbench.solvers.lemke` is one of those).
"""

from __future__ import annotations

import numpy as np


def lemke(A: np.ndarray, c: np.ndarray, covering: np.ndarray | None = None,
          max_pivots: int | None = None, pivot_tol: float = 1e-11) -> np.ndarray | None:
    """z with ``z >= 0``, ``w = A z + c >= 0``, ``z^T w = 0`` by Lemke's method.

    Lemke's method (C. E. Lemke, Management Science 11(7), 1965) with the lexicographic ratio
    test (Cottle, Pang and Stone, *The Linear Complementarity Problem*, 1992, section 4.4);
    None when it ends on a secondary ray or runs out of pivots. Dense tableau of
    ``w - A z - covering z0 = c``.

    Parameters
    ----------
    A : np.ndarray
        The LCP's matrix, dense, size x size.
    c : np.ndarray
        The LCP's vector, shape (size,); z = 0 is returned at once when c >= 0.
    covering : np.ndarray or None, optional
        The positive covering vector of the artificial variable z0, shape (size,); None (the
        default) for ones.
    max_pivots : int or None, optional
        The most pivots; None (the default) for ``50 size + 100``.
    pivot_tol : float, optional
        Column entries up to this, relative to the column's largest magnitude (at least 1),
        are not pivots; 1e-11 by default.

    Returns
    -------
    np.ndarray or None
        z, shape (size,), or None.
    """
    size = c.shape[0]
    if size == 0 or np.all(c >= 0):
        return np.zeros(size)
    covering = np.ones(size) if covering is None else np.asarray(covering, dtype=float)
    max_pivots = 50 * size + 100 if max_pivots is None else max_pivots
    # columns: w (0..size-1), z (size..2 size-1), z0 (2 size)
    tableau = np.hstack([np.eye(size), -np.asarray(A, dtype=float), -covering[:, None]])
    rhs = np.asarray(c, dtype=float).copy()
    basis = np.arange(size)
    artificial = 2 * size
    # z0 enters at the level that makes every w >= 0: the row of min c_i / covering_i leaves
    ratios = rhs / covering
    low = float(ratios.min())
    row = _lexicographic_min(np.flatnonzero(ratios <= low + 1e-12 * abs(low)), tableau,
                             covering, size)
    entering = artificial
    for _ in range(max_pivots):
        leaving = int(basis[row])
        _pivot(tableau, rhs, row, entering)
        basis[row] = entering
        if leaving == artificial:
            z = np.zeros(size)
            for i, variable in enumerate(basis):
                if size <= variable < artificial:
                    z[variable - size] = max(rhs[i], 0.0)
            return z
        entering = leaving + size if leaving < size else leaving - size
        column = tableau[:, entering]
        rows = np.flatnonzero(column > pivot_tol * max(1.0, float(np.max(np.abs(column)))))
        if rows.size == 0:
            return None  # secondary ray
        ratios = rhs[rows] / column[rows]
        low = float(ratios.min())
        tied = rows[ratios <= low + 1e-12 * max(1.0, abs(low))]
        row = _lexicographic_min(tied, tableau, column, size)
    return None


def _lexicographic_min(tied: np.ndarray, tableau: np.ndarray, column: np.ndarray,
                       size: int) -> int:
    """Among rows with the same ratio, the one whose row of B^-1 (the tableau's w columns)
    divided by its pivot entry is lexicographically smallest."""
    for j in range(size):
        if tied.size == 1:
            break
        part = tableau[tied, j] / column[tied]
        low = float(part.min())
        tied = tied[part <= low + 1e-12 * max(1.0, abs(low))]
    return int(tied[0])


def _pivot(tableau: np.ndarray, rhs: np.ndarray, row: int, column: int) -> None:
    pivot = tableau[row, column]
    tableau[row] /= pivot
    rhs[row] /= pivot
    factor = tableau[:, column].copy()
    factor[row] = 0.0
    tableau -= np.outer(factor, tableau[row])
    rhs -= factor * rhs[row]
