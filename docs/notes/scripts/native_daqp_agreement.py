"""The harness's time of ``daqp-native/dual`` against DAQP called directly, on the research
fork's 50 dumps of its 5x5 grid (issue #52: the two must agree within 0.7x-1.3x).

Each round calls, for every dump in a rotated order, the harness (``call_solver``: a blind
copy posed outside the stopwatch, timed from Q and b to l) and an independent call written
here (a blind copy posed outside its own stopwatch, around ``Q.toarray()`` and
``daqp.solve`` with bounds 0 <= l and the same options), in alternating order, so that
neither is ever timed twice in a row on one dump and both start from freshly made arrays.
Each dump keeps the fastest of its rounds for each; the script prints the per-dump ratio's
geometric mean and range.

Run: ``.venv/bin/python docs/notes/scripts/native_daqp_agreement.py [ROUNDS]`` (default 20;
about a minute) with ../shared beside the repository.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import daqp
import numpy as np

from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

FORK = (Path(__file__).resolve().parents[3] / ".." / "shared" / "scisim" / "forks"
        / "IsaiahWitzke_scisim" / "ura_research" / "old_simulation_outputs" / "5_by_5_grid")
LEVEL = 1e-8


def direct(problem: ImpactProblem, options: dict) -> float:
    """Seconds from Q (SciPy CSC) and b of a freshly posed blind copy of ``problem`` to l,
    DAQP called as its own documentation shows."""
    blind = problem.blind_copy()
    pose(blind, "dual")
    Q, b = blind.Q, blind.b
    start = time.perf_counter()
    n = b.size
    x, _, exitflag, _ = daqp.solve(Q.toarray(), b, np.empty((0, n)), np.full(n, 1e30),
                                   np.zeros(n), **options)
    elapsed = time.perf_counter() - start
    assert exitflag > 0 and np.all(np.isfinite(x))
    return elapsed


def main(rounds: int) -> None:
    dumps = sorted(FORK.glob("*.out"), key=lambda path: int(path.stem.split("_")[1].split(".")[0]))
    problems = [import_dump(path) for path in dumps]
    spec = get("daqp-native/dual")
    harness = {problem.name: math.inf for problem in problems}
    own = dict(harness)
    for round_number in range(rounds):
        shift = round_number % len(problems)
        for place, problem in enumerate(problems[shift:] + problems[:shift]):
            options = accuracy.options_for("daqp-native", LEVEL, metrics.scale(problem))
            order = ("harness", "own") if (round_number + place) % 2 else ("own", "harness")
            for name in order:
                if name == "harness":
                    seconds = call_solver(spec, problem, LEVEL).time_s
                    harness[problem.name] = min(harness[problem.name], seconds)
                else:
                    own[problem.name] = min(own[problem.name], direct(problem, options))
    ratios = np.array([harness[name] / own[name] for name in harness])
    print(f"{len(ratios)} dumps, {rounds} rounds: harness / direct DAQP time, geometric mean "
          f"{math.exp(np.mean(np.log(ratios))):.3f}, range {ratios.min():.3f}-{ratios.max():.3f}; "
          f"median harness {1e6 * np.median(list(harness.values())):.1f} us, direct "
          f"{1e6 * np.median(list(own.values())):.1f} us")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
