"""The primal active-set method that ends a prox step where block pivoting stops improving.

One prox step of pi-robust is LCP(H, q) with ``H = Q + rho D`` positive definite, that is the
convex QP ``min x^T H x / 2 + q^T x`` subject to ``x >= 0``. :func:`_primal_active_set`
solves it by a primal active-set method (Lawson and Hanson, "Solving Least Squares
Problems", 1974, chapter 23; Nocedal and Wright, "Numerical Optimization", 2nd ed., 2006,
section 16.5), whose objective never rises, so that unlike block pivoting it cannot cycle.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import (
    COUPLED,
    UPDATE_FIXED,
    UPDATE_SPREAD,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.factor import _policy_solve
from qpbench.solvers.pi_robust_kernel.residual import matvec_into
from qpbench.solvers.pi_robust_kernel.structures import Csc, OrderedLcp, Work


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _objective(A: Csc, rho: float, safe_diag: np.ndarray, q: np.ndarray, x: np.ndarray,
               product: np.ndarray) -> float:
    """``x^T (Q + rho D) x / 2 + q^T x``, with Q x formed in ``product``."""
    matvec_into(A, x, product)
    total = 0.0
    for i in range(x.size):
        total += x[i] * (0.5 * (product[i] + rho * safe_diag[i] * x[i]) + q[i])
    return total


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _clipped_curvature(A: Csc, rho: float, safe_diag: np.ndarray, solution: np.ndarray,
                       listed: np.ndarray) -> float:
    """``d^T (Q + rho D) d / 2`` for ``d = max(-solution, 0)``, summed over the columns
    ``listed``: those where d > 0 (a few, the free contacts a policy solve sends below zero)."""
    indptr, indices, data = A
    total = 0.0
    for column in listed:
        clipped = -solution[column]
        inner = rho * safe_diag[column] * clipped
        for k in range(indptr[column], indptr[column + 1]):
            inner += data[k] * max(-solution[indices[k]], 0.0)
        total += clipped * inner
    return 0.5 * total


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _diagonal_spread(diag: np.ndarray) -> float:
    """``max D_i / min D_i`` over the contacts with D_i > 0 (1 when there are none)."""
    largest, smallest = 0.0, np.inf
    for value in diag:
        if value > 0.0:
            largest, smallest = max(largest, value), min(smallest, value)
    return largest / smallest if largest > 0.0 else 1.0


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _free_violators(A: Csc, safe_diag: np.ndarray, policy: np.ndarray, product: np.ndarray,
                    q: np.ndarray, tol_w: float, all_of_them: bool, listed: np.ndarray,
                    scaled: np.ndarray) -> bool:
    """Free the fixed contacts that violate ``(Q x + q)_i < -tol_w``, all or the worst one.

    Parameters
    ----------
    A : Csc
        Q's CSC arrays in the kernel's order.
    safe_diag : np.ndarray
        D with its zeros replaced by ones.
    policy : np.ndarray
        The free set (True: free); the chosen violators are set in place.
    product : np.ndarray
        ``Q x``, for an x that is zero on the fixed contacts.
    q : np.ndarray
        The prox step's constant term.
    tol_w : float
        The tolerance on a fixed contact's slack.
    all_of_them : bool
        Free every violator not coupled to one freed before it; else only the first.
    listed, scaled : np.ndarray
        Work arrays of n entries (overwritten): the violators, sorted, and their scaled slacks.

    Returns
    -------
    bool
        Whether any contact violated.

    Notes
    -----
    The violators are ordered by their scaled slack ``(Q x + q)_i / sqrt(D_i)``, most negative
    first. A violator j coupled to one freed before it, ``Q_ij > COUPLED sqrt(D_i D_j)``, waits:
    freeing i raises j's slack by ``Q_ji x_i``, so j's violation is in part what i will carry.
    Freeing every violator overshoots on nearly singular blocks, where most of them are fixed
    again one or two per solve afterwards.
    """
    indptr, indices, data = A
    count = 0
    for i in range(q.size):  # (written, then kept only when violating: no branch)
        listed[count] = i
        count += (product[i] + q[i] < -tol_w) & ~policy[i]
    for c in range(count):
        violator = listed[c]
        scaled[violator] = (product[violator] + q[violator]) / np.sqrt(safe_diag[violator])
    for c in range(1, count):  # most negative first (an insertion sort: a few violators)
        violator, place = listed[c], c
        while place > 0 and scaled[listed[place - 1]] > scaled[violator]:
            listed[place] = listed[place - 1]
            place -= 1
        listed[place] = violator
    if count and not all_of_them:
        policy[listed[0]] = True
        return True
    for c in range(count):
        chosen = listed[c]
        if scaled[chosen] < 0.0:  # (0: coupled to one freed before it)
            policy[chosen] = True
            for k in range(indptr[chosen], indptr[chosen + 1]):
                coupled = indices[k]
                if scaled[coupled] < 0.0 and \
                        data[k] > COUPLED * np.sqrt(safe_diag[chosen] * safe_diag[coupled]):
                    scaled[coupled] = 0.0
    return count > 0


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _primal_active_set(lcp: OrderedLcp, policy: np.ndarray, rho: float, q: np.ndarray,
                       tol_l: np.ndarray, tol_w: float, budget: int, work: Work):
    """Solve LCP(H, q), ``H = Q + rho D``, by a primal active-set method on its QP.

    The LCP of the positive definite H is the convex QP ``min f(x) = x^T H x / 2 + q^T x``
    subject to ``x >= 0``.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    policy : np.ndarray
        The free set F of the starting point (True: free); changed in place.
    rho : float
        The prox weight.
    q : np.ndarray
        The prox step's constant term.
    tol_l : np.ndarray
        Per contact, how far below zero a free contact's value may be and count as zero.
    tol_w : float
        How far below zero a fixed contact's slack may be.
    budget : int
        The most linear solves to make.
    work : Work
        ``work.feasible`` holds the feasible starting point (changed in place); the answer is
        left in ``work.x``.

    Returns
    -------
    solves : int
        The linear solves made.
    solved : bool
        Whether x solves the LCP (to the tolerances).

    Notes
    -----
    Each step solves ``H_FF s_F = -q_F`` (:func:`.factor._policy_solve`), then:

    - some free ``s_i < -tol_l[i]``: x becomes ``max(s, 0)`` with those contacts fixed, when that
      lowers f (several at once); else x moves towards s until the first of them reaches zero,
      and the free contacts at zero with ``s_i < 0`` are fixed;
    - else ``x = max(s, 0)``, and the fixed contacts with ``(H x + q)_i < -tol_w`` are freed: all
      but those coupled to one freed before them (:func:`_free_violators`) when f has fallen
      since contacts were last freed, else the one with the most negative
      ``(H x + q)_i / sqrt(D_i)``; when there are none, x is the solution.

    f never rises, and every step that frees contacts starts lower than the one before or frees
    a single contact as Lawson and Hanson's method does, so unlike block pivoting the method
    cannot cycle. f needs no product with Q where a step fixes contacts: s minimizes f on the
    free set and every point is zero off it, so ``f(x) = f(s) + (x - s)^T H (x - s) / 2`` with
    ``f(s) = q^T s / 2``; hence ``f(max(s, 0)) = f(s) + d^T H d / 2`` for ``d = max(-s, 0)``
    (a few entries, :func:`_clipped_curvature`), and on the segment towards s
    ``f(x + t (s - x)) = f(s) + (1 - t)^2 (f(x) - f(s))``. A step's passes run over F alone,
    since s and x are zero off it.

    The next solve after a step that fixed at most ``UPDATE_FIXED`` contacts deletes their rows
    from the factor just used (:func:`.factor._block_solve_fixing`) when the problem's D_i span at
    most ``UPDATE_SPREAD``; wider spreads make the updated factor round differently enough to
    change the method's pivots.

    References
    ----------
    C. L. Lawson and R. J. Hanson, "Solving Least Squares Problems", Prentice-Hall, 1974,
    chapter 23. J. Nocedal and S. J. Wright, "Numerical Optimization", 2nd ed., Springer, 2006,
    section 16.5.
    """
    A, safe_diag = lcp.A, lcp.safe_diag
    solution, y, feasible = work.x, work.product, work.feasible
    free, listed = work.free, work.listed
    n = q.size
    value_now = _objective(A, rho, safe_diag, q, feasible, y)
    value_at_last_freeing = np.inf
    solves = 0
    solved = False
    updates = _diagonal_spread(lcp.diag) <= UPDATE_SPREAD
    fixed = 0  # contacts the last step fixed, their places in its block in listed[:fixed]
    while solves < budget:
        # F = free[:size]; the rows of the contacts the last step fixed deleted, or refactored
        size = _policy_solve(lcp, policy, rho, q, work,
                             listed[:fixed if fixed <= UPDATE_FIXED and updates else 0])
        fixed = 0
        solves += 1
        # one pass over F (s and x are zero off it): the first free contact that s sends below
        # zero, f(s), and the free contacts with s_i < 0 listed
        step, blocking = 1.0, -1
        at_minimum = 0.0
        count = 0
        for a in range(size):
            i = free[a]
            at_minimum += q[i] * solution[i]
            if solution[i] < -tol_l[i]:
                reach = feasible[i] / (feasible[i] - solution[i])
                if reach < step:
                    step, blocking = reach, i
            listed[count] = i  # (written, then kept only when s_i < 0: no branch)
            count += solution[i] < 0.0
        if blocking >= 0:
            at_minimum *= 0.5
            value = at_minimum + _clipped_curvature(A, rho, safe_diag, solution,
                                                    listed[:count])
            if value < value_now:
                value_now = value
                for a in range(size):
                    i = free[a]
                    feasible[i] = max(solution[i], 0.0)
                    policy[i] = solution[i] > 0.0
                    listed[fixed] = a  # (written, then kept only when fixed)
                    fixed += not policy[i]
                continue
            feasible[blocking] = 0.0  # (then the step below leaves it at zero: fixed)
            for a in range(size):
                i = free[a]
                feasible[i] = max(feasible[i] + step * (solution[i] - feasible[i]), 0.0)
                if solution[i] < 0.0 and feasible[i] == 0.0:
                    policy[i] = False
                    listed[fixed] = a
                    fixed += 1
            value_now = at_minimum + (1.0 - step) ** 2 * (value_now - at_minimum)
            continue
        for a in range(size):
            i = free[a]
            feasible[i] = max(solution[i], 0.0)
        value_now = _objective(A, rho, safe_diag, q, feasible, y)  # y = Q x
        all_of_them = value_now < value_at_last_freeing
        value_at_last_freeing = value_now
        if not _free_violators(A, safe_diag, policy, y, q, tol_w, all_of_them, listed,
                               work.rhs):
            solved = True
            break
    for i in range(n):
        solution[i] = feasible[i]
    return solves, solved

