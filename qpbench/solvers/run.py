"""One solve, judged: call a solver, never let it crash the caller, measure the answer."""

from __future__ import annotations

import math
import traceback
from typing import Any

import numpy as np

from qpbench import metrics
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec


def call_solver(spec: SolverSpec, problem: ImpactProblem, accuracy: float,
                warm_start: np.ndarray | None = None) -> SolverOutput:
    """``spec.solve`` with any exception turned into an output with status ``error: ...``."""
    assert spec.solve is not None, f"{spec.key} is not usable: {spec.reason}"
    try:
        output = spec.solve(problem, accuracy, warm_start)
    except Exception as error:  # a backend that raises is a failed solve, not a failed run
        last = traceback.extract_tb(error.__traceback__)[-1:]
        where = f" at {last[0].filename.rsplit('/', 1)[-1]}:{last[0].lineno}" if last else ""
        return SolverOutput(impulses=None, status=f"error: {type(error).__name__}: {error}{where}",
                            claimed_success=False, solve_time_s=math.nan)
    if output.impulses is not None:
        output.impulses = np.asarray(output.impulses, dtype=float).ravel()
    return output


def judge(spec: SolverSpec, problem: ImpactProblem, output: SolverOutput,
          accuracy: float) -> dict[str, Any]:
    """The result row of one solve: qpbench's metrics and verdict next to the solver's claim.

    ``status`` is qpbench's verdict (``solved`` / ``inaccurate`` / ``failed``);
    ``solver_status`` is the backend's own; ``status_honest`` is whether its claim agreed.
    """
    measured = metrics.evaluate(problem, output.impulses, accuracy)
    if measured["success"]:
        status = "solved"
    elif metrics.is_finite(output.impulses, problem):
        status = "inaccurate"
    else:
        status = "failed"
    return {
        "solver": spec.name,
        "formulation": spec.formulation,
        "backend": spec.backend,
        "solver_version": spec.version,
        "accuracy": accuracy,
        "status": status,
        "solver_status": output.status,
        "claimed_success": output.claimed_success,
        "status_honest": bool(output.claimed_success == measured["success"]),
        **measured,
        "iterations": output.iterations,
        "time_s": output.solve_time_s,
        "setup_time_s": output.setup_time_s,
    }


def solve_and_judge(spec: SolverSpec, problem: ImpactProblem, accuracy: float,
                    warm_start: np.ndarray | None = None) -> tuple[dict[str, Any], SolverOutput]:
    """call_solver then judge."""
    output = call_solver(spec, problem, accuracy, warm_start)
    return judge(spec, problem, output, accuracy), output
