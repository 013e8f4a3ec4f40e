"""PIQP through its own API, sparse (``piqp.SparseSolver``) and dense (``piqp.DenseSolver``).

``setup(P, c, A, b, G, h_l, h_u, x_l, x_u)`` takes every block as optional, so each
formulation passes only what it has: the dual ``x_l = 0`` (bounds, no rows), the primal
``h_l <= G v`` with ``G = G^T`` (one-sided rows), the dual-factored ``A x = 0`` and
``x_l = (0, -inf)`` (sparse only). PIQP reads the upper triangle of P, so Q goes in as it is;
the dense solver takes Fortran-ordered arrays. The primal's impulses are the multipliers
``z_l >= 0`` of the lower row bounds. PIQP is an interior point: it takes no warm start.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

try:
    import piqp
except ImportError as _error:
    piqp = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput
from qpbench.solvers.native.common import (
    dense_diagonal,
    dense_fortran,
    dense_symmetric,
    native_name,
    register_missing,
    register_pairs,
)

SPARSE = native_name("piqp")
DENSE = native_name("piqp-dense")
SPARSE_FORMULATIONS = ("dual", "primal", "dual-factored")
DENSE_FORMULATIONS = ("dual", "primal")


def _solver(name: str, dense: bool, eps: float, scale: float) -> Any:
    solver = piqp.DenseSolver() if dense else piqp.SparseSolver()
    solver.settings.verbose = False
    for key, value in accuracy.options_for(name, eps, scale).items():
        setattr(solver.settings, key, value)
    return solver


def _solved(solver: Any, impulses_of: Callable[[Any], np.ndarray], scale: float
            ) -> SolverOutput:
    status = solver.solve()
    result = solver.result
    return SolverOutput(impulses=impulses_of(result), status=status.name,
                        claimed_success=status == piqp.PIQP_SOLVED,
                        iterations=int(result.info.iter), info={"scale": scale})


def make_solve(name: str, formulation: str, dense: bool) -> SolveFunction:
    """The solve function of ``name`` (sparse or dense PIQP) in ``formulation``.

    Parameters
    ----------
    name : str
        ``piqp-native`` or ``piqp-dense-native``, whose accuracy-table row gives the
        options.
    formulation : str
        ``dual``, ``primal`` or ``dual-factored`` (sparse only).
    dense : bool
        Whether the dense solver runs it (the sparse one otherwise).

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale; the warm start is ignored. Its
        claim is PIQP's ``PIQP_SOLVED``.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        solver = _solver(name, dense, eps, scale)
        if formulation == "dual":
            P = dense_symmetric(problem.Q) if dense else problem.Q
            solver.setup(P, problem.b, x_l=np.zeros(problem.n_contacts))
            return _solved(solver, lambda result: result.x, scale)
        if formulation == "primal":
            primal = primal_qp(problem)
            P = dense_diagonal(primal.P.diagonal()) if dense else primal.P
            G = dense_fortran(primal.A) if dense else primal.A
            solver.setup(P, primal.q, G=G, h_l=primal.lower)
            return _solved(solver, lambda result: result.z_l, scale)
        factored = factored_dual_qp(problem)
        n = factored.n_contacts
        lower = np.concatenate([np.zeros(n), np.full(factored.A.shape[0], -np.inf)])
        solver.setup(factored.P, factored.q, A=factored.A, b=factored.b_eq, x_l=lower)
        return _solved(solver, lambda result: factored.impulses(result.x), scale)

    return solve


if piqp is None:
    register_missing({SPARSE: SPARSE_FORMULATIONS, DENSE: DENSE_FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(SPARSE, {formulation: make_solve(SPARSE, formulation, dense=False)
                            for formulation in SPARSE_FORMULATIONS}, "piqp")
    register_pairs(DENSE, {formulation: make_solve(DENSE, formulation, dense=True)
                           for formulation in DENSE_FORMULATIONS}, "piqp")
