"""pi-robust's interior point with and without Gondzio's centrality correctors.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_correctors.py COUNT... [--quick]
[--bodies N,N,...] [--steps K] [--grids S,S,...] [--seeds A-B] [--repeats R]
[--trajectory]``, e.g. ``0 3``. The problems are the impacts of the first K steps (3 unless
given) of dense piles of circles and of boxes (``qpbench scaling``'s scenes; 1,000 and 10,000
circles and 1,000 boxes unless ``--bodies`` gives the circle counts; the box pile has the
smallest of them), captured with the correctors off, and generated grids of S balls a side
(30 and 40 unless given; seeds A-B, 4100-4102 unless given): the sets where pi-robust's
interior point runs (its Python path). Each is solved cold at 1e-8 with
``lcp_interior.CENTRALITY_CORRECTORS`` set to each COUNT given, in rounds (each round every
problem once per count, the counts in a rotated order; R rounds, 3 unless given): the
interior point's iterations (one factorization each), pi-robust's linear solves, failures
(qpbench's residual above 1e-8) and the sum of each problem's fastest ``time_s``.

``--trajectory``: instead, the 1,000-circle pile (or the first of ``--bodies``) is simulated
K steps (6 unless given) once per count, pi-robust its inner solver with that count: per
step, the contacts the simulator found and the interior point's iterations, and on the first
step how far apart the two answers' velocities ``M^-1 G l`` are. ``--quick``: the 1,000-body
piles and the 30-ball grid, 2 steps, 1 round.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pi_robust_common import (
    ACCURACY,
    T,
    captured_impacts,
    option,
    quick_flag,
    with_constant,
    words,
)

from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.simulation.scaling import PILES
from qpbench.solvers import lcp_interior
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver


def with_correctors(count: int, action: Callable[[], T]) -> T:
    """``action()`` with ``lcp_interior.CENTRALITY_CORRECTORS = count``."""
    return with_constant(lcp_interior, "CENTRALITY_CORRECTORS", count, action)


def problem_groups(circles: list[int], steps: int, grids: list[int], seeds: range
                   ) -> list[tuple[str, list[ImpactProblem]]]:
    """(name, problems) of each group, the piles captured with the correctors off."""
    groups = []
    for bodies in circles:
        groups.append((f"circle pile {bodies}, steps 0-{steps - 1}", with_correctors(
            0, lambda bodies=bodies: captured_impacts(PILES["circles"](bodies), steps))))
    boxes = min(circles)
    groups.append((f"box pile {boxes}, steps 0-{steps - 1}", with_correctors(
        0, lambda: captured_impacts(PILES["boxes"](boxes), steps))))
    for size in grids:
        groups.append((f"grid {size}, seeds {seeds.start}-{seeds.stop - 1}",
                       [generate("grid", size, seed=seed)[0] for seed in seeds]))
    return groups


def compare(counts: list[int], groups: list[tuple[str, list[ImpactProblem]]],
            rounds: int) -> None:
    """One table row per group and count (module docstring)."""
    spec = get("pi-robust")
    spec.prepare()
    print("\n| group | correctors | interior iterations | solves | failed | time (ms) |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, problems in groups:
        fastest = np.full((len(problems), len(counts)), np.inf)
        iterations = np.zeros(len(counts), dtype=int)
        solves = np.zeros(len(counts), dtype=int)
        failed = np.zeros(len(counts), dtype=int)
        for round_ in range(rounds):
            for index, problem in enumerate(problems):
                order = np.roll(np.arange(len(counts)), round_ + index)
                for column in order:
                    output = with_correctors(counts[column], lambda problem=problem:
                                             call_solver(spec, problem, ACCURACY))
                    fastest[index, column] = min(fastest[index, column], output.time_s)
                    if round_ == 0:
                        iterations[column] += output.info.get("interior_iterations", 0)
                        solves[column] += output.iterations or 0
                        failed[column] += residual(problem, output.impulses) > ACCURACY
        for column, count in enumerate(counts):
            print(f"| {name} | {count} | {iterations[column]} | {solves[column]} | "
                  f"{failed[column]} | {1e3 * fastest[:, column].sum():.0f} |", flush=True)


def trajectory(counts: list[int], bodies: int, steps: int) -> None:
    """Per count, the simulated pile's contacts and interior iterations per step."""
    answers = {}
    spec = get("pi-robust")
    spec.prepare()
    print("\n| correctors | step | contacts | interior iterations | solve (ms) |")
    print("|---:|---:|---:|---:|---:|")
    for count in counts:
        problems = with_correctors(count, lambda: captured_impacts(PILES["circles"](bodies),
                                                                   steps))
        for step, problem in enumerate(problems):
            output = with_correctors(count, lambda problem=problem:
                                     call_solver(spec, problem, ACCURACY))
            if step == 0:
                answers[count] = output.impulses
            print(f"| {count} | {step} | {problem.n_contacts} | "
                  f"{output.info.get('interior_iterations', 0)} | "
                  f"{1e3 * output.time_s:.0f} |", flush=True)
    first, *others = counts
    problem = problems[0]  # step 0 does not depend on any answer
    scale = np.asarray(problem.m_inv).ravel()
    for count in others:
        change = answers[first] - answers[count]
        gap = np.max(np.abs(scale * (problem.G @ change)))
        print(f"\nstep 0, velocities with {first} and {count} correctors: at most {gap:.1e} "
              f"apart (largest impulse change {np.max(np.abs(change)):.1e})")


def main() -> None:
    quick = quick_flag()
    arguments = words()
    circles = [int(word) for word in option(arguments, "--bodies", "1000,10000").split(",")]
    grids = [int(word) for word in option(arguments, "--grids", "30,40").split(",")]
    first, last = (int(word) for word in option(arguments, "--seeds", "4100-4102").split("-"))
    rounds = int(option(arguments, "--repeats", "3"))
    tracing = "--trajectory" in arguments
    if tracing:
        arguments.remove("--trajectory")
    steps = int(option(arguments, "--steps", "6" if tracing else "3"))
    counts = [int(word) for word in arguments] or [0, lcp_interior.CENTRALITY_CORRECTORS]
    if quick:
        circles, grids, steps, rounds = circles[:1], grids[:1], 2, 1
    if tracing:
        trajectory(counts, circles[0], steps)
        return
    compare(counts, problem_groups(circles, steps, grids, range(first, last + 1)), rounds)


if __name__ == "__main__":
    main()
