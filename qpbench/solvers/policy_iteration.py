"""Policy iteration (Howard's algorithm) on the impact LCP, as the earlier research had it.

Source: Bokanowski, Maroso, Zidani, "Some convergence results for Howard's
algorithm", SIAM J. Numer. Anal. 47(4), 2009; the research report in
``shared/background`` (``LCPOperatorPI`` and ``policy_iter_v2``). Policy iteration
is Newton's method on ``min(D l, Q l + b) = 0``:

* policy ``P = {i : (Q l + b)_i < D_i l_i}`` (from l = 0: the approaching contacts);
* value: solve ``(P Q P + I - P) l = -P b``, i.e. ``Q_PP l_P = -b_P`` and ``l_i = 0``
  outside P, by conjugate gradients from zero as the research did (so l is a
  function of the policy alone and a repeated policy is a proven cycle), their inner
  products summed in a fixed order (``metrics.dot``), so that the path does not depend on
  the CPU's BLAS;
* stop when ``residual(l) <= tol`` or after ``max_iters`` policies.

``pi`` reports failure when a policy repeats (it would cycle forever) or at
max_iters. ``pi-v2`` jumps to a random policy (seeded) whenever a policy repeats.
Both converge for M-matrices (the theorem's monotone case) and can fail on the
singular Q of overlapping balls: they say so instead of returning a wrong answer.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import dot
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register


def policy_of(lcp: Lcp, impulses: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The policy P = {i : w_i < D_i l_i} as a boolean mask.

    Parameters
    ----------
    lcp : Lcp
        The LCP, for D = diag(Q).
    impulses : np.ndarray
        l, shape (n,).
    w : np.ndarray
        Q l + b, shape (n,).

    Returns
    -------
    np.ndarray
        The mask of P, shape (n,), bool.
    """
    return w < lcp.diag * impulses


def conjugate_gradients(matrix: sp.csr_matrix, rhs: np.ndarray, rtol: float, max_iters: int
                        ) -> np.ndarray:
    """x with ``A x = rhs`` for a symmetric positive semi-definite A, by conjugate gradients.

    Hestenes and Stiefel, J. Res. Nat. Bur. Standards 49(6), 1952: from x = 0, each step moves
    along a direction A-conjugate to the ones before by the step that minimizes
    ``x^T A x / 2 - rhs^T x`` along it. Stops when ``||rhs - A x||_2 < rtol ||rhs||_2``, after
    ``max_iters`` steps, or when a direction has no positive curvature (A singular along it),
    and returns the last x (SciPy's ``cg`` criterion, with that breakdown guarded). The inner
    products are :func:`qpbench.problem.metrics.dot`'s.

    Parameters
    ----------
    matrix : sp.csr_matrix
        A, shape (k, k).
    rhs : np.ndarray
        The right side, k entries.
    rtol : float
        The residual's norm to reach, relative to rhs's.
    max_iters : int
        The most steps.

    Returns
    -------
    np.ndarray
        x, k entries.
    """
    x = np.zeros(rhs.size)
    residual = rhs.copy()
    target = rtol * np.sqrt(dot(rhs, rhs))
    direction = residual.copy()
    squared = dot(residual, residual)
    for _ in range(max_iters):
        if np.sqrt(squared) < target:
            break
        image = matrix @ direction
        curvature = dot(direction, image)
        if not curvature > 0.0:
            break
        step = squared / curvature
        x += step * direction
        residual -= step * image
        squared, previous = dot(residual, residual), squared
        direction = residual + (squared / previous) * direction
    return x


