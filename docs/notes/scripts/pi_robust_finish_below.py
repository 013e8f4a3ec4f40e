"""pi-robust on dense piles and large grids for each residual from which the interior point
that runs first hands its iterates on to policy iteration.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_finish_below.py VALUE... [--quick]
[--bodies N,N,...] [--steps K] [--kinds circles,boxes] [--grids 26,30,40] [--rounds R]``,
e.g. ``1e-4 1e-3``. The value is the accuracy table's ``finish_below`` of pi-robust, which
the interior point that runs first on a sparse problem (a dense pile, a grid of 26 balls a
side and up) hands its iterates on from where the policy blocks are updated (on the grids,
which factor every block afresh, it waits for ``FIRST_FINISH_BELOW`` whatever the value;
the dense paths, which also read ``finish_below``, do not run on these problems). Each pile
(``qpbench scaling``'s scenes; 1,000 and 10,000 bodies unless given) is simulated K steps
(4 unless given) with the current settings and every step's impact problem kept; grids of
the given sizes are generated with seeds 4300-4303. Then every problem is solved cold at
1e-8 with each value in turn, the order reversed every round, R rounds (2 unless given); it
prints per group each step's fastest ``time_s``, their sum, the linear solves and the
failures (qpbench's residual above 1e-8). ``--quick``: the 1,000-circle pile, 2 steps, no
grids.
"""

from __future__ import annotations

import numpy as np
from pi_robust_common import ACCURACY, captured_impacts, option, quick_flag, with_row, words

from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.simulation.scaling import PILES
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

GRID_SEEDS = range(4300, 4304)


def compare(name: str, problems: list[ImpactProblem], values: list[float], rounds: int,
            spec: SolverSpec) -> None:
    """Print one group's row per value: the fastest time of each problem, their sum, solves
    and failures."""
    fastest = np.full((len(values), len(problems)), np.inf)
    solves = np.zeros(len(values), dtype=int)
    failed = np.zeros(len(values), dtype=int)
    for turn in range(rounds):
        order = list(range(len(values)))
        for index, problem in enumerate(problems):
            for column in order if turn % 2 == 0 else order[::-1]:
                output = with_row("finish_below", values[column],
                                  lambda problem=problem: call_solver(spec, problem, ACCURACY))
                fastest[column, index] = min(fastest[column, index], output.time_s)
                if turn == 0:
                    solves[column] += output.iterations or 0
                    failed[column] += residual(problem, output.impulses) > ACCURACY
    for column, value in enumerate(values):
        steps = " / ".join(f"{1e3 * seconds:.0f}" for seconds in fastest[column])
        print(f"| {name} | {value:g} | {steps} | {1e3 * fastest[column].sum():.0f} | "
              f"{solves[column]} | {failed[column]} |", flush=True)


def main() -> None:
    quick = quick_flag()
    arguments = words()
    sizes = [int(word) for word in option(arguments, "--bodies", "1000,10000").split(",")]
    kinds = option(arguments, "--kinds", ",".join(PILES)).split(",")
    grids = [int(word) for word in option(arguments, "--grids", "26,30,40").split(",") if word]
    steps = int(option(arguments, "--steps", "4"))
    rounds = int(option(arguments, "--rounds", "2"))
    if quick:
        kinds, sizes, steps, grids = ["circles"], sizes[:1], min(steps, 2), []
    values = [float(word) for word in arguments]
    spec = get("pi-robust")
    spec.prepare()
    print("\n| group | finish_below | fastest time_s per problem (ms) | sum (ms) | solves | "
          "failed |")
    print("|---|---:|---|---:|---:|---:|")
    for kind in kinds:
        for bodies in sizes:
            compare(f"{kind} {bodies}, steps 0-{steps - 1}",
                    captured_impacts(PILES[kind](bodies), steps), values, rounds, spec)
    for size in grids:
        compare(f"grid {size}, seeds {GRID_SEEDS[0]}-{GRID_SEEDS[-1]}",
                [generate("grid", size, seed=seed)[0] for seed in GRID_SEEDS], values, rounds,
                spec)


if __name__ == "__main__":
    main()
