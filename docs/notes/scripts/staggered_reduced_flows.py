"""Staggered projections on Siconos' reduced granular flows, where they stop short of 1e-8.

Usage: ``.venv/bin/python docs/notes/scripts/staggered_reduced_flows.py [--quick]
[--rounds N]``. The reduced granular flows on a wall (``../shared/siconos/fc2d``, 667, 2,020
and 7,002 contacts, mu = 0.5; ``--quick``: the first two) are imported without references.
For each it prints, as Markdown tables:

1. the groups of coupled contacts (``friction_reference.components``) and the largest;
2. ``pi-robust/staggered`` (the compiled loop) with the accuracy table's ``max_outer`` at 200
   (the table's own) and ``--rounds`` (default 2,000, the head-to-head's budget), plain
   (``anderson_depth`` 0) and Anderson-mixed (the table's depth), and ``piqp/staggered`` at
   200 rounds: how each ended, its Coulomb residual and its time; ``nsgs/nsgs`` beside them;
3. the plain loop round by round (``friction_staggered.Inner``, pi-robust on the normal QP,
   the compiled projected Gauss-Seidel on the box QP) with the inner solves at a tenth of the
   accuracy (the table's ``inner_accuracy``) and at 1e-12: the Coulomb residual after 100 and
   after ``--rounds`` rounds, and the largest change of l_N and of l_T in the last round.

Rounds and residuals do not depend on the machine; times do.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from qpbench.problem import friction_metrics
from qpbench.problem.formulations import pose
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.friction_reference import components
from qpbench.problem.siconos_import import import_siconos
from qpbench.solvers import accuracy, friction_staggered, registry
from qpbench.solvers.run import call_solver

ROOT = Path(__file__).resolve().parents[3]
SICONOS = ROOT / "../shared/siconos/fc2d"
FLOWS = ("fc2d_granularflowonwall_00667_00000.dat", "fc2d_granularflowonwall_02020_00213.dat",
         "fc2d_granularflowonwall_07002_00801.dat")
ACCURACY = 1e-8
TABLE_ROUNDS = 200
# (pair, the rounds: None for the --rounds budget, anderson depth: None for the table's)
PAIRS = (("pi-robust/staggered", TABLE_ROUNDS, 0), ("pi-robust/staggered", TABLE_ROUNDS, None),
         ("pi-robust/staggered", None, 0), ("pi-robust/staggered", None, None),
         ("piqp/staggered", TABLE_ROUNDS, None), ("nsgs/nsgs", None, None))


def with_staggered_row(rounds: int, depth: int | None, action):
    """``action()`` with the ``staggered`` row's ``max_outer`` at ``rounds`` and its
    ``anderson_depth`` at ``depth`` (None: as it is)."""
    row = accuracy.OPTIONS["staggered"]
    saved = dict(row)
    row["max_outer"] = rounds
    if depth is not None:
        row["anderson_depth"] = depth
    try:  # (the compiled loop's settings are cached by the row's items: no stale entry)
        return action()
    finally:
        row.clear()
        row.update(saved)


def pair_row(problem: FrictionalProblem, name: str, rounds: int, depth: int | None) -> str:
    """One table row: the pair's ending, Coulomb residual and time on ``problem``."""
    spec = registry.get(name, "frictional")
    if spec.prepare is not None:
        spec.prepare()
    output = with_staggered_row(rounds, depth,
                                lambda: call_solver(spec, problem, ACCURACY))
    value = friction_metrics.residual(problem, output.impulses)
    depth_used = accuracy.OPTIONS["staggered"]["anderson_depth"] if depth is None else depth
    budget = "" if name == "nsgs/nsgs" else f"{rounds} rounds, depth {depth_used}"
    return (f"| {problem.name} | `{name}` | {budget} | {output.status} | {value:.2e} | "
            f"{output.time_s:.2f} |")


def plain_rounds(problem: FrictionalProblem, rounds: int, inner_accuracy: float
                 ) -> tuple[float, float, float, float]:
    """The plain loop's Coulomb residual after 100 rounds and after ``rounds``, and the
    largest change of l_N and of l_T in its last round."""
    spec = registry.get("pi-robust")
    box_solver, _ = friction_staggered.box_solver_for(spec)
    posed = problem.blind_copy()
    pose(posed, "staggered")
    inner = friction_staggered.Inner(posed, spec.solve, box_solver, True, inner_accuracy)
    n = problem.n_contacts
    normal, tangential = np.zeros(n), np.zeros(n)
    at_100 = np.nan
    change_normal = change_tangential = np.nan
    for done in range(1, rounds + 1):
        new_normal, _ = inner.normal(tangential, normal)
        new_tangential, _ = inner.friction(new_normal, tangential)
        assert new_normal is not None and new_tangential is not None
        change_normal = float(np.max(np.abs(new_normal - normal)))
        change_tangential = float(np.max(np.abs(new_tangential - tangential)))
        normal, tangential = new_normal, new_tangential
        if done == 100:
            at_100 = friction_metrics.residual(problem, np.concatenate((normal, tangential)))
    last = friction_metrics.residual(problem, np.concatenate((normal, tangential)))
    return at_100, last, change_normal, change_tangential


def main() -> None:
    arguments = sys.argv[1:]
    quick = "--quick" in arguments
    rounds = int(arguments[arguments.index("--rounds") + 1]) if "--rounds" in arguments \
        else 2000
    flows = FLOWS[:2] if quick else FLOWS
    problems = [import_siconos(SICONOS / name) for name in flows]
    print("\n| flow | contacts | groups of coupled contacts | largest |\n|---|---:|---:|---:|")
    for problem in problems:
        groups = components(problem)
        print(f"| {problem.name} | {problem.n_contacts} | {len(groups)} | "
              f"{max(len(group) for group in groups)} |")
    print("\n| flow | pair | budget | status | Coulomb residual | time (s) |\n"
          "|---|---|---|---|---:|---:|")
    for problem in problems:
        for name, budget, depth in PAIRS:
            print(pair_row(problem, name, rounds if budget is None else budget, depth))
            sys.stdout.flush()
    print(f"\n| flow | inner accuracy | residual after 100 rounds | after {rounds} | "
          "last change of l_N | of l_T |\n|---|---:|---:|---:|---:|---:|")
    for problem in problems:
        for inner_accuracy in (0.1 * ACCURACY, 1e-12):
            at_100, last, change_normal, change_tangential = plain_rounds(
                problem, rounds, inner_accuracy)
            print(f"| {problem.name} | {inner_accuracy:.0e} | {at_100:.2e} | {last:.2e} | "
                  f"{change_normal:.1e} | {change_tangential:.1e} |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
