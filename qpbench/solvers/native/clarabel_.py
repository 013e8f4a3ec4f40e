"""Clarabel through its own API: ``clarabel.DefaultSolver(P, q, A, b, cones, settings)``.

Clarabel poses ``A x + s = b`` with s in a product of cones and reads the upper triangle of
P (taking it itself from a full P, so Q goes in as it is). The dual's ``l >= 0`` is
``-I l + s = 0``, s in the nonnegative cone; the primal's ``G^T v >= lower`` is
``-G^T v + s = -lower``; the dual-factored form puts ``L l - y = 0`` in the zero cone
before ``-l + s = 0``. Its multipliers z are nonnegative on the nonnegative cone, so the
primal's impulses are z. Clarabel takes no warm start; it reports its solve time.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

try:
    import clarabel
except ImportError as _error:
    clarabel = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput, reported_times
from qpbench.solvers.native.common import (
    native_name,
    register_missing,
    register_pairs,
)

NAME = native_name("clarabel")
FORMULATIONS = ("dual", "primal", "dual-factored")


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``clarabel-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale; the warm start is ignored. Its
        claim is Clarabel's ``Solved``, its backend time Clarabel's solve time.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        for key, value in accuracy.options_for(NAME, eps, scale).items():
            setattr(settings, key, value)
        n = problem.n_contacts
        if formulation == "dual":
            solver = clarabel.DefaultSolver(
                problem.Q, problem.b, -sp.identity(n, format="csc"),
                np.zeros(n), [clarabel.NonnegativeConeT(n)], settings)
        elif formulation == "primal":
            primal = primal_qp(problem)
            solver = clarabel.DefaultSolver(primal.P, primal.q, -primal.A, -primal.lower,
                                            [clarabel.NonnegativeConeT(n)], settings)
        else:
            factored = factored_dual_qp(problem)
            k = factored.A.shape[0]
            rows = sp.vstack([factored.A, factored.G], format="csc")
            solver = clarabel.DefaultSolver(
                factored.P, factored.q, rows, np.zeros(k + n),
                [clarabel.ZeroConeT(k), clarabel.NonnegativeConeT(n)], settings)
        solution = solver.solve()
        # the primal's impulses are its multipliers, the others' the first n of x
        answer = solution.z if formulation == "primal" else solution.x
        impulses = np.asarray(answer)[:n]
        return SolverOutput(
            impulses=impulses, status=str(solution.status),
            claimed_success=solution.status == clarabel.SolverStatus.Solved,
            iterations=int(solution.iterations),
            backend_times=reported_times(backend_solve_time_s=solution.solve_time),
            info={"scale": scale})

    return solve


if clarabel is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "clarabel")
