"""SCS through its own API: ``scs.SCS(data, cone, **settings).solve()``.

SCS poses ``A x + s = b`` with s in a cone; it reads the upper triangle of P
(its interface takes it from a full P, so Q goes in as it is). The dual's
``l >= 0`` is ``-I l + s = 0``, s in the positive cone (``l``); the primal's
``G^T v >= lower`` is ``-G^T v + s = -lower``; the dual-factored form puts ``L l - y = 0`` in
the zero cone (``z``) first. Its dual variables y are nonnegative on the positive cone: the
primal's impulses are those of its rows. A warm start of x goes through
``solve(warm_start=True, x=...)``, as qpsolvers passes it. SCS reports its set-up and solve
times in milliseconds.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

try:
    import scs
except ImportError as _error:
    scs = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput, reported_times
from qpbench.solvers.native.common import (
    factored_start,
    native_name,
    primal_start,
    register_missing,
    register_pairs,
)

NAME = native_name("scs")
FORMULATIONS = ("dual", "primal", "dual-factored")
SOLVED = 1  # SCS's status_val of "solved"
MILLISECONDS = 1e-3


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``scs-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale and the warm start in the
        formulation's variables. Its claim is SCS's ``solved``, its backend times SCS's own
        set-up and solve times, in seconds.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        if formulation == "dual":
            data = {"P": problem.Q, "c": problem.b,
                    "A": -sp.identity(n, format="csc"), "b": np.zeros(n)}
            cone = {"l": n}
            start = warm_start
        elif formulation == "primal":
            primal = primal_qp(problem)
            data = {"P": primal.P, "c": primal.q, "A": -primal.A, "b": -primal.lower}
            cone = {"l": n}
            start = primal_start(problem, warm_start)
        else:
            factored = factored_dual_qp(problem)
            k = factored.A.shape[0]
            data = {"P": factored.P, "c": factored.q,
                    "A": sp.vstack([factored.A, factored.G], format="csc"),
                    "b": np.zeros(k + n)}
            cone = {"z": k, "l": n}
            start = factored_start(problem, warm_start)
        solver = scs.SCS(data, cone, verbose=False, **accuracy.options_for(NAME, eps, scale))
        result = solver.solve(warm_start=start is not None, x=start)
        info = result["info"]
        # the primal's impulses are its multipliers, the others' the first n of x
        impulses = np.asarray(result["y" if formulation == "primal" else "x"])[:n]
        return SolverOutput(
            impulses=impulses, status=str(info["status"]),
            claimed_success=info["status_val"] == SOLVED, iterations=int(info["iter"]),
            backend_times=reported_times(
                backend_setup_time_s=info["setup_time"] * MILLISECONDS,
                backend_solve_time_s=info["solve_time"] * MILLISECONDS),
            info={"scale": scale})

    return solve


if scs is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "scs", warm_start=True)
