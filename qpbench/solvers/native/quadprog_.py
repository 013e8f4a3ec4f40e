"""quadprog through its own API: ``quadprog.solve_qp(G, a, C, b)`` minimises
``1/2 x^T G x - a^T x`` subject to ``C^T x >= b`` (Goldfarb-Idnani, dense).

It needs G positive definite and has no bounds: the dual passes ``G = Q``, ``a = -b`` and
``C = I`` (the rows ``l >= 0``), and a singular Q is refused by name (status
``unsupported: not positive definite``, no claim), as through qpsolvers. The primal's
``G = M`` is diagonal, so it goes in factored (``factorized=True`` with
``R^-1 = M^-1/2``), with ``C = G`` and ``b = lower``; its Lagrange multipliers are the
impulses. The dual-factored form (``P = diag(0, I)``) is singular by construction.
"""

from __future__ import annotations

import numpy as np

try:
    import quadprog
except ImportError as _error:
    quadprog = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput
from qpbench.solvers.native.common import native_name, register_missing, register_pairs
from qpbench.solvers.qpsolvers_ import NOT_POSITIVE_DEFINITE

NAME = native_name("quadprog")
FORMULATIONS = ("dual", "primal")
SINGULAR_FORMULATION = "dual-factored"


def _output(result: tuple, impulses: np.ndarray, scale: float) -> SolverOutput:
    iterations = np.ravel(result[3])
    return SolverOutput(impulses=impulses, status="solved", claimed_success=True,
                        iterations=int(iterations[0]) if iterations.size else None,
                        info={"scale": scale})


def solve_dual(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
               ) -> SolverOutput:
    """``min 1/2 l^T Q l + b^T l`` with ``I^T l >= 0``; a singular Q is refused by name.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level; the options follow from it at the problem's scale.
    warm_start : np.ndarray or None, optional
        Ignored: quadprog takes no start.

    Returns
    -------
    SolverOutput
        l, claimed whenever quadprog returns; a singular Q reads ``unsupported: not
        positive definite``, any other error ``error: ...``, both without impulses.
    """
    scale = metrics.scale(problem)
    n = problem.n_contacts
    try:
        result = quadprog.solve_qp(problem.Q.toarray(), -problem.b, np.identity(n), np.zeros(n))
    except ValueError as error:
        refused = "positive definite" in str(error)
        return SolverOutput(impulses=None, claimed_success=False, info={"scale": scale},
                            status=NOT_POSITIVE_DEFINITE if refused else f"error: {error}")
    return _output(result, result[0], scale)


def solve_primal(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
                 ) -> SolverOutput:
    """``min 1/2 v^T M v - (M v-)^T v`` with ``(G^T)^T v >= lower``, M given factored.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level; the options follow from it at the problem's scale.
    warm_start : np.ndarray or None, optional
        Ignored: quadprog takes no start.

    Returns
    -------
    SolverOutput
        l (quadprog's Lagrange multipliers), claimed whenever quadprog returns.
    """
    scale = metrics.scale(problem)
    primal = primal_qp(problem)
    inverse_root = np.diag(1.0 / np.sqrt(primal.P.diagonal()))
    result = quadprog.solve_qp(inverse_root, -primal.q, primal.A.T.toarray(), primal.lower,
                               factorized=True)
    return _output(result, result[4], scale)


if quadprog is None:
    register_missing({NAME: (*FORMULATIONS, SINGULAR_FORMULATION)}, IMPORT_ERROR)
else:
    register_pairs(NAME, {"dual": solve_dual, "primal": solve_primal}, "quadprog",
                   refused={SINGULAR_FORMULATION: f"{NOT_POSITIVE_DEFINITE} (P = diag(0, I) "
                            "is singular)"})
