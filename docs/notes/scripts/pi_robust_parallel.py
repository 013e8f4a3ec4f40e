"""pi-robust with and without its presolve of parallel contacts.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_parallel.py [--quick]
[--first-seed N]``. Both variants run in one process, in a fresh order every round:

- ``whole``: the compiled entry ``envelope_pi_robust`` on the whole problem (no presolve),
  as ``solve`` called it before the presolve;
- ``presolved``: ``pi_robust.kernel_into`` as ``solve`` calls it now (``pi_robust_into``:
  the problem without its looser parallel contacts first, when it has any).

Before every timed call, one of the research fork's 5x5 grid dumps is solved by DAQP, PIQP
and quadprog through their own APIs, as the head-to-head interleaves other pairs. It prints
per group the linear solves and factorizations of one solve of each problem, the problems
above 1e-8 (qpbench's residual), and the sum over the problems of each one's fastest call
over the rounds (20, 5 with ``--quick``). The groups: near-duplicate grids of 4, 6 and 8
balls a side (every ball-ball contact captured twice, the copy turned by about 1e-9 rad), and,
with no parallel contacts, grids of 7 balls a side, K3, K4 and cradles of 3 balls, and twelve
of the fork's dumps; generated with seeds from ``--first-seed`` (900 by default).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
from pi_robust_common import ACCURACY, ROOT, kernel_arguments, option, quick_flag, solvers_between

from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import pi_robust
from qpbench.solvers.pi_robust_kernel import entry
from qpbench.solvers.run import call_solver


def groups(quick: bool, first: int) -> dict[str, list[ImpactProblem]]:
    """The problem groups of the module docstring, posed as ``lcp``."""
    count = 2 if quick else 6
    seeds = range(first, first + count)
    chosen = {f"near-duplicate {size}": [generate("near-duplicate", size, seed=seed)[0]
                                         for seed in seeds] for size in (4, 6, 8)}
    chosen["grid 7"] = [generate("grid", 7, seed=seed)[0] for seed in seeds]
    chosen["K3, K4, cradle 3"] = [generate(family, size, seed=seed)[0] for family, size in
                                  (("k3", None), ("k4", None), ("cradle", 3)) for seed in seeds]
    dumps = sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))
    chosen["fork 5x5 dumps"] = [import_dump(path) for path in dumps[20:20 + 2 * count]]
    for problems in chosen.values():
        for problem in problems:
            pose(problem, "lcp")
    return chosen


def whole(problem: ImpactProblem) -> tuple[np.ndarray, int, int]:
    """l, solves and factorizations of the wide entry on the whole problem."""
    answer = entry.envelope_pi_robust(*kernel_arguments(problem))
    return answer[0], answer[3], answer[5]


def presolved(problem: ImpactProblem) -> tuple[np.ndarray, int, int]:
    """l, solves and factorizations of the narrow entry, with its presolve."""
    impulses, answer = pi_robust.kernel_into(problem, pi_robust.settings_for(ACCURACY), None)
    return impulses, answer[2], answer[4]


def main() -> None:
    quick = quick_flag()
    rounds = 5 if quick else 20
    pi_robust.prepare()
    others = solvers_between()
    between = [import_dump(path) for path in
               sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))[:20]]
    for problem in between:
        pose(problem, "lcp")
    variants: dict[str, Callable[[ImpactProblem], tuple[np.ndarray, int, int]]] = {
        "whole": whole, "presolved": presolved}
    generator = np.random.default_rng(0)
    print(f"\nsums over each group's problems; time: each problem's fastest of {rounds} calls, "
          "DAQP, PIQP and quadprog solving a dump before every call\n")
    print("| group | variant | solves | factorizations | above 1e-8 | time (us) |")
    print("|---|---|---:|---:|---:|---:|")
    first = int(option(sys.argv[1:], "--first-seed", "900"))
    for name, problems in groups(quick, first).items():
        fastest = {(variant, index): np.inf for variant in variants
                   for index in range(len(problems))}
        for number in range(rounds):
            for index in generator.permutation(len(problems)):
                for variant in generator.permutation(list(variants)):
                    for spec in others:
                        call_solver(spec, between[number % len(between)], ACCURACY)
                    start = time.perf_counter()
                    variants[variant](problems[index])
                    elapsed = time.perf_counter() - start
                    fastest[variant, index] = min(fastest[variant, index], elapsed)
        for variant, solve in variants.items():
            answers = [solve(problem) for problem in problems]
            above = sum(metrics.residual(problem, impulses) > ACCURACY
                        for problem, (impulses, _, _) in zip(problems, answers, strict=True))
            total = sum(fastest[variant, index] for index in range(len(problems)))
            print(f"| {name} | {variant} | {sum(answer[1] for answer in answers)} | "
                  f"{sum(answer[2] for answer in answers)} | {above} | {1e6 * total:.0f} |")


if __name__ == "__main__":
    sys.exit(main())
