"""pi-robust on problems of a few contacts, with and without its dense pivoting path.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_dense.py VALUE... [--quick]
[--first-seed N]``, the values of ``constants.DENSE_CONTACTS`` to compare (0: no dense path),
e.g. ``0 16 32``. numba
reads the kernel's constants when it compiles, so each value runs in its own process with its
own, empty numba cache (each compiles the kernel: about a minute).

Each process times pi-robust through the harness's stopwatch (``call_solver``) as the
head-to-head and the sequence mode see it: before every timed call, one of the research
fork's 5x5 grid dumps is solved by DAQP, PIQP and quadprog through their own APIs, so that the
kernel's code and data are no longer in the caches. It prints per group the linear solves,
factorizations and failures (qpbench's residual above 1e-8) of one solve of each problem, and
the median time of a call over the rounds (20, 5 with ``--quick``). The groups: generated
families of 2 to 50 contacts (ten seeds from ``--first-seed``, 0 by default; three with
``--quick``), the first 40 impacts of two scenes of few contacts that the sequence mode
replays, and the fork's dumps (38-59 contacts).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile

import numpy as np
from pi_robust_common import (
    ACCURACY,
    COLUMNS,
    ROOT,
    option,
    quick_flag,
    results_in_children,
    run,
    solvers_between,
    table,
    words,
)

from qpbench.problem import files
from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver
from qpbench.studies.sequence import capture

FAMILIES = (("k3", None), ("k4", None), ("k4-middle", None), ("cradle", 3), ("cradle", 10),
            ("cradle", 17), ("cradle", 25), ("cradle", 30), ("cradle", 50), ("grid", 3),
            ("grid", 4), ("grid", 5), ("near-duplicate", 2), ("near-duplicate", 3), ("box", 8),
            ("box", 20), ("box", 25), ("box", 30), ("mass-ratio", 3))
SCENES = ("problems/scenes/scisim/butterfly.xml", "problems/scenes/ura/10_balls_in_box.xml")


def problem_groups(quick: bool, folder: str, first_seed: int) -> dict[str, list[ImpactProblem]]:
    """The groups of the module docstring, posed as pi-robust takes them."""
    seeds = range(first_seed, first_seed + (3 if quick else 10))
    groups = {f"{family} {size or ''}".strip(): [generate(family, size, seed=seed)[0]
                                                 for seed in seeds]
              for family, size in FAMILIES}
    for scene in SCENES:
        paths = capture(ROOT / scene, os.path.join(folder, os.path.basename(scene)),
                        10 if quick else 40)
        loaded = [files.load(path) for path in paths]
        groups[os.path.basename(scene)] = [problem for problem in loaded
                                           if isinstance(problem, ImpactProblem)]
    dumps = sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))
    groups["fork 5x5 dumps"] = [import_dump(path) for path in dumps[:6 if quick else 20]]
    for problems in groups.values():
        for problem in problems:
            pose(problem, "lcp")
    return groups


def child(value: int, quick: bool, first_seed: int) -> None:
    """Set DENSE_CONTACTS before anything compiles, then print the groups' results as JSON."""
    from qpbench.solvers.pi_robust_kernel import entry
    entry.DENSE_CONTACTS = value  # (the name the entry compiles with)
    spec = get("pi-robust")
    spec.prepare()
    others = solvers_between()
    rounds = 5 if quick else 20
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        groups = problem_groups(quick, folder, first_seed)
    between = groups["fork 5x5 dumps"]
    for name, problems in groups.items():
        totals = run(problems, 1)  # (its one solve each: the counts)
        times = []
        for number in range(rounds):
            for problem in problems:
                for other in others:
                    call_solver(other, between[number % len(between)], ACCURACY)
                times.append(call_solver(spec, problem, ACCURACY).time_s)
        results[name] = {**totals, "median_us": 1e6 * float(np.median(times))}
    print(json.dumps(results))


def main() -> None:
    values = words()
    quick = quick_flag()
    first_seed = int(option(values, "--first-seed", "0"))
    if "--child" in sys.argv:
        child(int(values[0]), quick, first_seed)
        return
    results, names = results_in_children(values, lambda value: [
        __file__, value, "--child", "--first-seed", str(first_seed),
        *(["--quick"] if quick else [])])
    table(f"pi-robust at 1e-8, DENSE_CONTACTS = {' / '.join(values)}", values, results, names,
          columns=(*COLUMNS[:3], ("median_us", "median call (us)", ".1f")),
          variant_heading="DENSE_CONTACTS")

if __name__ == "__main__":
    main()
