"""QPALM through its own API: ``qpalm.Data(n, m)`` (Q, q, A, bmin, bmax), ``qpalm.Settings``
and ``qpalm.Solver(data, settings).solve()``, sparse.

QPALM has no bounds apart from its rows ``bmin <= A x <= bmax``: the dual's ``l >= 0`` are
the rows ``I l``, the primal's ``G^T v >= lower``, the dual-factored form stacks
``L l - y = 0`` over ``I l >= 0``. Its multiplier of a row active at its lower bound is
negative: the primal's impulses are ``-y``. A warm start of x goes through
``Solver.warm_start``. QPALM reports its set-up and solve times.
"""

from __future__ import annotations

from typing import Any

import numpy as np

try:
    import qpalm
except ImportError as _error:
    qpalm = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput, reported_times
from qpbench.solvers.native.common import (
    bounds_only_rows,
    factored_rows_with_bounds,
    factored_start,
    native_name,
    primal_start,
    register_missing,
    register_pairs,
)

NAME = native_name("qpalm")
FORMULATIONS = ("dual", "primal", "dual-factored")
SOLVED = "solved"


def _solved(Q: Any, q: np.ndarray, A: Any, lower: np.ndarray, upper: np.ndarray,
            start: np.ndarray | None, eps: float, scale: float) -> tuple[SolverOutput, Any]:
    data = qpalm.Data(q.size, A.shape[0])
    data.Q, data.q, data.A, data.bmin, data.bmax = Q, q, A, lower, upper
    settings = qpalm.Settings()
    settings.verbose = False
    for key, value in accuracy.options_for(NAME, eps, scale).items():
        setattr(settings, key, value)
    solver = qpalm.Solver(data, settings)
    if start is not None:
        solver.warm_start(start, None)
    solver.solve()
    info = solver.info
    output = SolverOutput(impulses=None, status=str(info.status),
                          claimed_success=info.status == SOLVED, iterations=int(info.iter),
                          backend_times=reported_times(backend_setup_time_s=info.setup_time,
                                                       backend_solve_time_s=info.solve_time),
                          info={"scale": scale})
    return output, solver.solution


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``qpalm-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale and the warm start in the
        formulation's variables. Its claim is QPALM's ``solved``, its backend times QPALM's
        own set-up and solve times.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        if formulation == "dual":
            output, solution = _solved(problem.Q, problem.b, bounds_only_rows(n), np.zeros(n),
                                       np.full(n, np.inf), warm_start, eps, scale)
            output.impulses = np.array(solution.x)
        elif formulation == "primal":
            primal = primal_qp(problem)
            output, solution = _solved(primal.P, primal.q, primal.A, primal.lower,
                                       np.full(n, np.inf), primal_start(problem, warm_start),
                                       eps, scale)
            output.impulses = -np.array(solution.y)
        else:
            factored = factored_dual_qp(problem)
            rows, k, _ = factored_rows_with_bounds(problem)
            output, solution = _solved(factored.P, factored.q, rows, np.zeros(k + n),
                                       np.concatenate([np.zeros(k), np.full(n, np.inf)]),
                                       factored_start(problem, warm_start), eps, scale)
            output.impulses = factored.impulses(np.array(solution.x))
        return output

    return solve


if qpalm is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "qpalm", warm_start=True)
