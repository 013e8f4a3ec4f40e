"""The ordered solve: proximal policy iteration, then the interior point, finished.

:func:`_solve_ordered` runs proximal policy iteration within ``pi_budget`` linear solves;
when that fails, a Mehrotra predictor-corrector interior point (Mehrotra, "On the
implementation of a primal-dual interior point method", SIAM J. Optim. 2(4), 1992; Nocedal
and Wright, "Numerical Optimization", 2006, section 16.6) on the Jacobi-scaled LCP, as
``qpbench.solvers.lcp_interior.interior_point`` runs it, whose Newton system

    (S Q S + diag(max(w / l, 1e-14))) dl = r,   S = D^-1/2,

is solved by the envelope factor of the whole matrix. Iterates close to the solution, and the
best iterate when the interior point stalls, are handed to policy iteration
(:func:`.prox._finish`), which finds their exact active set.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import (
    PATH_INTERIOR,
    PATH_NONE,
    PATH_POLICY_ITERATION,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.factor import _envelope_solve, _factor_rows
from qpbench.solvers.pi_robust_kernel.prox import (
    _finish,
    _policy_from,
    _polish,
    _prox_policy_iteration,
)
from qpbench.solvers.pi_robust_kernel.residual import _matvec, _original_residual
from qpbench.solvers.pi_robust_kernel.structures import Options, OrderedLcp, _work


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _inner(left: np.ndarray, right: np.ndarray) -> float:
    """``sum_i left_i right_i``, in index order: a loop, not ``@`` (which calls the BLAS, whose
    summation order depends on the CPU)."""
    total = 0.0
    for i in range(left.size):
        total += left[i] * right[i]
    return total


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _step_to_boundary(value: np.ndarray, change: np.ndarray) -> float:
    """The largest ``alpha <= 1`` with ``value + alpha * change >= 0``."""
    alpha = 1.0
    for i in range(value.size):
        if change[i] < 0.0:
            candidate = -value[i] / change[i]
            if candidate < alpha:
                alpha = candidate
    return alpha


@njit(cache=True)
def _solve_ordered(lcp: OrderedLcp, start: np.ndarray, start_residual: float,
                   start_product: np.ndarray, options: Options, normal_first: np.ndarray):
    """Solve the ordered LCP by proximal policy iteration, then the interior point.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order; every residual is taken on ``lcp.original``, as
        qpbench's caller would sum it.
    start : np.ndarray
        The start l >= 0 in the kernel's order, not converged.
    start_residual : float
        qpbench's residual of ``start``, computed by the caller.
    start_product : np.ndarray
        The ``Q l`` of that residual, in the posed order.
    options : Options
        The unpacked options.
    normal_first : np.ndarray
        The row offsets of the whole matrix's lower envelope (``ordering._envelope_widths``).

    Returns
    -------
    l : np.ndarray
        The answer, in the kernel's order.
    converged : bool
        Whether its residual (qpbench's formula) is at most tol.
    path : int
        ``PATH_POLICY_ITERATION``, ``PATH_INTERIOR`` or ``PATH_NONE``.
    solves : int
        Linear solves of policy iteration plus interior-point iterations.
    interior : int
        Interior-point iterations.
    factorizations : int
        Envelope factorizations, of blocks and of Newton matrices.
    residual : float
        The residual of l.

    Notes
    -----
    1. Proximal policy iteration from ``start`` with the policy ``{(Q l + b)_i <= D_i l_i}``,
       within ``pi_budget`` solves; a converged answer is polished (:func:`.prox._polish`).
    2. Otherwise Mehrotra's predictor-corrector on the Jacobi-scaled LCP (S = D^-1/2), as
       ``qpbench.solvers.lcp_interior.interior_point`` without its centrality correctors
       (the hard cases that come here are small and dense): each iteration factors
       ``S Q S + diag(max(w / l, 1e-14))`` by the envelope factor of the whole matrix, solves
       the predictor and the corrector with it, and steps 0.99 of the way to the boundary.
    3. Every iterate whose residual is at most ``finish_below`` (then ten times lower than the
       last try) is finished by policy iteration (:func:`.prox._finish`), and so is the best
       iterate when the interior point stalls (its residual not cut by 10% in five
       iterations, as rounding makes it on extreme mass ratios).
    4. When nothing converged, the better of policy iteration's best and the interior point's
       best, with qpbench's residual of it.

    References
    ----------
    S. Mehrotra, "On the implementation of a primal-dual interior point method", SIAM J. Optim.
    2(4), 1992. J. Nocedal and S. J. Wright, "Numerical Optimization", 2nd ed., 2006,
    section 16.6.
    """
    A, upper, original, b, diag, safe_diag, scale = lcp
    tol, rho = options.tol, options.rho
    prox = options.prox
    finish_budget, finish_below = options.finish_budget, options.finish_below
    n = b.size
    work, policy, first, polished = _work(n, normal_first[n])
    product, unpermuted = work.product, work.unpermuted
    counters = work.cache.counters
    _policy_from(lcp, start, start_product, policy, False)
    converged, _, solves, first_res = _prox_policy_iteration(
        lcp, start, start_residual, policy, tol, rho, prox, options.pi_budget, work, first)
    if converged:
        moved, first_res, used = _polish(lcp, first, first_res, tol, rho, work, polished,
                                         policy)
        return polished if moved else first, True, PATH_POLICY_ITERATION, solves + used, 0, \
            counters[0], first_res
    # Mehrotra predictor-corrector on the Jacobi-scaled LCP (lcp_interior.interior_point's,
    # without its centrality correctors)
    root = 1.0 / np.sqrt(safe_diag)
    everything = np.arange(n)
    normal = np.empty(normal_first[n])
    scaled_b = b * root
    scaled_scale = max(np.max(np.abs(scaled_b)), 1e-300)
    impulses = np.full(n, scaled_scale)
    slack = np.maximum(root * _matvec(A, root * impulses) + scaled_b, scaled_scale)
    floor = 1e-14
    best, best_res, best_w = impulses * root, np.inf, slack / root
    progress, stalled = np.inf, 0
    iterations = 0
    for iteration in range(1, options.ipm_iters + 1):
        iterations = iteration - 1
        infeasibility = root * _matvec(A, root * impulses) + scaled_b - slack
        mu = _inner(impulses, slack) / n
        original_l = impulses * root
        original_w = (infeasibility + slack) / root
        res = 0.0
        for i in range(n):
            value = abs(min(diag[i] * original_l[i], original_w[i]))
            if value > res:
                res = value
        res /= scale
        if res < best_res:
            best, best_res, best_w = original_l, res, original_w
        if res < 0.9 * progress:
            progress, stalled = res, 0
        else:
            stalled += 1
        if res <= tol:
            exact = _original_residual(original, scale, original_l, product, unpermuted)
            if exact <= tol:
                return original_l, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], exact
        if res <= finish_below:
            finished, done, used, finished_res = _finish(lcp, original_l, original_w, tol, rho,
                                                         prox, finish_budget, work)
            solves += used
            if done:
                return finished, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], finished_res
            finish_below = 0.1 * res
        if stalled >= 5:  # the interior point stalls (rounding, extreme mass ratios): finish
            stalled = 0
            finished, done, used, finished_res = _finish(  # from its best iterate
                lcp, best, best_w, tol, rho, prox, finish_budget, work)
            solves += used
            if done:
                return finished, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], finished_res
        _factor_rows(upper, everything, everything, root, 1.0,
                     np.maximum(slack / impulses, floor), normal, normal_first, np.int64(0),
                     root[:0])
        counters[0] += 1
        dl = _envelope_solve(normal, normal_first, n, -slack - infeasibility)
        dw = root * _matvec(A, root * dl) + infeasibility
        alpha = min(_step_to_boundary(impulses, dl), _step_to_boundary(slack, dw))
        mu_affine = _inner(impulses + alpha * dl, slack + alpha * dw) / n
        sigma = (mu_affine / mu) ** 3 if mu > 0 else 0.0
        rhs = sigma * mu / impulses - slack - infeasibility - dl * dw / impulses
        dl = _envelope_solve(normal, normal_first, n, rhs)
        dw = root * _matvec(A, root * dl) + infeasibility
        alpha = min(1.0, 0.99 * min(_step_to_boundary(impulses, dl),
                                    _step_to_boundary(slack, dw)))
        impulses = np.maximum(impulses + alpha * dl, 1e-300)
        slack = np.maximum(slack + alpha * dw, 1e-300)
        iterations = iteration
        if not (np.all(np.isfinite(impulses)) and np.all(np.isfinite(slack))):
            break
    if first_res < best_res:  # policy iteration's best, whose residual is qpbench's already
        best, best_res = first, first_res
    else:  # the interior point's estimate, its residual as qpbench computes it
        best_res = _original_residual(original, scale, best, product, unpermuted)
    return best, best_res <= tol, PATH_NONE, solves + iterations, iterations, counters[0], \
        best_res

