"""Parallel contacts: the looser constraint of each parallel group, dropped before a solve.

With ``Q = A^T A`` (``A = M^-1/2 G``, column a_i a contact's), LCP(Q, b) reads
``w_i = a_i^T y + b_i >= 0`` at ``y = A l``. Two contacts whose columns are parallel and point
the same way (``a_j = c a_i``, c > 0: a contact captured twice) meet Cauchy-Schwarz with
equality, ``Q_ij^2 = Q_ii Q_jj``, and every column of Q is then ``Q_kj = c Q_ki``: Q_FF is
singular whenever both are free. Since ``c = sqrt(Q_jj / Q_ii)``, ``w_j = c w_i + (b_j -
c b_i)``, so when ``b_j / sqrt(Q_jj) >= b_i / sqrt(Q_ii)`` contact j's constraint is implied
by contact i's: in an answer of the problem without j, ``w_j >= c w_i >= 0``, and j may stay
at l = 0. Dropping the looser contact of every parallel pair (the first of equals kept)
halves a problem of duplicated contacts and leaves fewer dependent columns. It is a presolve
of the kind that removes duplicate rows of a linear program (Andersen and Andersen,
"Presolving in linear programming", Math. Program. 71, 1995); the caller maps the answer back
and accepts it only on qpbench's residual of the whole problem, since parallel is decided up
to rounding (``PARALLEL_DEFECT``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import PARALLEL_DEFECT, WITHOUT_REFCOUNTS


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _alignment(entry: float, diag_i: float) -> float:
    """``Q_ij |Q_ij| / Q_ii`` for the entry Q_ij (0 where Q_ii is not positive): contacts i and
    j are parallel when it exceeds ``(1 - PARALLEL_DEFECT) Q_jj``, that is ``Q_ij > 0`` and
    ``Q_ij^2 > (1 - PARALLEL_DEFECT) Q_ii Q_jj``. No negative entry makes it positive."""
    return entry * abs(entry) / diag_i if diag_i > 0.0 else 0.0


@njit(cache=True, **WITHOUT_REFCOUNTS)
def diagonal_into(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                  diag: np.ndarray) -> bool:
    """Write diag(Q) into ``diag`` and tell whether any two contacts are parallel.

    One pass over Q's entries, which every solve makes to read its diagonal anyway: most
    problems have no parallel contacts, and this is what they pay. In column j, the entries
    above the diagonal (rows i < j, whose D_i is known by then) give their largest
    :func:`_alignment`, and a pair is parallel when it exceeds ``(1 - PARALLEL_DEFECT) Q_jj``
    (as in :func:`looser_parallel`).

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays (symmetric).
    diag : np.ndarray
        n entries, overwritten with diag(Q) (duplicate entries summed, as SciPy's
        ``diagonal``).

    Returns
    -------
    bool
        Whether some pair of contacts is parallel.
    """
    parallel = False
    for j in range(diag.size):
        diag[j] = 0.0
        largest = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            if i == j:
                diag[j] += data[k]
            elif i < j:
                largest = max(largest, _alignment(data[k], diag[i]))
        if largest > (1.0 - PARALLEL_DEFECT) * diag[j]:
            parallel = True
    return parallel


@njit(cache=True)
def looser_parallel(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, b: np.ndarray,
                    diag: np.ndarray) -> np.ndarray:
    """Mark the contacts whose constraint a parallel contact's implies.

    Contacts i and j are parallel when :func:`_alignment` of Q_ij exceeds ``(1 -
    PARALLEL_DEFECT) Q_jj`` (both diagonals positive), the test of :func:`diagonal_into`. Of a
    parallel pair, the one with the larger ``b / sqrt(Q_ii)`` is looser; of equals, the later
    one.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays (symmetric, so each pair is met from both columns).
    b : np.ndarray
        The LCP's constant term.
    diag : np.ndarray
        diag(Q).

    Returns
    -------
    np.ndarray
        Boolean, n entries: True for a contact to drop.
    """
    n = b.size
    dropped = np.zeros(n, dtype=np.bool_)
    for j in range(n):
        if diag[j] <= 0.0:
            continue
        tightness_j = b[j] / np.sqrt(diag[j])
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            if i == j or _alignment(data[k], diag[i]) <= (1.0 - PARALLEL_DEFECT) * diag[j]:
                continue
            tightness_i = b[i] / np.sqrt(diag[i])
            if tightness_i < tightness_j or (tightness_i == tightness_j and i < j):
                dropped[j] = True
                break
    return dropped


@njit(cache=True)
def without(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, b: np.ndarray,
            dropped: np.ndarray):
    """The LCP without the ``dropped`` contacts: Q's kept rows and columns, and b's entries.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays.
    b : np.ndarray
        The LCP's constant term.
    dropped : np.ndarray
        Boolean, n entries (:func:`looser_parallel`).

    Returns
    -------
    kept : np.ndarray
        The kept contacts, in their order (int64).
    indptr, indices, data : np.ndarray
        The smaller Q's CSC arrays, index arrays of the given dtype, rows in the same order
        within each column (so sorted indices stay sorted).
    b : np.ndarray
        Its constant term.
    """
    n = b.size
    new_index = np.full(n, -1, dtype=np.int64)
    kept = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if not dropped[i]:
            new_index[i] = m
            kept[m] = i
            m += 1
    kept = kept[:m]
    entries = 0
    for column in kept:
        for k in range(indptr[column], indptr[column + 1]):
            if new_index[indices[k]] >= 0:
                entries += 1
    small_indptr = np.empty(m + 1, dtype=indptr.dtype)
    small_indices = np.empty(entries, dtype=indices.dtype)
    small_data = np.empty(entries)
    small_b = np.empty(m)
    at = 0
    small_indptr[0] = 0
    for position in range(m):
        column = kept[position]
        for k in range(indptr[column], indptr[column + 1]):
            row = new_index[indices[k]]
            if row >= 0:
                small_indices[at] = row
                small_data[at] = data[k]
                at += 1
        small_indptr[position + 1] = at
        small_b[position] = b[column]
    return kept, small_indptr, small_indices, small_data, small_b
