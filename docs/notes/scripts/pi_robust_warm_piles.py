"""pi-robust on settling piles from the previous step's impulses, against a cold start.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_warm_piles.py LIMIT... [--quick]
[--bodies N]``, e.g. ``-1 64 inf``. It simulates dense piles of N (1,000 unless given)
circles (12 steps) and N boxes (8 steps) as ``qpbench scaling`` builds them, with the
impulses of each step carried to the next (SCISim's ``cache_impulses``), and keeps every
step's impact problem and its warm start. For each value of ``NEAR_START_INFEASIBLE`` (a
warm start is followed by policy iteration when one solve of its policy leaves at most that
many contacts infeasible; -1 never, inf always) it prints per problem the linear solves,
failures and fastest ``time_s`` of the warm-started solve, beside the cold solve's, and the
sums. Steps whose start already solves the problem (no solve at all, whatever the value) are
counted apart. ``--quick``: the circles only, 6 steps, one repeat.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pi_robust_common import ACCURACY, captured_impacts, option, quick_flag, words

from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.simulation.scaling import PILES
from qpbench.solvers import pi_robust
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver


def warm_started_impacts(kind: str, bodies: int, steps: int
                         ) -> list[tuple[ImpactProblem, np.ndarray]]:
    """(problem, warm start) of each step of a pile whose scene caches impulses, the first
    step (no impulses to carry) left out: the simulator's own capture, which stores each
    impact with the impulses it carried (``warm_start``)."""
    scene = PILES[kind](bodies)
    scene = dataclasses.replace(scene, impact=dataclasses.replace(scene.impact,
                                                                  cache_impulses=True))
    return [(problem, problem.data["warm_start"]) for problem in captured_impacts(scene, steps)
            if np.any(problem.data.get("warm_start", 0.0))]


def timed(problem: ImpactProblem, warm: np.ndarray | None, repeats: int
          ) -> tuple[int, bool, float]:
    """(linear solves, failed, fastest time_s) of pi-robust at ``ACCURACY``."""
    spec = get("pi-robust")
    outputs = [call_solver(spec, problem, ACCURACY, warm) for _ in range(repeats)]
    first = outputs[0]
    failed = bool(residual(problem, first.impulses) > ACCURACY)
    return first.iterations or 0, failed, min(output.time_s for output in outputs)


def main() -> None:
    quick = quick_flag()
    arguments = words()
    bodies = int(option(arguments, "--bodies", "1000"))
    limits = [float(word) for word in arguments] or [-1.0, 64.0, np.inf]
    repeats = 1 if quick else 2
    piles = [("circles", bodies, 6 if quick else 12)] + ([] if quick else [("boxes", bodies, 8)])
    get("pi-robust").prepare()
    saved = pi_robust.NEAR_START_INFEASIBLE
    header = " | ".join(f"warm, {limit:g}: solves, ms" for limit in limits)
    for kind, bodies, steps in piles:
        posed = warm_started_impacts(kind, bodies, steps)
        print(f"\n{kind}, {bodies} bodies, steps 2-{steps}\n")
        print(f"| step | contacts | cold: solves, ms | {header} |")
        print("|---:|---:|---:|" + "---:|" * len(limits))
        totals = np.zeros(len(limits) + 1)
        started_solved = 0
        for step, (problem, warm) in enumerate(posed, start=2):
            cells = []
            for column, limit in enumerate([None, *limits]):  # None: the cold solve
                pi_robust.NEAR_START_INFEASIBLE = saved if limit is None else limit
                solves, failed, seconds = timed(problem, None if limit is None else warm,
                                                repeats)
                totals[column] += seconds
                cells.append(f"{solves}, {1e3 * seconds:.1f}" + (" failed" if failed else ""))
                started_solved += column == 1 and solves == 0
            pi_robust.NEAR_START_INFEASIBLE = saved
            print(f"| {step} | {problem.n_contacts} | " + " | ".join(cells) + " |", flush=True)
        print(f"| all | | {1e3 * totals[0]:.1f} | "
              + " | ".join(f"{1e3 * total:.1f}" for total in totals[1:]) + " |")
        print(f"\nsteps whose warm start already solved the problem: {started_solved}")


if __name__ == "__main__":
    main()
