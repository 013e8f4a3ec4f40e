"""DAQP through its own API: ``daqp.solve(H, f, A, bupper, blower)``, dense.

DAQP reads the first entries of ``bupper``/``blower`` beyond A's rows as simple bounds on
x, so the dual passes A with no rows and its bounds ``0 <= l`` alone; the primal passes
``A = G^T`` (dense) with ``lower <= G^T v``. DAQP's multiplier of a constraint active at its
lower bound is negative, so the primal's impulses are ``-lam``. Both take a primal start.
"""

from __future__ import annotations

import numpy as np

try:
    import daqp
except ImportError as _error:
    daqp = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, reported_times
from qpbench.solvers.native.common import (
    native_name,
    primal_start,
    register_missing,
    register_pairs,
)

NAME = native_name("daqp")
FORMULATIONS = ("dual", "primal")
# DAQP's "no upper bound" (its own infinity)
UNBOUNDED = 1e30
EXIT_FLAGS = {2: "soft optimal", 1: "optimal", -1: "infeasible", -2: "cycling",
              -3: "unbounded", -4: "iteration limit", -5: "nonconvex",
              -6: "overdetermined initial active set", -7: "time limit", -8: "unsupported"}


def _output(x: np.ndarray, exitflag: int, info: dict, impulses: np.ndarray | None,
            scale: float) -> SolverOutput:
    found = exitflag > 0
    return SolverOutput(
        impulses=impulses if found else None,
        status=f"{EXIT_FLAGS.get(exitflag, 'unknown')} ({exitflag})",
        claimed_success=found,
        iterations=int(info["iterations"]),
        backend_times=reported_times(backend_setup_time_s=info.get("setup_time"),
                                     backend_solve_time_s=info.get("solve_time")),
        info={"scale": scale},
    )


def solve_dual(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
               ) -> SolverOutput:
    """``min 1/2 l^T Q l + b^T l`` with the simple bounds ``0 <= l``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level; the options follow from it at the problem's scale.
    warm_start : np.ndarray or None, optional
        A guess of l, DAQP's primal start; None for none.

    Returns
    -------
    SolverOutput
        l (none unless DAQP's exit flag is positive, its claim), status, iterations
        and DAQP's own set-up and solve times.
    """
    scale = metrics.scale(problem)
    n = problem.n_contacts
    x, _, exitflag, info = daqp.solve(
        problem.Q.toarray(), problem.b, np.empty((0, n)), np.full(n, UNBOUNDED), np.zeros(n),
        primal_start=warm_start, **accuracy.options_for(NAME, eps, scale))
    return _output(x, exitflag, info, x, scale)


def solve_primal(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
                 ) -> SolverOutput:
    """``min 1/2 v^T M v + q^T v`` with ``lower <= G^T v``; the impulses are ``-lam``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level; the options follow from it at the problem's scale.
    warm_start : np.ndarray or None, optional
        A guess of l, passed as DAQP's primal start v+(l) on the free degrees of
        freedom; None for none.

    Returns
    -------
    SolverOutput
        l (none unless DAQP's exit flag is positive, its claim), status, iterations
        and DAQP's own set-up and solve times.
    """
    scale = metrics.scale(problem)
    primal = primal_qp(problem)
    n = problem.n_contacts
    x, _, exitflag, info = daqp.solve(
        np.diag(primal.P.diagonal()), primal.q, primal.A.toarray(), np.full(n, UNBOUNDED),
        primal.lower, primal_start=primal_start(problem, warm_start),
        **accuracy.options_for(NAME, eps, scale))
    return _output(x, exitflag, info, -np.asarray(info["lam"]), scale)


if daqp is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {"dual": solve_dual, "primal": solve_primal}, "daqp", warm_start=True)
