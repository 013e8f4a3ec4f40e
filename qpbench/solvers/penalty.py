"""The research's penalty method for the impact LCP.

Source: the research report in ``shared/background`` (``LCPOperatorPenalty``, after
W. Zhang's report); penalty methods for LCPs: Wang and Huang, "A power penalty
method for linear complementarity problems", Oper. Res. Lett. 36(2), 2008 (power 1).
Repeat: ``P = diag(l_i < 0)``, solve ``(Q + kappa P) l = -b``, until qpbench's
``residual(l) <= tol``; failure when P repeats without converging or at
``max_iters``. The linear solve is a minimum-norm least-squares solve (dense) up to
``dense_limit`` contacts and a sparse Cholesky factorization above, which fails, and says so,
when the system is not numerically positive definite (the first one, ``Q l = -b``, whenever Q
is singular). Both take their sums in an order the CPU does not choose
(``qpbench.solvers.fixed_order_dense``, and ``qpbench.solvers.sparse_cholesky``'s simplicial
factor), so the answer is the same on every machine.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy, fixed_order_dense
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register
from qpbench.solvers.sparse_cholesky import symmetric_factor

NAME = "penalty"


def penalty(lcp: Lcp, tol: float, kappa: float, max_iters: int, dense_limit: int
            ) -> tuple[np.ndarray | None, bool, str, int]:
    """Run the penalty iteration from l = 0 until qpbench's residual reaches ``tol``.

    The penalty of a contact with ``l_i < 0`` is ``kappa * D_ii`` (1 in place of a zero
    ``D_ii``).

    Parameters
    ----------
    lcp : Lcp
        The LCP to solve.
    tol : float
        qpbench's relative residual to reach.
    kappa : float
        The penalty factor, relative to diag(Q).
    max_iters : int
        The most linear solves.
    dense_limit : int
        The most contacts for the dense least-squares solve; above it, sparse Cholesky.

    Returns
    -------
    l : np.ndarray or None
        The last solution, shape (n,); None when the sparse system was not positive definite.
    converged : bool
        Whether its residual is at most ``tol``.
    status : str
        ``converged`` or why it stopped (a singular system, divergence, a repeated
        penalized set, the iteration limit).
    solves : int
        The linear solves done.
    """
    n = lcp.n
    impulses = np.zeros(n)
    if lcp.converged(impulses, tol):
        return impulses, True, "converged", 0
    dense = lcp.Q.toarray() if n <= dense_limit else None
    penalized = np.zeros(n, dtype=bool)
    seen: set[bytes] = set()
    for iteration in range(1, max_iters + 1):
        seen.add(np.packbits(penalized).tobytes())
        shift = kappa * lcp.safe_diag * penalized
        if dense is not None:
            impulses = fixed_order_dense.min_norm_solve(dense + np.diag(shift), -lcp.b)
        else:
            try:
                impulses = symmetric_factor(lcp.Q + sp.diags(shift)).solve(-lcp.b)
            except np.linalg.LinAlgError as error:
                return None, False, f"singular penalty system: {error}", iteration
        if not np.all(np.isfinite(impulses)):
            return impulses, False, "diverged: non-finite impulses", iteration
        if lcp.converged(impulses, tol):
            return impulses, True, "converged", iteration
        penalized = impulses < 0.0
        if np.packbits(penalized).tobytes() in seen:
            return impulses, False, "penalized set repeated above tolerance", iteration
    return impulses, False, f"max_iters ({max_iters}) reached", max_iters


def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    """Solve ``problem`` by the penalty method at accuracy level ``eps``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level, the relative residual to reach; the solver's options
        follow from it in :mod:`qpbench.solvers.accuracy`.
    warm_start : np.ndarray or None, optional
        Ignored: the method always starts at l = 0.

    Returns
    -------
    SolverOutput
        The impulses, status, the algorithm's own convergence test as claim, and
        the linear solves done.
    """
    lcp = Lcp.of(problem)
    options = accuracy.options_for(NAME, eps, lcp.scale)
    impulses, converged, status, iterations = penalty(lcp, **options)
    return output(impulses, converged, status, iterations)


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=False, prepare=fixed_order_dense.warm_up,
                    description="penalty method (Q + kappa P) l = -b, kappa ~ 1e9"))
