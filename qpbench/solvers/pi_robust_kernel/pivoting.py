"""Block principal pivoting on one prox step, handing over to the active-set method.

Each prox step of pi-robust solves LCP(Q + rho D, q). :func:`_inner_lcp` does so by block
principal pivoting with a backup rule (Judice and Pires, "A block principal pivoting
algorithm for large-scale strictly monotone linear complementarity problems", Comput. Oper.
Res. 21(5), 1994; Kim and Park, "Fast nonnegative matrix factorization: an active-set-like
method and comparisons", SIAM J. Sci. Comput. 33(6), 2011): every infeasible contact is
exchanged while their number falls, and when it stops falling (or the block is nearly
singular) the primal active-set method of :mod:`.active_set` finishes the step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.active_set import _primal_active_set
from qpbench.solvers.pi_robust_kernel.constants import DEPENDENT_CONTACTS, WITHOUT_REFCOUNTS
from qpbench.solvers.pi_robust_kernel.factor import _policy_solve
from qpbench.solvers.pi_robust_kernel.residual import matvec_into
from qpbench.solvers.pi_robust_kernel.structures import Csc, OrderedLcp, Prox, Work


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _fixed_slacks_negative(A: Csc, policy: np.ndarray, x: np.ndarray, q: np.ndarray,
                           tol_w: float, free_count: int, infeasible: np.ndarray,
                           product: np.ndarray) -> None:
    """``infeasible[i]`` for every fixed contact i (not ``policy[i]``): ``(Q x + q)_i < -tol_w``
    for an x that is zero on the fixed contacts (so rho D x adds nothing there). Formed by
    whichever visits fewer columns of Q: scattering the free columns into ``product``
    (x is zero elsewhere), or gathering column i (Q is symmetric) for each fixed i."""
    indptr, indices, data = A
    n = q.size
    if 2 * free_count <= n:
        matvec_into(A, x, product)
        for i in range(n):
            if not policy[i]:
                infeasible[i] = product[i] + q[i] < -tol_w
        return
    for i in range(n):
        if not policy[i]:
            total = q[i]
            for k in range(indptr[i], indptr[i + 1]):
                total += data[k] * x[indices[k]]
            infeasible[i] = total < -tol_w


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _inner_lcp(lcp: OrderedLcp, policy: np.ndarray, rho: float, q: np.ndarray,
               tol_l: np.ndarray, tol_w: float, prox: Prox, budget: int, work: Work):
    """Solve one prox step's LCP(Q + rho D, q) by block principal pivoting.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    policy : np.ndarray
        The starting free set (True: free); the final policy is left in it.
    rho : float
        The prox weight.
    q : np.ndarray
        The prox step's constant term, ``b - rho D z``.
    tol_l : np.ndarray
        Per contact, how far below zero a free contact's value may be.
    tol_w : float
        How far below zero a fixed contact's slack may be.
    prox : Prox
        The safeguards: ``backup_steps``, ``active_set``.
    budget : int
        The most linear solves to make.
    work : Work
        The solve's work arrays; x is left in ``work.x``.

    Returns
    -------
    solves : int
        The linear solves made.
    solved : bool
        Whether x solves the LCP (to the tolerances).

    Notes
    -----
    Each step solves the policy's block (:func:`.factor._policy_solve`). Contact i is
    infeasible when it is free with ``x_i < -tol_l[i]`` or fixed with
    ``y_i = (Q x + rho D x + q)_i < -tol_w``; every infeasible contact is exchanged (freed or
    fixed) while their number falls, and at most ``prox.backup_steps`` exchanges in a row that
    do not cut it are allowed. Then :func:`.active_set._primal_active_set` goes on from the
    best exchange's x (``prox.active_set``), or the step stops unsolved.

    Nearly singular blocks: when the block just solved has at least ``DEPENDENT_CONTACTS``
    dependent contacts and most of the infeasible contacts are negative free ones, the iterate
    swings between large sets fixed and freed, so the active-set method goes on at once
    (``prox.active_set``); without it, only the negative free contacts are exchanged (they are
    fixed first).

    References
    ----------
    J. J. Judice and F. M. Pires, "A block principal pivoting algorithm for large-scale strictly
    monotone linear complementarity problems", Comput. Oper. Res. 21(5), 1994. J. Kim and
    H. Park, "Fast nonnegative matrix factorization: an active-set-like method and comparisons",
    SIAM J. Sci. Comput. 33(6), 2011.
    """
    A = lcp.A
    backup_steps, active_set = prox.backup_steps, prox.active_set
    x, infeasible = work.x, work.infeasible
    n = q.size
    best = n + 1
    backup = backup_steps
    solves = 0
    x[:] = 0.0
    while solves < budget:
        free_count = _policy_solve(lcp, policy, rho, q, work, work.listed[:0])
        solves += 1
        _fixed_slacks_negative(A, policy, x, q, tol_w, free_count, infeasible, work.product)
        count = 0
        negative = 0
        for i in range(n):
            if policy[i]:
                infeasible[i] = x[i] < -tol_l[i]
                negative += infeasible[i]
            count += infeasible[i]
        if count == 0:
            return solves, True
        singular = work.cache.counters[2] >= DEPENDENT_CONTACTS and \
            count < 2 * negative < 2 * count
        improved = count < best
        if improved:
            best, backup = count, backup_steps
            for i in range(n):
                work.best_x[i] = x[i]
        if not (active_set and singular) and (improved or backup > 0):
            if not improved:
                backup -= 1
            if singular:
                for i in range(n):  # fix first: only the negative free contacts are exchanged
                    infeasible[i] &= policy[i]
            for i in range(n):
                policy[i] ^= infeasible[i]
        elif active_set:
            feasible = work.feasible
            for i in range(n):
                feasible[i] = max(work.best_x[i], 0.0)
                policy[i] = feasible[i] > 0.0
            used, solved = _primal_active_set(lcp, policy, rho, q, tol_l, tol_w,
                                              budget - solves, work)
            return solves + used, solved
        else:
            break
    return solves, False

