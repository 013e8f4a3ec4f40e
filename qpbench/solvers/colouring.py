"""Greedy colouring of a contact graph, compiled (numba): the sweep order of the Gauss-Seidel
solvers written here (``pgs``, ``nsgs`` and the box QP of ``staggered``).

Two contacts conflict when the symmetric pattern given by its CSR (or CSC) arrays has an entry
between them (they share a body). Each contact in index order takes the smallest colour that
none of its neighbours holds, so contacts of one colour do not interact and updating a colour
at once is Gauss-Seidel in that order. Compiled once per process and cached beside this file
(``cache=True``); :func:`warm_up` loads it outside any clock.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

from qpbench.solvers.counting_sort import stable_order


@njit(cache=True)
def greedy_colours(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Colour of each contact: the smallest colour unused by its neighbours.

    The neighbours of a contact are the entries of its row; contacts are taken in index order.

    Parameters
    ----------
    indptr, indices : np.ndarray
        The CSR (or CSC) pattern of a symmetric n x n matrix.

    Returns
    -------
    np.ndarray
        The colours 0, 1, ..., shape (n,), int64.
    """
    n = indptr.size - 1
    colours = np.full(n, -1, dtype=np.int64)
    taken_by = np.full(n + 1, -1, dtype=np.int64)  # taken_by[c] = i: a neighbour of i holds c
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            neighbour_colour = colours[indices[k]]
            if neighbour_colour >= 0:
                taken_by[neighbour_colour] = i
        colour = 0
        while taken_by[colour] == i:
            colour += 1
        colours[i] = colour
    return colours


@njit(cache=True)
def colour_order(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """The contacts class by class of :func:`greedy_colours`, in index order within a class.

    That is ``np.argsort(colours, kind="stable")``, computed by :func:`stable_order`.

    Parameters
    ----------
    indptr, indices : np.ndarray
        The CSR (or CSC) pattern of a symmetric n x n matrix.

    Returns
    -------
    np.ndarray
        Every contact index once, shape (n,), int64.
    """
    return stable_order(greedy_colours(indptr, indices))


def colours_of(pattern: sp.spmatrix) -> np.ndarray:
    """:func:`greedy_colours` of a symmetric sparse matrix's pattern.

    Parameters
    ----------
    pattern : sp.spmatrix
        A symmetric n x n sparse matrix; its entries' values do not matter, only their places
        (a format other than CSR or CSC is converted to CSR).

    Returns
    -------
    np.ndarray
        The colour of each contact, shape (n,), int64.
    """
    compressed = pattern if sp.isspmatrix_csr(pattern) or sp.isspmatrix_csc(pattern) \
        else sp.csr_matrix(pattern)
    return greedy_colours(compressed.indptr, compressed.indices)


_warm = False


def warm_up() -> None:
    """Compiles (or loads from the cache) both functions once in this process, for SciPy's
    32-bit and 64-bit index arrays."""
    global _warm
    if _warm:
        return
    for dtype in (np.int32, np.int64):
        indptr, indices = np.array([0, 2, 4], dtype=dtype), np.array([0, 1, 0, 1], dtype=dtype)
        greedy_colours(indptr, indices)
        colour_order(indptr, indices)
    _warm = True
