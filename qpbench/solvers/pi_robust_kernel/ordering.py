"""The contacts' order, the permuted matrix, its upper triangle and its envelope.

An envelope (skyline, profile) factor of a symmetric matrix stores row i from its first
nonzero column ``first(i)`` to the diagonal, and Cholesky creates no fill outside that
envelope (George and Liu, "Computer Solution of Large Sparse Positive Definite Systems",
Prentice-Hall 1981, chapter 4). One factorization then costs ``sum_i w_i^2 / 2``
multiply-adds, ``w_i = i - first(i) + 1`` (:func:`_envelope_work`). Q's graph is the line
graph of the contact graph, and a reverse Cuthill-McKee order (:func:`reverse_cuthill_mckee`)
keeps every block's envelope narrow on grids and packings; the entry module decides whether
to reorder (``constants.WIDE_ENVELOPE``, ``constants.WIDE_ENVELOPE_WORK``).

The factors read the lower triangle row by row, which is Q's upper triangle column by column
(:func:`_upper`); SciPy's own CSC arrays serve as that triangle when their row indices rise
(:func:`_leading_upper`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.counting_sort import stable_order
from qpbench.solvers.pi_robust_kernel.constants import WITHOUT_REFCOUNTS
from qpbench.solvers.pi_robust_kernel.structures import Csc, Upper


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _envelope_widths(A: Csc, offsets: np.ndarray) -> None:
    """Row offsets of the lower envelope of the whole symmetric Q: row c starts at the
    smallest row index of column c."""
    indptr, indices, _ = A
    offsets[0] = 0
    for column in range(indptr.size - 1):
        row_first = column
        for k in range(indptr[column], indptr[column + 1]):
            row_first = min(row_first, indices[k])
        offsets[column + 1] = offsets[column] + column - row_first + 1


@njit(cache=True)
def _upper(A: Csc) -> Upper:
    """The upper triangle of the symmetric Q (its entries Q_rc with r <= c), copied: column c
    holds row c of the lower triangle, all that an envelope row reads. Once per solve,
    O(nnz(Q)); it halves what every block's pattern and fill visit."""
    n = A[0].size - 1
    starts, rows, values = (np.empty(n + 1, dtype=np.int64), np.empty(A[1].size, dtype=np.int64),
                            np.empty(A[1].size))
    _upper_into(A, (starts, rows, values))
    return starts, starts[1:], rows, values


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _upper_into(A: Csc, upper: Csc) -> None:
    """:func:`_upper`'s copy into ``upper``'s arrays (n + 1 starts, as many rows and values as
    Q has entries; those past the upper triangle's are left as they are)."""
    indptr, indices, data = A
    starts, rows, values = upper
    n = indptr.size - 1
    starts[0] = 0
    end = 0
    for column in range(n):
        for k in range(indptr[column], indptr[column + 1]):
            # written, then kept only when in the upper triangle (end <= k): no branch on it
            rows[end], values[end] = indices[k], data[k]
            end += indices[k] <= column
        starts[column + 1] = end


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _leading_upper(A: Csc, ends: np.ndarray) -> bool:
    """Whether Q's own CSC arrays can serve as its upper triangle, and where each column's ends.

    True when every column's rows rise (SciPy's sorted indices); then ``ends[c]`` is one past
    column c's last entry with row <= c, so that the leading entries of each column are the
    upper triangle's column and :func:`_upper` needs no copy.
    """
    indptr, indices, _ = A
    for column in range(indptr.size - 1):
        end = indptr[column]
        previous = -1
        for k in range(indptr[column], indptr[column + 1]):
            if indices[k] <= previous:
                return False
            previous = indices[k]
            end += indices[k] <= column
        ends[column] = end
    return True


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _envelope_work(offsets: np.ndarray) -> float:
    """Multiply-adds of one envelope factorization, ``sum_i w_i^2 / 2`` over the row widths
    ``w_i = offsets[i + 1] - offsets[i]``."""
    work = 0.0
    for i in range(offsets.size - 1):
        work += 0.5 * float(offsets[i + 1] - offsets[i]) ** 2
    return work


