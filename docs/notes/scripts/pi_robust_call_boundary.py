"""What the call itself costs pi-robust on small problems when other solvers ran in between.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_call_boundary.py [--quick]``. Before
every timed call, other solvers each solve a problem through their own APIs
(``call_solver``), as the head-to-head and the sequence mode interleave other pairs: DAQP,
PIQP and quadprog in the first table; those and OSQP, ProxQP, QPALM, SCS and Clarabel (eight)
in the second, about as many as the sequence mode runs. Then one of these is timed, in an order
drawn afresh every round:

- ``time_s``: pi-robust's ``time_s`` through the harness's stopwatch (``call_solver``): its
  settings read, the kernel's narrow entry ``pi_robust_into`` called past numba's dispatcher
  (``pi_robust_kernel.call``), from zero by its options, the output built;
- ``time_s, as before``: the same with pi-robust's solve as it was made before that,
  statement for statement (the array for l marked "from zero" by writing NaN into it, the
  narrow entry through numba's dispatcher), and ``difference``: the median over rounds and
  problems of the two figures' difference, each pair timed in the same round;
- ``kernel, direct`` / ``kernel, dispatcher``: the narrow entry alone, as ``solve`` calls it
  now (``pi_robust_call.kernel_into``) and as before, timed around the call;
- ``empty, direct`` / ``empty, dispatcher``: a compiled function of the narrow entry's six
  arguments that copies b into the array made for l and returns six scalars: the call
  boundary alone, past the dispatcher and through it.

It prints the median over the rounds (20, 5 with ``--quick``) and problems of each, for
problems of a few contacts (three K3, three K4 and three cradles of 3 balls), for impacts of
two scenes of the sequence mode (``butterfly``, 1-3 contacts, and ``balls_in_box_100``,
20-100 contacts; the first nine of each) and for six of the fork's 5x5 dumps.
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import time
from collections.abc import Callable

import numpy as np
from numba import njit
from pi_robust_common import ACCURACY, ROOT, captured_impacts

from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes import load_scene
from qpbench.solvers import pi_robust, pi_robust_call
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.pi_robust_kernel import entry
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

FEW = ("daqp-native/dual", "piqp-native/dual", "quadprog-native/dual")
MANY = (*FEW, "osqp-native/primal", "proxqp-native/dual", "qpalm-native/dual",
        "scs-native/primal", "clarabel-native/dual")


@njit
def _empty_narrow_kernel(indptr, indices, data, b, out, call_options):
    out[:] = b
    return True, 1, 0, 0, 0, True


settings_as_before = functools.lru_cache(maxsize=64)(pi_robust_call.settings_for)


def kernel_into_as_before(problem: ImpactProblem, settings: pi_robust_call.Settings,
                          warm_start: np.ndarray | None) -> tuple[np.ndarray, tuple]:
    """``pi_robust.kernel_into`` as it was before the direct call (the same statements)."""
    n = problem.b.size
    impulses = np.empty(n)
    if warm_start is not None and np.size(warm_start) == n:
        impulses[:] = np.ravel(warm_start)
    else:
        impulses[0] = np.nan
    Q = problem.Q
    return impulses, entry.pi_robust_into(Q.indptr, Q.indices, Q.data, problem.b, impulses,
                                          settings.call_options)


def solve_as_before(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
                    ) -> SolverOutput:
    """``pi_robust.solve`` as it was before the direct call (the same statements), on a
    problem the kernel certifies (every problem here)."""
    settings = settings_as_before(eps)
    n = problem.b.size
    compiled = 0 < n <= settings.compiled_limit
    if compiled:
        kernel = entry
        try:
            impulses, answer = kernel_into_as_before(problem, settings, warm_start)
        except np.linalg.LinAlgError:
            answer = None
        if answer is not None:
            converged, path, solves, interior, factorizations, certified = answer
            if certified and path % kernel.PATH_PARALLEL_DROPPED != kernel.PATH_INTERIOR:
                return SolverOutput(impulses, "converged", True, solves, {},
                                    {"path": kernel.PATH_NAMES[path], "compiled": True,
                                     "factorizations": factorizations,
                                     "confirmed_by": "rounding bound"})
    raise AssertionError("not certified by the kernel")


def scene_impacts(path: str, steps: int) -> list[ImpactProblem]:
    return captured_impacts(load_scene(ROOT / path), steps)[:9]


def set_up(names: tuple[str, ...]) -> list[SolverSpec]:
    specs = [get(name) for name in names]
    for spec in specs:
        if spec.prepare is not None:
            spec.prepare()
    return specs


def main() -> None:
    rounds = 5 if "--quick" in sys.argv[1:] else 20
    pi_robust.prepare()
    dumps = [import_dump(path) for path in
             sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))[:6]]
    groups = {
        "K3, K4, cradle of 3": [generate(family, size, seed=seed)[0] for family, size in
                                (("k3", None), ("k4", None), ("cradle", 3))
                                for seed in range(3)],
        "butterfly": scene_impacts("problems/scenes/scisim/butterfly.xml", 400),
        "balls_in_box_100": scene_impacts("problems/scenes/ura/balls_in_box_100.xml", 60),
        "fork 5x5 dumps": dumps}
    for problems in groups.values():
        for problem in problems:
            pose(problem, "lcp")
    settings = pi_robust.settings_for(ACCURACY)
    spec = get("pi-robust/lcp")
    spec_as_before = dataclasses.replace(spec, solve=solve_as_before)

    def empty_arguments(problem: ImpactProblem) -> tuple:
        Q = problem.Q
        return (Q.indptr, Q.indices, Q.data, problem.b, np.empty(problem.b.size),
                settings.call_options_from_zero)

    arguments = empty_arguments(groups["K3, K4, cradle of 3"][0])
    _empty_narrow_kernel(*arguments)
    empty_direct = _empty_narrow_kernel.overloads[tuple(
        _empty_narrow_kernel.typeof_pyval(value) for value in arguments)].entry_point

    def timed(call: Callable[[ImpactProblem], object]) -> Callable[[ImpactProblem], float]:
        def seconds(problem: ImpactProblem) -> float:
            start = time.perf_counter()
            call(problem)
            return time.perf_counter() - start
        return seconds

    variants: dict[str, Callable[[ImpactProblem], float]] = {
        "time_s": lambda problem: call_solver(spec, problem, ACCURACY).time_s,
        "time_s, as before": lambda problem: call_solver(spec_as_before, problem,
                                                         ACCURACY).time_s,
        "kernel, direct": timed(lambda problem: pi_robust_call.kernel_into(problem, settings,
                                                                           None)),
        "kernel, dispatcher": timed(lambda problem: kernel_into_as_before(problem, settings,
                                                                          None)),
        "empty, direct": timed(lambda problem: empty_direct(*empty_arguments(problem))),
        "empty, dispatcher": timed(lambda problem: _empty_narrow_kernel(
            *empty_arguments(problem))),
    }
    for problems in groups.values():  # the same answers either way
        for problem in problems:
            assert np.array_equal(pi_robust.solve(problem, ACCURACY).impulses,
                                  solve_as_before(problem, ACCURACY).impulses)
    generator = np.random.default_rng(0)
    for between in (FEW, MANY):
        others = set_up(between)
        print(f"\nmedian over {rounds} rounds, {len(others)} solvers solving a dump before "
              "every call (us)\n")
        print("| problems | " + " | ".join(variants) + " | difference |")
        print("|---|" + "---:|" * (len(variants) + 1))
        for group, problems in groups.items():
            times: dict[str, list[float]] = {name: [] for name in variants}
            for number in range(rounds):
                for problem in problems:
                    for name in generator.permutation(list(variants)):
                        for other in others:
                            call_solver(other, dumps[number % len(dumps)], ACCURACY)
                        times[name].append(variants[name](problem))
            difference = np.median(np.subtract(times["time_s"], times["time_s, as before"]))
            print(f"| {group} | " + " | ".join(f"{1e6 * np.median(times[name]):.1f}"
                                               for name in variants)
                  + f" | {1e6 * difference:+.1f} |", flush=True)

if __name__ == "__main__":
    main()
