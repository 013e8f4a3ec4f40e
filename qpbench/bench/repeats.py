"""Repeated timing of one solve: the fastest of a few, as the head-to-head and the sequence
mode time their solves (the main benchmark has its own ``--repeats``).

A solve's ``time_s`` varies from run to run with what else the machine does; the fastest of a
few repeats is the least disturbed. Repeats stop once they have taken ``REPEAT_BUDGET_S`` in
all: a slow solve varies little, and repeating it would only take the benchmark's time.
"""

from __future__ import annotations

import numpy as np

from qpbench.bench.defaults import REPEATS
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.run import call_solver

REPEAT_BUDGET_S = 0.2


def fastest_solve(spec: SolverSpec, problem: ImpactProblem | FrictionalProblem,
                  accuracy: float, repeats: int = REPEATS,
                  warm_start: np.ndarray | None = None) -> SolverOutput:
    """The output of the fastest of up to ``repeats`` solves of ``problem`` by ``spec``
    through the one stopwatch (``call_solver``), each from the same warm start; fewer once
    they have taken ``REPEAT_BUDGET_S`` in all."""
    outputs = [call_solver(spec, problem, accuracy, warm_start)]
    while len(outputs) < repeats and sum(output.time_s for output in outputs) < REPEAT_BUDGET_S:
        outputs.append(call_solver(spec, problem, accuracy, warm_start))
    return min(outputs, key=lambda output: output.time_s)
