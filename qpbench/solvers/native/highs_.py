"""HiGHS through its own API (highspy): one ``Highs.passModel`` call with the arrays of the
model, then ``run()``.

HiGHS keeps column bounds apart from rows: the dual is columns ``l`` in ``[0, inf)`` and no
rows; the primal is free columns v with the rows ``G^T v >= lower``; the dual-factored form
is columns ``(l, y)`` with ``l >= 0`` and the rows ``L l - y = 0``. The Hessian goes in as
its lower triangle, column-wise (HiGHS's triangular format). HiGHS's row duals of a
minimisation are nonnegative on rows active at their lower bound, so they are the primal's
impulses. HiGHS takes no warm start of a QP.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

try:
    import highspy
except ImportError as _error:
    highspy = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput
from qpbench.solvers.native.common import (
    lower_triangle,
    native_name,
    register_missing,
    register_pairs,
)
from qpbench.solvers.quiet import highs_banner_silenced

NAME = native_name("highs")
FORMULATIONS = ("dual", "primal", "dual-factored")
COLUMN_WISE = 1  # HiGHS's MatrixFormat.kColwise
TRIANGULAR = 1  # HiGHS's HessianFormat.kTriangular (the lower triangle, column-wise)
MINIMIZE = 1  # HiGHS's ObjSense.kMinimize


def _run(hessian: sp.spmatrix, cost: np.ndarray, col_lower: np.ndarray, col_upper: np.ndarray,
         rows: sp.csc_matrix | None, row_lower: np.ndarray, row_upper: np.ndarray,
         eps: float, scale: float) -> tuple[Any, Any, SolverOutput]:
    """Passes the QP, runs HiGHS and returns it, its solution and the output without
    impulses."""
    highs = highspy.Highs()
    highs.setOptionValue("output_flag", False)
    for key, value in accuracy.options_for(NAME, eps, scale).items():
        highs.setOptionValue(key, value)
    triangle = lower_triangle(hessian)
    columns = cost.size
    if rows is None:
        rows = sp.csc_matrix((0, columns))
    highs.passModel(columns, rows.shape[0], rows.nnz, triangle.nnz, COLUMN_WISE, TRIANGULAR,
                    MINIMIZE, 0.0, cost, col_lower, col_upper, row_lower, row_upper,
                    rows.indptr.astype(np.int32, copy=False),
                    rows.indices.astype(np.int32, copy=False), rows.data,
                    triangle.indptr.astype(np.int32, copy=False),
                    triangle.indices.astype(np.int32, copy=False), triangle.data,
                    np.zeros(columns, dtype=np.int32))  # every column continuous
    highs.run()
    model_status = highs.getModelStatus()
    output = SolverOutput(impulses=None, status=highs.modelStatusToString(model_status),
                          claimed_success=model_status == highspy.HighsModelStatus.kOptimal,
                          iterations=int(highs.getInfo().qp_iteration_count),
                          info={"scale": scale})
    return highs, highs.getSolution(), output


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``highs-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale; the warm start is ignored. Its
        claim is HiGHS's model status ``kOptimal``; no impulses when HiGHS holds no valid
        solution.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        empty = np.empty(0)
        if formulation == "dual":
            _, solution, output = _run(problem.Q, problem.b, np.zeros(n), np.full(n, np.inf),
                                       None, empty, empty, eps, scale)
            impulses = np.asarray(solution.col_value)
        elif formulation == "primal":
            primal = primal_qp(problem)
            free = np.full(primal.q.size, np.inf)
            _, solution, output = _run(primal.P, primal.q, -free, free, primal.A,
                                       primal.lower, np.full(n, np.inf), eps, scale)
            impulses = np.asarray(solution.row_dual)
        else:
            factored = factored_dual_qp(problem)
            k = factored.A.shape[0]
            lower = np.concatenate([np.zeros(n), np.full(k, -np.inf)])
            _, solution, output = _run(factored.P, factored.q, lower,
                                       np.full(n + k, np.inf), factored.A, factored.b_eq,
                                       factored.b_eq, eps, scale)
            impulses = factored.impulses(np.asarray(solution.col_value))
        output.impulses = impulses if solution.value_valid else None
        return output

    return solve


if highspy is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "highspy", prepare=highs_banner_silenced)
