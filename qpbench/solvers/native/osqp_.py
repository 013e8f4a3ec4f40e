"""OSQP through its own API: ``osqp.OSQP().setup(P, q, A, l, u, **settings)``, sparse.

OSQP reads the upper triangle of P (its interface takes it from a full P, so Q goes in as
it is) and has no bounds apart from its rows ``l <= A x <= u``,
so the dual's ``l >= 0`` are the rows ``I l`` in ``[0, inf)``, the primal's are
``G^T v >= lower``, and the dual-factored form stacks ``L l - y = 0`` over ``I l >= 0``.
OSQP's multiplier of a row active at its lower bound is negative: the primal's impulses are
``-y``. It takes a warm start of x (as qpsolvers passes it) and reports its own set-up and
solve times.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

try:
    import osqp
except ImportError as _error:
    osqp = None
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
from qpbench.solvers.quiet import c_stdout_silenced

NAME = native_name("osqp")
FORMULATIONS = ("dual", "primal", "dual-factored")


def _solved(P: Any, q: np.ndarray, A: Any, lower: np.ndarray, upper: np.ndarray,
            start: np.ndarray | None, impulses_of: Callable[[Any], np.ndarray], eps: float,
            scale: float) -> SolverOutput:
    solver = osqp.OSQP()
    with c_stdout_silenced():  # OSQP's C code prints "Polishing ..." even when not verbose
        solver.setup(P, q, A, lower, upper, verbose=False,
                     **accuracy.options_for(NAME, eps, scale))
        if start is not None:
            solver.warm_start(x=start)
        result = solver.solve(raise_error=False)
    info = result.info
    found = info.status_val == osqp.SolverStatus.OSQP_SOLVED
    return SolverOutput(
        impulses=impulses_of(result) if result.x is not None else None,
        status=str(info.status), claimed_success=bool(found), iterations=int(info.iter),
        backend_times=reported_times(backend_setup_time_s=info.setup_time,
                                     backend_solve_time_s=info.solve_time),
        info={"scale": scale})


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``osqp-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale and the warm start in the
        formulation's variables. Its claim is OSQP's ``solved``, its backend times OSQP's
        own set-up and solve times.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        if formulation == "dual":
            return _solved(problem.Q, problem.b, bounds_only_rows(n),
                           np.zeros(n), np.full(n, np.inf), warm_start,
                           lambda result: result.x, eps, scale)
        if formulation == "primal":
            primal = primal_qp(problem)
            return _solved(primal.P, primal.q, primal.A, primal.lower, np.full(n, np.inf),
                           primal_start(problem, warm_start), lambda result: -result.y,
                           eps, scale)
        factored = factored_dual_qp(problem)
        rows, k, _ = factored_rows_with_bounds(problem)
        lower = np.zeros(k + n)
        upper = np.concatenate([np.zeros(k), np.full(n, np.inf)])
        return _solved(factored.P, factored.q, rows, lower, upper,
                       factored_start(problem, warm_start),
                       lambda result: factored.impulses(result.x), eps, scale)

    return solve


if osqp is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "osqp", warm_start=True)
