"""Rounds of staggered projections, plain and with Anderson acceleration of the friction impulse.

Usage: ``.venv/bin/python docs/notes/scripts/staggered_anderson.py [--quick]``. Staggered
projections (``qpbench.solvers.friction_staggered``, pi-robust for the normal QP, the compiled
projected Gauss-Seidel for the box QP, the inner solves at a tenth of the accuracy) is the
fixed-point iteration ``l_T <- G(l_T)``: the friction box QP's answer for the normal QP's
answer given ``l_T``. Anderson acceleration (``qpbench.solvers.anderson``) starts each round
from the mixing of the last m + 1 rounds instead of ``G(x_k)``; the history restarts when the
Coulomb residual of a round's iterate is more than twice the round before's (``coulomb``), or
when ``|G(x) - x|`` grows (``fixed point``: the rule the loop uses, with m the table's
``anderson_depth``). Every round's iterate is a genuine staggered one, judged by qpbench's
Coulomb residual; a run ends at 1e-8 or after 2,000 rounds (the head-to-head's budget).

It prints per problem the rounds of each variant (``-`` where 2,000 rounds did not reach
1e-8): rough-box-30 of the seeds the rule was chosen on, then of fresh seeds, the other
frictional families and Siconos' granular flows on a wall (from ``../shared/siconos``). The
counts do not depend on the machine. ``--quick``: three problems.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from qpbench.problem import friction_metrics
from qpbench.problem.formulations import pose
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.friction_generate import generate
from qpbench.problem.siconos_import import import_siconos
from qpbench.solvers import anderson, friction_staggered, registry

ROOT = Path(__file__).resolve().parents[3]
ACCURACY = 1e-8
MAX_ROUNDS = 2000
# (label, history depth m, restart rule; depth 0 is the plain loop; all but ``coulomb`` run
# ``friction_staggered.staggered`` itself)
VARIANTS = (("plain", 0, ""), ("m=5, coulomb", 5, "coulomb"), ("m=3, coulomb", 3, "coulomb"),
            ("m=5, fixed point", 5, "fixed point"), ("m=3, fixed point", 3, "fixed point"))
# (family, size, seeds): the seeds looked at while choosing the variants, then seeds drawn
# afresh, then the other frictional families (fresh seeds) and Siconos' granular flows
TUNED = (("rough-box", 30, (0, 5, 6, 620862, 731447)),)
FRESH = (("rough-box", 30, tuple(range(100, 110))), ("rough-box", 60, (100, 101)))
OTHERS = (("pyramid", 2, (100, 101)), ("pyramid", 3, (100, 101, 102)),
          ("pyramid", 5, (100, 101)), ("friction-mass-ratio", 4, (100, 101, 102)),
          ("incline", 2, (100, 101)), ("rough-floor", 2, (100, 101)))
SICONOS = ROOT / "../shared/siconos/fc2d"
FLOWS = ("gfc2d_granularflowonwall_00069_00350.dat", "gfc2d_granularflowonwall_00230_00206.dat",
         "fc2d_granularflowonwall_00667_00000.dat")


def rounds(problem: FrictionalProblem, depth: int, restart: str) -> int | None:
    """Rounds until the Coulomb residual is at most ``ACCURACY``; None past ``MAX_ROUNDS``."""
    spec = registry.get("pi-robust")
    box_solver, _ = friction_staggered.box_solver_for(spec)
    posed = problem.blind_copy()
    pose(posed, "staggered")
    inner = friction_staggered.Inner(posed, spec.solve, box_solver, True, 0.1 * ACCURACY)
    if restart != "coulomb":  # the loop itself, the rule it uses (plain at depth 0)
        output = friction_staggered.staggered(posed, inner, ACCURACY, MAX_ROUNDS, None, depth)
        rounds_done = output.info["outer_iterations"]
        return rounds_done if output.status == "converged" and output.claimed_success else None
    n = posed.n_contacts
    start, normal = np.zeros(n), np.zeros(n)
    starts: list[np.ndarray] = []
    answers: list[np.ndarray] = []
    last_residual = np.inf
    for round_ in range(1, MAX_ROUNDS + 1):
        solved_normal, _ = inner.normal(start, normal)
        if solved_normal is None:
            return None
        normal = solved_normal
        tangential, _ = inner.friction(normal, start)
        if tangential is None:
            return None
        residual = friction_metrics.residual(posed, np.concatenate([normal, tangential]))
        if residual <= ACCURACY:
            return round_
        if residual > 2.0 * last_residual:
            starts, answers = [], []
        last_residual = residual
        starts, answers = [*starts, start][-(depth + 1):], [*answers, tangential][-(depth + 1):]
        start = tangential
        if depth > 0 and len(starts) > 1:
            start = anderson.anderson_start(np.array(starts), np.array(answers))
    return None


def problems(quick: bool) -> Iterator[tuple[str, FrictionalProblem]]:
    """(label, problem) of the groups above; ``quick``: the first three."""
    shown = 0
    for title, groups in (("tuned on", TUNED), ("fresh", FRESH), ("fresh", OTHERS)):
        for family, size, seeds in groups:
            for seed in seeds:
                if quick and shown == 3:
                    return
                problem = generate(family, size, seed=seed)[0]
                yield f"{problem.name} ({title})", problem
                shown += 1
    for name in FLOWS:
        path = SICONOS / name
        if path.exists():
            problem = import_siconos(path)
            assert isinstance(problem, FrictionalProblem)
            yield f"{path.stem} (Siconos)", problem


def main() -> None:
    quick = "--quick" in sys.argv[1:]
    registry.get("pi-robust").prepare()
    print("| problem | contacts | " + " | ".join(label for label, _, _ in VARIANTS) + " |")
    print("|---|---:|" + "---:|" * len(VARIANTS))
    for label, problem in problems(quick):
        cells = []
        for _, depth, restart in VARIANTS:
            count = rounds(problem, depth, restart)
            cells.append("-" if count is None else str(count))
        print(f"| {label} | {problem.n_contacts} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
