"""Block principal pivoting on a dense copy of Q: the kernel's compact path for a few contacts.

On a problem of a few contacts the arithmetic of a solve is a few hundred multiply-adds, and
what a solve costs is mostly the code and data the core has to bring back into its caches
when other work ran in between (docs/notes/pi-robust.md). The general path (ordering,
envelope factors, prox steps, the active-set method) touches much of the kernel even when one
block solve ends it. :func:`dense_pivoting` touches little: Q copied into a dense array, then
LCP(Q, b) itself, without a prox term, by block principal pivoting with Murty's single
principal pivot as backup (Judice and Pires, "A block principal pivoting algorithm for
large-scale strictly monotone linear complementarity problems", Comput. Oper. Res. 21(5),
1994; Murty, "Note on a Bard-type scheme for solving the complementarity problem", Opsearch
11, 1974), each block by a dense Cholesky factor. Q_FF may be singular (contacts that are
combinations of others): a contact whose pivot shows it dependent on the free contacts before
it is held at zero, so the block is solved on its independent contacts. The pivoting
converges for a P-matrix; on a singular Q it is not guaranteed to, so it gives up after a
budget of solves, and the caller's general path then runs. Whatever it returns, the caller
accepts only on qpbench's residual.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import (
    DENSE_DEPENDENT_PIVOT,
    REDUCTIONS,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.structures import Csc

# exchanges of every infeasible contact allowed without a fall in their number, before a
# single exchange (Judice and Pires's backup rule)
CHANCES = 3


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _factor_block(dense: np.ndarray, rows: np.ndarray, size: int, factor: np.ndarray) -> None:
    """The lower Cholesky factor of ``Q[rows, rows]`` (``rows[:size]``) into ``factor``.

    Row by row (a row's entries from the rows before it, then its pivot). A row whose pivot
    ``L_aa^2`` is below ``DENSE_DEPENDENT_PIVOT`` times its diagonal is dependent on the rows
    before it: its ``L_aa`` is set to 0, and later rows take no entry in its column, so the
    factor is that of the block without the dependent rows (their unknowns held at zero by
    :func:`_solve_block`).
    """
    for a in range(size):
        row = rows[a]
        for c in range(a):
            if factor[c, c] == 0.0:
                factor[a, c] = 0.0
                continue
            total = dense[row, rows[c]]
            for k in range(c):
                total -= factor[a, k] * factor[c, k]
            factor[a, c] = total / factor[c, c]
        pivot = dense[row, row]
        for k in range(a):
            pivot -= factor[a, k] * factor[a, k]
        factor[a, a] = np.sqrt(pivot) if pivot > DENSE_DEPENDENT_PIVOT * dense[row, row] else 0.0


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _solve_block(factor: np.ndarray, rows: np.ndarray, size: int, b: np.ndarray,
                 solution: np.ndarray, impulses: np.ndarray) -> None:
    """``impulses`` zero but on ``rows[:size]``, where they solve ``Q_FF l_F = -b_F`` by
    ``factor`` (dependent rows held at zero); ``solution`` is overwritten."""
    for a in range(size):
        if factor[a, a] == 0.0:
            solution[a] = 0.0
            continue
        total = -b[rows[a]]
        for k in range(a):
            total -= factor[a, k] * solution[k]
        solution[a] = total / factor[a, a]
    for a in range(size - 1, -1, -1):
        if factor[a, a] == 0.0:
            continue
        total = solution[a]
        for k in range(a + 1, size):
            total -= factor[k, a] * solution[k]
        solution[a] = total / factor[a, a]
    impulses[:] = 0.0
    for a in range(size):
        impulses[rows[a]] = solution[a]


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _mark_infeasible(dense: np.ndarray, b: np.ndarray, impulses: np.ndarray, slack: float,
                     infeasible: np.ndarray) -> int:
    """Mark in ``infeasible`` the contacts with ``l_i < 0`` and those at zero (fixed, or held
    at zero as dependent) with ``(Q l + b)_i < -slack``; return how many. A NaN counts as
    infeasible (the comparisons are written so), so that no NaN answer is ever found."""
    count = 0
    for i in range(b.size):
        bad = not impulses[i] >= 0.0
        if not bad and impulses[i] == 0.0:
            w = b[i]
            for k in range(b.size):
                w += dense[i, k] * impulses[k]
            bad = not w >= -slack
        infeasible[i] = bad
        count += bad
    return count


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _pivot(dense: np.ndarray, b: np.ndarray, free: np.ndarray, impulses: np.ndarray,
           factor: np.ndarray, solution: np.ndarray, rows: np.ndarray,
           infeasible: np.ndarray, slack: float, budget: int) -> int:
    """Block principal pivoting from the policy ``free``; the solves it took, negated when it
    gave up (budget spent) without a feasible policy. ``impulses`` holds the last solve."""
    fewest, chances = b.size + 1, CHANCES
    for solves in range(1, budget + 1):
        size = 0
        for i in range(b.size):
            if free[i]:
                rows[size] = i
                size += 1
        _factor_block(dense, rows, size, factor)
        _solve_block(factor, rows, size, b, solution, impulses)
        count = _mark_infeasible(dense, b, impulses, slack, infeasible)
        if count == 0:
            return solves
        if count < fewest:
            fewest, chances = count, CHANCES
        elif chances > 0:
            chances -= 1
        else:  # Murty's backup: exchange only the infeasible contact of largest index
            last = b.size - 1
            while not infeasible[last]:
                last -= 1
            free[last] = not free[last]
            continue
        for i in range(b.size):
            if infeasible[i]:
                free[i] = not free[i]
    return -budget


@njit(cache=True)
def dense_pivoting(A: Csc, b: np.ndarray, start: np.ndarray, slack: float, budget: int):
    """Solve LCP(Q, b) by block principal pivoting on a dense copy of Q.

    Parameters
    ----------
    A : Csc
        Q's CSC arrays as posed.
    b : np.ndarray
        The LCP's constant term.
    start : np.ndarray
        The start; its positive entries are the first free set.
    slack : float
        How far below zero ``(Q l + b)_i`` of a contact at zero may be and still count as
        feasible (rounding on dependent contacts).
    budget : int
        The most block solves.

    Returns
    -------
    impulses : np.ndarray
        A new array: the policy's l where a feasible policy was found, else the last solve's.
    solves : int
        The block solves (each one factorization).
    found : bool
        Whether a feasible policy was found: every free l_i >= 0, every other w_i >= -slack.
    """
    indptr, indices, data = A
    n = b.size
    reals = np.zeros(n * (2 * n + 1))
    dense = reals[:n * n].reshape((n, n))
    factor = reals[n * n:2 * n * n].reshape((n, n))
    solution = reals[2 * n * n:]
    impulses = np.zeros(n)  # (returned: an array of its own)
    for column in range(n):
        for k in range(indptr[column], indptr[column + 1]):
            dense[indices[k], column] = data[k]
    flags = np.empty(2 * n, dtype=np.bool_)
    free, infeasible = flags[:n], flags[n:]
    for i in range(n):
        free[i] = start[i] > 0.0
    rows = np.empty(n, dtype=np.int64)
    solves = _pivot(dense, b, free, impulses, factor, solution, rows, infeasible, slack, budget)
    return impulses, abs(solves), solves > 0
