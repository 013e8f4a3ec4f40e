"""Proximal policy iteration: prox steps, drift extrapolation, polish and finish.

Policy iteration is Newton's method on ``min(D l, Q l + b) = 0`` (Bertsekas, "Abstract
Dynamic Programming", 2018, and the policy-iteration report this project grew from); with Q
singular its policy systems are singular and it cycles. The proximal point method
(Rockafellar, "Monotone operators and the proximal point algorithm", SIAM J. Control Optim.
14(5), 1976) replaces the LCP by a sequence of prox steps around a centre z, each the LCP

    w = (Q + rho D) x + b - rho D z >= 0,   x >= 0,   x^T w = 0,

whose matrix is positive definite; the centre then moves to ``max(x, 0)``. Each prox step is
solved by :func:`.pivoting._inner_lcp`. rho falls when the residual stalls, and a settled
policy whose steps drift along the null space of Q_FF is followed to where that drift ends
(:func:`_extrapolate_drift`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import (
    DRIFT_RATIO,
    PROX_BUDGET,
    PROX_CONVERGED,
    PROX_STALLED,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.pivoting import _inner_lcp
from qpbench.solvers.pi_robust_kernel.residual import _original_residual
from qpbench.solvers.pi_robust_kernel.structures import OrderedLcp, Prox, Work


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _extrapolate_drift(centre: np.ndarray, drift: np.ndarray, previous_drift: np.ndarray,
                       policy: np.ndarray) -> bool:
    """Move the prox centre along a settled prox step's drift, when it is a drift.

    Parameters
    ----------
    centre : np.ndarray
        The prox centre z after the step; moved in place.
    drift : np.ndarray
        The step's change ``d = x - z_before`` (the step kept its policy F).
    previous_drift : np.ndarray
        The change d' of the step before.
    policy : np.ndarray
        F (True: free).

    Returns
    -------
    bool
        Whether the centre moved.

    Notes
    -----
    On a settled policy a prox step is ``x = (Q_FF + rho D_F)^-1 (rho D_F z - b_F)``. When
    ``Q_FF l_F = -b_F`` has no solution (the policy is wrong and Q_FF singular, as on grids where
    contacts outnumber the degrees of freedom), each step moves l along the null space of Q_FF
    by the same ``D_F^-1 r / rho``, r the part of -b_F outside the range of Q_FF, while the
    residual (about |r|) hardly falls, until a free contact reaches zero and the policy changes.
    This takes those steps at once. It moves when the ratio
    ``g = d_F . d'_F / d'_F . d'_F`` is at least ``DRIFT_RATIO`` (a drift keeps its length):
    ``z_F <- max(z_F + t d_F, 0)`` with t the step to the first free contact that reaches zero,
    ``t = min {z_i / -d_i : i in F, d_i < 0, z_i > 0}`` (that contact set to exactly 0), or the
    geometric series' ``g / (1 - g)`` steps when that is smaller. A step that contracts (g
    below 1: an ill-conditioned but consistent block, as on large mass ratios) is left to the
    prox steps and the fall of rho.
    """
    along, before = 0.0, 0.0
    for i in range(centre.size):
        if policy[i]:
            along += drift[i] * previous_drift[i]
            before += previous_drift[i] * previous_drift[i]
    if not along >= DRIFT_RATIO * before or before == 0.0:
        return False
    step, blocking = along / (before - along) if along < before else np.inf, -1
    for i in range(centre.size):
        if policy[i] and drift[i] < 0.0 and centre[i] > 0.0:
            reach = centre[i] / -drift[i]
            if reach < step:
                step, blocking = reach, i
    if step == np.inf:
        return False
    for i in range(centre.size):
        if policy[i]:
            centre[i] = np.maximum(centre[i] + step * drift[i], 0.0)
    if blocking >= 0:
        centre[blocking] = 0.0
    return True


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _prox_policy_iteration(lcp: OrderedLcp, start: np.ndarray, start_residual: float,
                           policy: np.ndarray, tol: float, rho: float, prox: Prox,
                           budget: int, work: Work, best: np.ndarray):
    """Run proximal policy iteration from a centre and a policy, within a budget of solves.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    start : np.ndarray
        The first centre z (l >= 0).
    start_residual : float
        qpbench's residual of ``start``, computed by the caller.
    policy : np.ndarray
        The first policy (True: free); changed in place.
    tol : float
        Converged when qpbench's residual is at most tol.
    rho : float
        The first prox weight.
    prox : Prox
        The safeguards.
    budget : int
        The most linear solves to make.
    work : Work
        The solve's work arrays.
    best : np.ndarray
        Receives the l of least residual (an array other than ``start``).

    Returns
    -------
    converged : bool
        Whether ``best`` meets tol.
    status : int
        ``PROX_CONVERGED``, ``PROX_BUDGET`` or ``PROX_STALLED``.
    solves : int
        The linear solves made.
    best_residual : float
        qpbench's residual of ``best``.

    Notes
    -----
    Each prox step solves LCP(Q + rho D, b - rho D z) (:func:`.pivoting._inner_lcp`) and moves
    the centre to ``z <- max(x, 0)``. rho falls by ``prox.rho_decrease`` (not below
    ``prox.rho_min``: then the run has stalled) after ``prox.stall_steps`` steps in a row that
    do not cut the residual by ``prox.stall_ratio``; a settled step (one solve, its policy kept)
    that does not cut it moves the centre along its drift instead (:func:`_extrapolate_drift`,
    at most ``prox.drift_steps`` times a run). A step that the inner LCP cannot solve ends the
    run.

    References
    ----------
    R. T. Rockafellar, "Monotone operators and the proximal point algorithm", SIAM J. Control
    Optim. 14(5), 1976. D. P. Bertsekas, "Abstract Dynamic Programming", 2nd ed., Athena
    Scientific, 2018 (policy iteration as Newton's method).
    """
    original, b, safe_diag, scale = lcp.original, lcp.b, lcp.safe_diag, lcp.scale
    centre, q, x, tol_l = work.centre, work.q, work.x, work.tol_l
    drift, previous_drift = work.drift, work.previous_drift
    n = b.size
    for i in range(n):
        tol_l[i] = 0.1 * tol * scale / safe_diag[i]
        centre[i] = start[i]
        best[i] = start[i]
        drift[i] = 0.0  # (no step before the first)
    tol_w = 0.1 * tol * scale
    res = start_residual
    best_res = res
    solves = 0
    stalls = 0
    drifts = 0
    status = PROX_BUDGET
    while solves < budget:
        for i in range(n):
            q[i] = b[i] - rho * safe_diag[i] * centre[i]
        used, solved = _inner_lcp(lcp, policy, rho, q, tol_l, tol_w, prox, budget - solves,
                                  work)
        solves += used
        settled = used == 1 and drifts < prox.drift_steps  # the step kept its policy
        drift, previous_drift = previous_drift, drift  # (swapped, not copied)
        for i in range(n):
            drift[i] = x[i] - centre[i]
            centre[i] = np.maximum(x[i], 0.0)
        previous = res
        res = _original_residual(original, scale, centre, work.product, work.unpermuted)
        if res < best_res or res <= tol:
            for i in range(n):
                best[i] = centre[i]
            best_res = min(res, best_res)
        if res <= tol:
            return True, PROX_CONVERGED, solves, res
        if not solved:
            break
        stalls = stalls + 1 if res > prox.stall_ratio * previous else 0
        if settled and stalls > 0 and _extrapolate_drift(centre, drift, previous_drift, policy):
            drifts += 1
            stalls = 0
            continue
        if stalls >= prox.stall_steps:
            stalls = 0
            if rho * prox.rho_decrease < prox.rho_min:
                status = PROX_STALLED
                break
            rho *= prox.rho_decrease
    return False, status, solves, best_res


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _policy_from(lcp: OrderedLcp, impulses: np.ndarray, posed_product: np.ndarray,
                 policy: np.ndarray, strict: bool) -> None:
    """``policy``: the contacts with ``(Q l + b)_i < D_i l_i`` (``<=`` unless ``strict``), l in
    the kernel's order, from the ``Q l`` that its residual formed on the problem as posed
    (``posed_product``, in the posed order): no product of its own."""
    order, b, diag = lcp.original.order, lcp.b, lcp.diag
    for i in range(impulses.size):
        w = (posed_product[order[i]] if order.size else posed_product[i]) + b[i]
        policy[i] = w < diag[i] * impulses[i] if strict else w <= diag[i] * impulses[i]


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _polish(lcp: OrderedLcp, impulses: np.ndarray, residual: float, tol: float, rho: float,
            work: Work, polished: np.ndarray, policy: np.ndarray):
    """Give a converged l one more prox step on its own policy, for a margin below tol.

    A prox step ends at a residual of about ``rho |D (l - z)|``, about tol when rho = tol. An
    answer whose ``residual`` is above tol / 10 gets one more prox step on its policy
    ``{i : (Q l + b)_i < D_i l_i}`` (usually on the kept factor: two triangular solves), so that
    the caller can certify it without a second residual pass.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    impulses : np.ndarray
        The converged l.
    residual : float
        Its residual; ``work.product`` must hold its ``Q l`` (as
        :func:`_prox_policy_iteration` leaves it when it converges).
    tol, rho : float
        The tolerance and the prox weight.
    work : Work
        The solve's work arrays.
    polished : np.ndarray
        Receives the polished l.
    policy : np.ndarray
        Work array of n flags (overwritten).

    Returns
    -------
    moved : bool
        Whether a step was made: the answer is then ``polished`` (l itself unless the step
        lowered the residual); else it is l.
    residual : float
        The answer's residual.
    solves : int
        The linear solves made.
    """
    if residual <= 0.1 * tol:
        return False, residual, 0
    _policy_from(lcp, impulses, work.product, policy, True)
    one_step = Prox(rho, 1.0, 0.5, 1, 0, False, 0)
    _, _, used, polished_residual = _prox_policy_iteration(
        lcp, impulses, residual, policy, 0.1 * tol, rho, one_step, np.int64(1), work, polished)
    return True, polished_residual, used


@njit(cache=True)
def _finish(lcp: OrderedLcp, start: np.ndarray, start_w: np.ndarray, tol: float, rho: float,
            prox: Prox, finish_budget: int, work: Work):
    """Finish an interior-point iterate by proximal policy iteration, then polish it.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    start, start_w : np.ndarray
        The iterate's l and w; the first policy is ``{i : w_i < D_i l_i}``.
    tol, rho : float
        The tolerance and the prox weight.
    prox : Prox
        The safeguards.
    finish_budget : int
        The most linear solves to make.
    work : Work
        The solve's work arrays.

    Returns
    -------
    l : np.ndarray
        The best l found (polished by :func:`_polish` when converged).
    done : bool
        Whether it converged.
    solves : int
        The linear solves made.
    residual : float
        The residual of l.

    Notes
    -----
    Near the solution the policy of an interior-point iterate is close to the exact active set,
    and policy iteration finds that set in one or two solves, so that the answer is not the
    interior point's approximation.
    """
    finished = np.empty(start.size)
    done, _, used, finished_residual = _prox_policy_iteration(
        lcp, start, _original_residual(lcp.original, lcp.scale, start, work.product,
                                       work.unpermuted),
        start_w < lcp.diag * start, tol, rho, prox, finish_budget, work, finished)
    if done:
        polished = np.empty(start.size)
        moved, finished_residual, extra = _polish(lcp, finished, finished_residual, tol, rho,
                                                  work, polished,
                                                  np.empty(start.size, dtype=np.bool_))
        used += extra
        if moved:
            finished = polished
    return finished, done, used, finished_residual