@njit(cache=True)
def reverse_cuthill_mckee(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """A reverse Cuthill-McKee order of the graph of a symmetric CSC pattern.

    Parameters
    ----------
    indptr, indices : np.ndarray
        The pattern's CSC arrays.
    n : int
        The nodes (columns).

    Returns
    -------
    np.ndarray
        The order: position k holds the node placed k-th.

    Notes
    -----
    Breadth-first from a least-degree node of each component (the seeds in a stable order by
    degree, :func:`~qpbench.solvers.counting_sort.stable_order`), each node's unvisited
    neighbours by rising degree, the whole order reversed, which keeps the envelope at most as
    wide as the forward order's (George and Liu 1981, section 4.3).

    References
    ----------
    E. Cuthill and J. McKee, "Reducing the bandwidth of sparse symmetric matrices", Proc. 24th
    ACM National Conference, 1969. A. George, "Computer implementation of the finite element
    method", PhD thesis, Stanford, 1971. A. George and J. W. H. Liu, "Computer Solution of
    Large Sparse Positive Definite Systems", Prentice-Hall, 1981.
    """
    degree = indptr[1:] - indptr[:-1]
    order = np.empty(n, dtype=np.int64)
    visited = np.zeros(n, dtype=np.bool_)
    head = tail = 0
    for seed in stable_order(degree):
        if visited[seed]:
            continue
        visited[seed] = True
        order[tail] = seed
        tail += 1
        while head < tail:
            node = order[head]
            head += 1
            begin = tail
            for k in range(indptr[node], indptr[node + 1]):
                neighbour = indices[k]
                if not visited[neighbour]:
                    visited[neighbour] = True
                    order[tail] = neighbour
                    tail += 1
            for i in range(begin + 1, tail):  # insertion sort by degree (few neighbours)
                moving = order[i]
                j = i - 1
                while j >= begin and degree[order[j]] > degree[moving]:
                    order[j + 1] = order[j]
                    j -= 1
                order[j + 1] = moving
    return order[::-1].copy()


@njit(cache=True)
def _permuted(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, order: np.ndarray,
              widths: np.ndarray, upper: Csc):
    """Permute Q to ``Q[order][:, order]``, with its upper triangle and envelope, in one pass.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays as posed.
    order : np.ndarray
        The new order (:func:`reverse_cuthill_mckee`).
    widths : np.ndarray
        Receives the envelope's row offsets, as :func:`_envelope_widths` forms them (column c's
        smallest row is where row c starts; every column holds its diagonal).
    upper : Csc
        Receives the permuted matrix's upper triangle ``(starts, rows, values)``, as
        :func:`_upper_into` copies it.

    Returns
    -------
    Csc
        The permuted matrix's CSC arrays (row indices within a column left unsorted).
    """
    n = order.size
    starts, rows, values = upper
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = np.arange(n)
    new_indptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        new_indptr[j + 1] = new_indptr[j] + indptr[order[j] + 1] - indptr[order[j]]
    new_indices = np.empty(new_indptr[n], dtype=np.int64)
    new_data = np.empty(new_indptr[n])
    starts[0] = widths[0] = 0
    end = 0
    for j in range(n):
        position = new_indptr[j]
        row_first = j
        for k in range(indptr[order[j]], indptr[order[j] + 1]):
            row = inverse[indices[k]]
            new_indices[position] = row
            new_data[position] = data[k]
            position += 1
            # written, then kept only when in the upper triangle (row <= j): no branch on it
            rows[end], values[end] = row, data[k]
            end += row <= j
            row_first = min(row_first, row)
        starts[j + 1] = end
        widths[j + 1] = widths[j] + j - row_first + 1
    return new_indptr, new_indices, new_data

