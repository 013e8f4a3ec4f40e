"""Backends reached through qpsolvers (https://github.com/qpsolvers/qpsolvers), dual formulation.

``min 1/2 l^T Q l + b^T l  s.t.  l >= 0`` is passed as ``P = Q, q = b, lb = 0``.
"""

from __future__ import annotations

import warnings

import numpy as np
import qpsolvers

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec, timed
from qpbench.solvers.registry import register, register_unusable

BACKEND = "qpsolvers"
SOLVERS = ("osqp", "clarabel")


def _solve_dual(solver: str):
    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = max(float(np.max(np.abs(problem.b), initial=0.0)), 1e-300)
        options = accuracy.options_for(solver, eps, scale)
        qp = qpsolvers.Problem(P=problem.Q, q=problem.b, lb=np.zeros(problem.n_contacts))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            solution, seconds = timed(
                lambda: qpsolvers.solve_problem(qp, solver=solver, initvals=warm_start, **options)
            )
        extras = getattr(solution, "extras", {}) or {}
        info = extras.get("info")
        iterations = getattr(info, "iter", None) if info is not None else None
        status = getattr(info, "status", None) if info is not None else None
        return SolverOutput(
            impulses=solution.x if solution.x is not None else None,
            status=str(status if status is not None else ("found" if solution.found else "failed")),
            claimed_success=bool(solution.found),
            solve_time_s=seconds,
            iterations=int(iterations) if iterations is not None else None,
        )

    return solve


for _name in SOLVERS:
    if _name in qpsolvers.available_solvers:
        register(SolverSpec(name=_name, formulation="dual", backend=BACKEND,
                            solve=_solve_dual(_name), version=qpsolvers.__version__,
                            warm_start=True))
    else:
        register_unusable(_name, ("dual",), BACKEND, f"qpsolvers has no '{_name}' installed")
