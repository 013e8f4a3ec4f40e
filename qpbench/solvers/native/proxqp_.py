"""ProxQP (proxsuite) through its own API, sparse (``proxqp.sparse.QP``) and dense
(``proxqp.dense.QP``, with box constraints).

``QP(n, n_eq, n_in[, box_constraints]).init(H, g, A, b, C, l, u[, l_box, u_box])`` then
``solve()``. The dense dual is all bounds: ``box_constraints=True`` with ``0 <= l`` and no
rows; the sparse one has no boxes, so its bounds are the rows ``0 <= I l``. The primal is
``lower <= G^T v`` in both, the dual-factored form (sparse) ``L l - y = 0`` with
``0 <= I l``. ProxQP's multiplier of a row active at its lower bound is negative: the
primal's impulses are ``-z``. A warm start of x goes through ``initial_guess = WARM_START``
and ``solve(x, None, None)``, as qpsolvers passes it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

try:
    from proxsuite import proxqp
except ImportError as _error:
    proxqp = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput
from qpbench.solvers.native.common import (
    bounds_only_rows,
    dense_diagonal,
    dense_fortran,
    dense_symmetric,
    factored_start,
    native_name,
    primal_start,
    register_missing,
    register_pairs,
)

SPARSE = native_name("proxqp")
DENSE = native_name("proxqp-dense")
SPARSE_FORMULATIONS = ("dual", "primal", "dual-factored")
DENSE_FORMULATIONS = ("dual", "primal")


def _configured(qp: Any, name: str, eps: float, scale: float) -> Any:
    qp.settings.verbose = False
    for key, value in accuracy.options_for(name, eps, scale).items():
        setattr(qp.settings, key, value)
    return qp


def _solved(qp: Any, start: np.ndarray | None, impulses: Any, scale: float) -> SolverOutput:
    """Solves ``qp`` (from ``start`` when given); ``impulses(results)`` reads l."""
    if start is None:
        qp.solve()
    else:
        qp.settings.initial_guess = proxqp.InitialGuess.WARM_START
        qp.solve(start, None, None)
    results = qp.results
    status = results.info.status
    return SolverOutput(impulses=impulses(results), status=status.name,
                        claimed_success=status == proxqp.QPSolverOutput.PROXQP_SOLVED,
                        iterations=int(results.info.iter), info={"scale": scale})


def make_solve(name: str, formulation: str, dense: bool) -> SolveFunction:
    """The solve function of ``name`` (sparse or dense ProxQP) in ``formulation``.

    Parameters
    ----------
    name : str
        ``proxqp-native`` or ``proxqp-dense-native``, whose accuracy-table row gives the
        options.
    formulation : str
        ``dual``, ``primal`` or ``dual-factored`` (sparse only).
    dense : bool
        Whether the dense solver runs it (the sparse one otherwise).

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale and the warm start in the
        formulation's variables. Its claim is ProxQP's ``PROXQP_SOLVED``.
    """
    backend = None if proxqp is None else (proxqp.dense if dense else proxqp.sparse)

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        upper = np.full(n, np.inf)
        if formulation == "dual" and dense:
            qp = _configured(backend.QP(n, 0, 0, True), name, eps, scale)
            qp.init(H=dense_symmetric(problem.Q), g=problem.b, l_box=np.zeros(n),
                    u_box=upper)
            return _solved(qp, warm_start, lambda results: results.x, scale)
        if formulation == "dual":
            qp = _configured(backend.QP(n, 0, n), name, eps, scale)
            qp.init(H=problem.Q, g=problem.b, C=bounds_only_rows(n), l=np.zeros(n), u=upper)
            return _solved(qp, warm_start, lambda results: results.x, scale)
        if formulation == "primal":
            primal = primal_qp(problem)
            dofs = primal.q.size
            qp = _configured(backend.QP(dofs, 0, n), name, eps, scale)
            if dense:
                qp.init(H=dense_diagonal(primal.P.diagonal()), g=primal.q,
                        C=dense_fortran(primal.A), l=primal.lower, u=upper)
            else:
                qp.init(H=primal.P, g=primal.q, C=primal.A, l=primal.lower, u=upper)
            return _solved(qp, primal_start(problem, warm_start),
                           lambda results: -results.z, scale)
        factored = factored_dual_qp(problem)
        k = factored.A.shape[0]
        bounds = sp.hstack([bounds_only_rows(n), sp.csc_matrix((n, k))], format="csc")
        qp = _configured(backend.QP(n + k, k, n), name, eps, scale)
        qp.init(H=factored.P, g=factored.q, A=factored.A, b=factored.b_eq, C=bounds,
                l=np.zeros(n), u=upper)
        return _solved(qp, factored_start(problem, warm_start),
                       lambda results: factored.impulses(results.x), scale)

    return solve


if proxqp is None:
    register_missing({SPARSE: SPARSE_FORMULATIONS, DENSE: DENSE_FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(SPARSE, {formulation: make_solve(SPARSE, formulation, dense=False)
                            for formulation in SPARSE_FORMULATIONS}, "proxsuite",
                   warm_start=True)
    register_pairs(DENSE, {formulation: make_solve(DENSE, formulation, dense=True)
                           for formulation in DENSE_FORMULATIONS}, "proxsuite",
                   warm_start=True)
