"""Where pi-robust's compiled kernel should hand large problems to the sparse path.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_work_limit.py LIMIT... [--quick]``,
e.g. ``1e7 2.5e6``. For each value of the accuracy table's ``compiled_work_limit`` (the most
multiply-adds one envelope factorization may cost before the kernel declines and the sparse
path, with CHOLMOD, runs), it prints solves, factorizations, failures and time on grids of
16x16 to 30x30 balls, fresh seeds each, and on the impacts of the first three steps of a
dense pile of 1,000 circles, next to each group's envelope work (reverse Cuthill-McKee
order, the kernel's own functions). Without ``--quick`` (two seeds) it runs five seeds.
"""

from __future__ import annotations

import ast

import numpy as np
from pi_robust_common import quick_flag, run, table, with_row, words

from qpbench.inner_solvers import choose_by_name
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.simulation.scaling import PILES
from qpbench.simulation.stepper import Simulator
from qpbench.solvers.pi_robust_kernel.ordering import (
    _envelope_work,
    _permuted,
    reverse_cuthill_mckee,
)

SEED_BASE = 7_000  # seeds nobody tuned on


def envelope_work(problem: ImpactProblem) -> float:
    """One factorization's multiply-adds over Q's whole envelope in reverse Cuthill-McKee
    order."""
    copy = problem.blind_copy()
    pose(copy, "lcp")
    Q = copy.Q
    n = Q.shape[0]
    indptr, indices = Q.indptr.astype(np.int64), Q.indices.astype(np.int64)
    widths = np.empty(n + 1, dtype=np.int64)
    order = reverse_cuthill_mckee(indptr, indices, n)
    _permuted(indptr, indices, Q.data, order, widths,
              (np.empty(n + 1, dtype=np.int64), np.empty(indices.size, dtype=np.int64),
               np.empty(indices.size)))
    return float(_envelope_work(widths))


def pile_impacts(bodies: int, steps: int) -> list[ImpactProblem]:
    """The impact problems of the first ``steps`` steps of a dense circle pile."""
    simulator = Simulator(PILES["circles"](bodies), choose_by_name("pi-robust"))
    captured: list[ImpactProblem] = []
    make = simulator.impact_problem

    def capture(*arguments: object, **keywords: object) -> ImpactProblem:
        problem = make(*arguments, **keywords)
        captured.append(problem)
        return problem

    simulator.impact_problem = capture  # type: ignore[method-assign]
    for _ in range(steps):
        simulator.step()
    for problem in captured:
        problem.posed.clear()
    return captured


def main() -> None:
    limits = [ast.literal_eval(word) for word in words()]
    quick = quick_flag()
    seeds = range(SEED_BASE, SEED_BASE + (2 if quick else 5))
    groups = [(f"grid {size}", [generate("grid", size, seed=seed)[0] for seed in seeds])
              for size in (16, 20, 24, 26, 30)]
    groups.append(("circle pile 1000, steps 0-2", pile_impacts(1000, 3)))
    results, names = {}, []
    for name, problems in groups:
        works = [envelope_work(problem) for problem in problems]
        name = f"{name} (work {min(works):.1e}-{max(works):.1e})"
        names.append(name)
        for limit in limits:
            results[name, repr(limit)] = with_row(
                "compiled_work_limit", limit, lambda problems=problems: run(problems, 3))
    table(f"pi-robust at 1e-8, compiled_work_limit = {' / '.join(map(repr, limits))}",
          [repr(limit) for limit in limits], results, names)


if __name__ == "__main__":
    main()
