"""Accelerated projected gradient descent (APGD) on the dual QP, as SCISim ships it.

Source: Mazhar, Heyn, Negrut, Tasora, "Using Nesterov's method to accelerate
multibody dynamics with friction and contact", ACM TOG 34(3), 2015 (Nesterov /
FISTA steps with the gradient restart of O'Donoghue and Candes, "Adaptive restart
for accelerated gradient schemes", Found. Comput. Math. 15, 2015).

``min 1/2 l^T Q l + b^T l, l >= 0`` in the Jacobi-scaled metric ``D = diag(Q)``:
``x+ = max(0, y - (Q y + b) / (L D))`` with L a Gershgorin bound on the largest
eigenvalue of ``D^-1/2 Q D^-1/2``; momentum ``y = x+ + (t - 1) / t+ (x+ - x)``,
restarted whenever the step goes uphill. Stops on qpbench's ``residual <= tol``
(checked every ``check_every`` steps) or at ``max_iters``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register

NAME = "apgd"


def gershgorin_scaled(lcp: Lcp) -> float:
    """max_i sum_j |Q_ij| / sqrt(D_i D_j) >= lambda_max(D^-1/2 Q D^-1/2).

    Parameters
    ----------
    lcp : Lcp
        The LCP; zero diagonal entries count as 1.

    Returns
    -------
    float
        The Gershgorin bound, at least 1 (1 for a problem without contacts).
    """
    inverse_root = 1.0 / np.sqrt(lcp.safe_diag)
    scaled = sp.diags(inverse_root) @ abs(lcp.Q) @ sp.diags(inverse_root)
    return float(np.max(np.asarray(scaled.sum(axis=1)).ravel(), initial=1.0))


def apgd(lcp: Lcp, start: np.ndarray, tol: float, max_iters: int, check_every: int
         ) -> tuple[np.ndarray, bool, str, int]:
    """Run APGD from ``start`` until qpbench's residual reaches ``tol``.

    Parameters
    ----------
    lcp : Lcp
        The LCP to solve.
    start : np.ndarray
        The first iterate, shape (n,), l >= 0; it is copied, not changed.
    tol : float
        qpbench's relative residual to reach.
    max_iters : int
        The most gradient steps.
    check_every : int
        Steps between residual (and finiteness) checks.

    Returns
    -------
    l : np.ndarray
        The last iterate, shape (n,).
    converged : bool
        Whether its residual is at most ``tol``.
    status : str
        ``converged``, a divergence or the iteration limit reached.
    iterations : int
        The steps taken.
    """
    x = start.copy()
    if lcp.converged(x, tol):
        return x, True, "converged", 0
    step = 1.0 / (gershgorin_scaled(lcp) * lcp.safe_diag)
    y = x.copy()
    t = 1.0
    for iteration in range(1, max_iters + 1):
        gradient = lcp.Q @ y + lcp.b
        x_next = np.maximum(0.0, y - step * gradient)
        if gradient @ (x_next - x) > 0.0:  # uphill: restart the momentum
            t = 1.0
            y = x_next
        else:
            t_next = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
            y = x_next + ((t - 1.0) / t_next) * (x_next - x)
            t = t_next
        x = x_next
        if iteration % check_every == 0:
            if not np.all(np.isfinite(x)):
                return x, False, "diverged: non-finite impulses", iteration
            if lcp.converged(x, tol):
                return x, True, "converged", iteration
    converged = lcp.converged(x, tol)
    return x, converged, "converged" if converged else f"max_iters ({max_iters}) reached", \
        max_iters


def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    """Solve ``problem`` by APGD at accuracy level ``eps``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level, the relative residual to reach; the solver's options
        follow from it in :mod:`qpbench.solvers.accuracy`.
    warm_start : np.ndarray or None, optional
        A guess of l, the start when finite and of the right size (clipped to
        l >= 0); None or an unusable guess starts at 0.

    Returns
    -------
    SolverOutput
        The impulses, status, the algorithm's own convergence test as claim, and
        the steps taken.
    """
    lcp = Lcp.of(problem)
    options = accuracy.options_for(NAME, eps, lcp.scale)
    start = lcp.start(warm_start)
    impulses, converged, status, iterations = apgd(lcp, start, **options)
    return output(impulses, converged, status, iterations)


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=True,
                    description="accelerated projected gradient (Nesterov, restart), Jacobi"))