def policy_value(lcp: Lcp, policy: np.ndarray, cg_rtol: float, cg_max_iters: int) -> np.ndarray:
    """l with ``Q_PP l_P = -b_P`` (conjugate gradients from zero) and ``l_i = 0`` outside P.

    Parameters
    ----------
    lcp : Lcp
        The LCP.
    policy : np.ndarray
        The mask of P, shape (n,), bool.
    cg_rtol : float
        CG's relative tolerance on the residual of ``Q_PP l_P = -b_P``.
    cg_max_iters : int
        The most CG iterations; CG's last iterate is taken when it does not converge.

    Returns
    -------
    np.ndarray
        l, shape (n,).
    """
    impulses = np.zeros(lcp.n)
    index = np.flatnonzero(policy)
    if index.size == 0:
        return impulses
    block = lcp.Q[index][:, index]
    rhs = -lcp.b[index]
    impulses[index] = conjugate_gradients(block, rhs, cg_rtol, cg_max_iters)
    return impulses


def policy_iteration(lcp: Lcp, start: np.ndarray, tol: float, max_iters: int, cg_rtol: float,
                     cg_max_iters: int, rng: np.random.Generator | None = None
                     ) -> tuple[np.ndarray, bool, str, int]:
    """Run policy iteration from ``start`` until qpbench's residual reaches ``tol``.

    ``rng`` given: on a repeated policy jump to a random one (pi-v2); ``rng`` None: a
    repeated policy ends the run as ``cycled`` (pi).

    Parameters
    ----------
    lcp : Lcp
        The LCP to solve.
    start : np.ndarray
        The first iterate, shape (n,); its policy is the first one solved.
    tol : float
        qpbench's relative residual to reach.
    max_iters : int
        The most policies solved.
    cg_rtol : float
        CG's relative tolerance in each policy's solve.
    cg_max_iters : int
        The most CG iterations of each policy's solve.
    rng : np.random.Generator or None, optional
        The source of random policies; None (the default) stops on a repeated policy.

    Returns
    -------
    l : np.ndarray
        The last iterate, shape (n,).
    converged : bool
        Whether its residual is at most ``tol``.
    status : str
        ``converged``, a cycle, a divergence or the iteration limit reached.
    policies : int
        The policies solved.
    """
    impulses = start
    w = lcp.w(impulses)
    if lcp.converged(impulses, tol, w):
        return impulses, True, "converged", 0
    seen: set[bytes] = set()
    for iteration in range(1, max_iters + 1):
        policy = policy_of(lcp, impulses, w)
        key = np.packbits(policy).tobytes()
        if key in seen:
            if rng is None:
                return impulses, False, f"cycled: policy repeated at iteration {iteration}", \
                    iteration - 1
            while key in seen and len(seen) < 2 ** min(lcp.n, 62):
                policy = rng.random(lcp.n) < 0.5
                key = np.packbits(policy).tobytes()
        seen.add(key)
        impulses = policy_value(lcp, policy, cg_rtol, cg_max_iters)
        if not np.all(np.isfinite(impulses)):
            return impulses, False, "diverged: non-finite impulses", iteration
        w = lcp.w(impulses)
        if lcp.converged(impulses, tol, w):
            return impulses, True, "converged", iteration
    return impulses, False, f"max_iters ({max_iters}) reached", max_iters


def _solver(name: str, randomize: bool):
    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        lcp = Lcp.of(problem)
        options = accuracy.options_for(name, eps, lcp.scale)
        start = lcp.start(warm_start)
        rng = np.random.default_rng(options["seed"]) if randomize else None
        impulses, converged, status, iterations = policy_iteration(
            lcp, start, options["tol"], options["max_iters"], options["cg_rtol"],
            options["cg_max_iters"], rng)
        return output(impulses, converged, status, iterations)

    return solve


register(SolverSpec(name="pi", formulation=FORMULATION, backend=BACKEND,
                    solve=_solver("pi", randomize=False), version=VERSION, warm_start=True,
                    description="policy iteration (Howard), CG inner solves; fails on a cycle"))
register(SolverSpec(name="pi-v2", formulation=FORMULATION, backend=BACKEND,
                    solve=_solver("pi-v2", randomize=True), version=VERSION, warm_start=True,
                    description="policy iteration, random seeded policy when one repeats"))
