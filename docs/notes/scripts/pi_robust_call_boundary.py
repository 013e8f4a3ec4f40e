"""What the call itself costs pi-robust on small problems when other solvers ran in between.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_call_boundary.py [--quick]``. Before
every timed call, one of the research fork's 5x5 grid dumps is solved by DAQP, PIQP and
quadprog through their own APIs (``call_solver``), as the head-to-head interleaves other
pairs. Then one of these is timed, in an order drawn afresh every round:

- ``solve``: pi-robust's solve function (``qpbench.solvers.pi_robust.solve``), what the
  harness's stopwatch holds, less the harness;
- ``narrow``: the compiled entry ``pi_robust_into`` as ``solve`` calls it
  (``pi_robust.kernel_into``: six arrays in, l written into one of them, six scalars back);
- ``wide``: the compiled entry ``envelope_pi_robust`` alone (nine arguments in, a new array
  and six scalars back), through numba's dispatcher;
- ``wide, entry point``: the same compiled overload called past the dispatcher (no typing of
  the arguments);
- ``empty, wide``: a compiled function of the wide entry's nine arguments that returns a copy
  of b and six scalars, and nothing else: the call boundary alone;
- ``empty, narrow``: one of the narrow entry's six arguments that copies b into the array
  made for l and returns six scalars;
- ``empty, one integer``: the wide one's arguments, returning one integer.

It prints the median over the rounds (30, 10 with ``--quick``) and problems of each, for
problems of a few contacts (three K3, three K4 and three cradles of 3 balls) and for six dumps.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
from numba import njit
from pi_robust_common import ACCURACY, ROOT, kernel_arguments, solvers_between

from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import pi_robust
from qpbench.solvers.pi_robust_kernel import entry
from qpbench.solvers.run import call_solver


@njit
def _empty_kernel(indptr, indices, data, b, diag, warm_start, order_above, work_limit,
                  options):
    return b.copy(), True, 1, 0, 0, 0, True


@njit
def _empty_narrow_kernel(indptr, indices, data, b, out, call_options):
    out[:] = b
    return True, 1, 0, 0, 0, True


@njit
def _empty_kernel_integer(indptr, indices, data, b, diag, warm_start, order_above, work_limit,
                          options):
    return 1


def main() -> None:
    rounds = 10 if "--quick" in sys.argv[1:] else 30
    pi_robust.prepare()
    others = solvers_between()
    small = [generate(family, size, seed=seed)[0] for family, size in
             (("k3", None), ("k4", None), ("cradle", 3)) for seed in range(3)]
    dumps = [import_dump(path) for path in
             sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))[:6]]
    for problem in small + dumps:
        pose(problem, "lcp")
    arguments = kernel_arguments(small[0])
    signature = tuple(entry.envelope_pi_robust.typeof_pyval(value) for value in arguments)
    entry_point = entry.envelope_pi_robust.overloads[signature].entry_point
    settings = pi_robust.settings_for(ACCURACY)

    def empty_narrow(problem: ImpactProblem) -> object:
        Q = problem.Q
        impulses = np.empty(problem.b.size)
        impulses[0] = np.nan
        return _empty_narrow_kernel(Q.indptr, Q.indices, Q.data, problem.b, impulses,
                                    settings.call_options)

    _empty_kernel(*arguments)
    _empty_kernel_integer(*arguments)
    empty_narrow(small[0])
    variants: dict[str, Callable[[ImpactProblem], object]] = {
        "solve": lambda problem: pi_robust.solve(problem, ACCURACY),
        "narrow": lambda problem: pi_robust.kernel_into(problem, settings, None),
        "wide": lambda problem: entry.envelope_pi_robust(*kernel_arguments(problem)),
        "wide, entry point": lambda problem: entry_point(*kernel_arguments(problem)),
        "empty, wide": lambda problem: _empty_kernel(*kernel_arguments(problem)),
        "empty, narrow": empty_narrow,
        "empty, one integer": lambda problem: _empty_kernel_integer(*kernel_arguments(problem)),
    }
    generator = np.random.default_rng(0)
    print(f"\nmedian over {rounds} rounds, DAQP, PIQP and quadprog solving a dump before every "
          "call (us)\n")
    print("| call | " + " | ".join(variants) + " |")
    print("|---|" + "---:|" * len(variants))
    for group, problems in (("K3, K4, cradle of 3", small), ("fork 5x5 dumps", dumps)):
        times: dict[str, list[float]] = {name: [] for name in variants}
        for number in range(rounds):
            for problem in problems:
                for name in generator.permutation(list(variants)):
                    for spec in others:
                        call_solver(spec, dumps[number % len(dumps)], ACCURACY)
                    start = time.perf_counter()
                    variants[name](problem)
                    times[name].append(time.perf_counter() - start)
        print(f"| {group} | " + " | ".join(f"{1e6 * np.median(times[name]):.1f}"
                                           for name in variants) + " |")


if __name__ == "__main__":
    main()
