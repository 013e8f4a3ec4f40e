"""pi-robust on dense piles for each prox weight of the updated finish.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_finish_rho.py RHO... [--quick]
[--bodies N,N,...] [--steps K]``, e.g. ``1e-5 1e-7 1e-9 1e-11``. It simulates dense piles of
circles and of boxes (``qpbench scaling``'s scenes; 1,000 and 3,000 bodies unless given) for
K steps (4 unless given) with pi-robust at the first value given of ``UPDATED_FINISH_RHO``
(the prox weight of the policy iteration that finishes the interior point's iterates where the
policy blocks are updated), keeps every step's impact problem, and then solves each of them
cold at 1e-8 once for every value given. The first value makes the problems: a step's
contacts follow from the answers of the steps before, and a more exact answer can make the
next step easier. It prints per problem the linear solves, failures (qpbench's residual
above 1e-8) and ``time_s``, and the sums. ``--quick``: the 1,000-body piles, 2 steps.
"""

from __future__ import annotations

import numpy as np
from pi_robust_common import (
    ACCURACY,
    captured_impacts,
    option,
    quick_flag,
    with_constant,
    words,
)

from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.simulation.scaling import PILES
from qpbench.solvers import pi_robust
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver


def pile_impacts(kind: str, bodies: int, steps: int, finish_rho: float
                 ) -> list[ImpactProblem]:
    """The impact problems of the first ``steps`` steps of a pile, as the simulator captures
    them, pi-robust its inner solver with ``UPDATED_FINISH_RHO = finish_rho``."""
    return with_constant(pi_robust, "UPDATED_FINISH_RHO", finish_rho,
                         lambda: captured_impacts(PILES[kind](bodies), steps))


def main() -> None:
    quick = quick_flag()
    arguments = words()
    sizes = [int(word) for word in option(arguments, "--bodies", "1000,3000").split(",")]
    steps = int(option(arguments, "--steps", "4"))
    if quick:
        sizes, steps = sizes[:1], min(steps, 2)
    values = [float(word) for word in arguments] or [pi_robust.UPDATED_FINISH_RHO]
    spec = get("pi-robust")
    spec.prepare()
    header = " | ".join(f"{value:g}: solves, ms" for value in values)
    for kind in PILES:
        for bodies in sizes:
            problems = pile_impacts(kind, bodies, steps, values[0])
            print(f"\n{kind}, {bodies} bodies, steps 0-{steps - 1}\n")
            print(f"| step | contacts | {header} |")
            print("|---:|---:|" + "---:|" * len(values))
            totals = np.zeros(len(values))
            for step, problem in enumerate(problems):
                cells = []
                for column, value in enumerate(values):
                    output = with_constant(pi_robust, "UPDATED_FINISH_RHO", value,
                                           lambda problem=problem:
                                           call_solver(spec, problem, ACCURACY))
                    totals[column] += output.time_s
                    failed = residual(problem, output.impulses) > ACCURACY
                    cells.append(f"{output.iterations or 0}, {1e3 * output.time_s:.0f}"
                                 + (" failed" if failed else ""))
                print(f"| {step} | {problem.n_contacts} | " + " | ".join(cells) + " |",
                      flush=True)
            print("| all | | " + " | ".join(f"{1e3 * total:.0f}" for total in totals) + " |")


if __name__ == "__main__":
    main()
