"""Problem groups and a timed run of pi-robust, shared by the pi-robust notes' scripts.

Each script prints, per group, the linear solves, factorizations, failures and the sum of
each problem's fastest ``time_s`` (the harness's stopwatch, ``call_solver``), for every
variant it compares. Times depend on the machine; solve counts do not.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import TypeVar

from qpbench.inner_solvers import choose_by_name
from qpbench.problem import files
from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.scenes.model import Scene
from qpbench.simulation.stepper import Simulator
from qpbench.solvers import accuracy, pi_robust, pi_robust_call
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.pi_robust import settings_for
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

ROOT = Path(__file__).resolve().parents[3]
T = TypeVar("T")
ACCURACY = 1e-8


def groups(quick: bool) -> Iterator[tuple[str, list[ImpactProblem]]]:
    """(name, problems) of the groups the notes quote; ``quick``: a few problems of each.

    With ``--folder DIR`` (the head-to-head problems, ``qpbench build-set
    problems/head_to_head.toml -o DIR``) the captured impacts of the research fork's 7x7 grid
    scenes and of the grid scenes come first."""
    seeds = range(2) if quick else range(20)
    folder = folder_argument()
    if folder is not None:
        captured: dict[str, list[ImpactProblem]] = {}
        for path in sorted(folder.rglob("*.npz")):
            problem = files.load(path)
            family = str(getattr(problem, "family", "") or "")
            name = ("fork 7x7 scenes" if family.startswith("scene:grid7_") else
                    "grid scene captures" if family.startswith("scene:grid") else None)
            if name is not None and isinstance(problem, ImpactProblem):
                captured.setdefault(name, []).append(problem)
        for name, problems in sorted(captured.items()):
            yield name, problems[:3] if quick else problems
    dumps = sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))
    yield "fork 5x5 dumps", [import_dump(path) for path in dumps[:3 if quick else None]]
    for size in (7, 10, 14, 20):
        yield f"grid {size}", [generate("grid", size, seed=seed)[0] for seed in seeds]
    for ratio in (5, 10):
        yield f"mass ratio {ratio}", [generate("mass-ratio", ratio, seed=seed)[0]
                                      for seed in seeds]
    yield "near-duplicate", [generate("near-duplicate", None, seed=seed)[0] for seed in seeds]
    yield "box packings", [generate("box", size, seed=0)[0]
                           for size in ((1000,) if quick else (1000, 4000))]


def captured_impacts(scene: Scene, steps: int) -> list[ImpactProblem]:
    """The impact problems of the first ``steps`` steps of ``scene``, pi-robust its inner
    solver, as the simulator's own capture stores them (with the impulses each step carried,
    ``data["warm_start"]``, where the scene caches them)."""
    with tempfile.TemporaryDirectory() as folder:
        simulator = Simulator(scene, choose_by_name("pi-robust"), capture=folder)
        for _ in range(steps):
            simulator.step()
        captured = [files.load(path) for path in files.find([folder])]
    return [problem for problem in captured if isinstance(problem, ImpactProblem)]

def run(problems: list[ImpactProblem], repeats: int) -> dict[str, float]:
    """pi-robust at ``ACCURACY`` on ``problems``: summed solves, factorizations, failures
    (qpbench's residual above the level) and each problem's fastest time."""
    spec = get("pi-robust")
    spec.prepare()
    totals = {"solves": 0, "factorizations": 0, "failed": 0, "time_s": 0.0}
    for problem in problems:
        outputs = [call_solver(spec, problem, ACCURACY) for _ in range(repeats)]
        first = outputs[0]
        totals["solves"] += first.iterations or 0
        totals["factorizations"] += first.info.get("factorizations", 0)
        totals["failed"] += residual(problem, first.impulses) > ACCURACY
        totals["time_s"] += min(output.time_s for output in outputs)
    return totals


# the solvers that solve a dump between timed calls, as the head-to-head interleaves other
# pairs, so that pi-robust's code and data are no longer in the caches
BETWEEN = ("daqp-native/dual", "piqp-native/dual", "quadprog-native/dual")


def solvers_between() -> list[SolverSpec]:
    """The pairs of :data:`BETWEEN`, each set up (outside any clock)."""
    specs = [get(name) for name in BETWEEN]
    for spec in specs:
        if spec.prepare is not None:
            spec.prepare()
    return specs


def kernel_arguments(problem: ImpactProblem) -> tuple:
    """The arguments of the compiled entry ``envelope_pi_robust`` for ``problem`` (posed as
    ``lcp``), as pi-robust's ``solve`` passes them, at ``ACCURACY`` from no start."""
    settings = settings_for(ACCURACY)
    Q = problem.Q
    return (Q.indptr, Q.indices, Q.data, problem.b, problem.diag_Q, pi_robust_call.NO_START,
            pi_robust_call.ORDERING_ABOVE, settings.compiled_work_limit, settings.kernel)


def dump_kernel_calls() -> list[tuple]:
    """:func:`kernel_arguments` for each of the fork's 5x5 dumps, posed as pi-robust's
    ``solve`` poses them (the kernel loaded or compiled first)."""
    pi_robust.prepare()
    calls = []
    for path in sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out")):
        problem = import_dump(path)
        pose(problem, "lcp")
        calls.append(kernel_arguments(problem))
    return calls


def with_constant(module: ModuleType, name: str, value: object, action: Callable[[], T]) -> T:
    """``action()`` with ``module.name`` set to ``value`` (a module constant read at each
    call, as ``lcp_interior.CENTRALITY_CORRECTORS``), restored after it."""
    saved = getattr(module, name)
    setattr(module, name, value)
    try:
        return action()
    finally:
        setattr(module, name, saved)


def with_row(key: str, value: object, action: Callable[[], dict[str, float]]
             ) -> dict[str, float]:
    """``action()`` with pi-robust's accuracy-table entry ``key`` set to ``value``."""
    row = accuracy.OPTIONS["pi-robust"]
    saved = row[key]
    row[key] = value
    settings_for.cache_clear()
    try:
        return action()
    finally:
        row[key] = saved
        settings_for.cache_clear()


# the columns of :func:`table`: (result key, heading, format)
COLUMNS = (("solves", "solves", ".0f"), ("factorizations", "factorizations", ".0f"),
           ("failed", "failed", ".0f"), ("time_s", "time (s)", ".4f"))


def table(title: str, variants: list[str], results: dict[tuple[str, str], dict[str, float]],
          group_names: list[str], columns: tuple[tuple[str, str, str], ...] = COLUMNS,
          variant_heading: str = "variant") -> None:
    """Print one line per (group, variant), one column per entry of ``columns``."""
    print(f"\n{title}\n")
    print(f"| group | {variant_heading} | " + " | ".join(heading for _, heading, _ in columns)
          + " |")
    print("|---|---|" + "---:|" * len(columns))
    for group in group_names:
        for variant in variants:
            got = results[group, variant]
            print(f"| {group} | {variant} | "
                  + " | ".join(format(got[key], form) for key, _, form in columns) + " |")
    sys.stdout.flush()


def results_in_children(variants: list[str], command: Callable[[str], list[str]]
                        ) -> tuple[dict[tuple[str, str], dict[str, float]], list[str]]:
    """Run ``python *command(variant)`` for each variant, each in its own process with its own,
    empty numba cache (numba reads the kernel's constants when it compiles), and read the
    last line each prints as JSON ``{group: results}``. Returns the results by (group,
    variant) and the groups in the order printed."""
    results, names = {}, []
    for variant in variants:
        with tempfile.TemporaryDirectory() as cache:
            printed = subprocess.run([sys.executable, *command(variant)],
                                     env={**os.environ, "NUMBA_CACHE_DIR": cache}, check=True,
                                     capture_output=True, text=True).stdout
        for group, got in json.loads(printed.splitlines()[-1]).items():
            results[group, variant] = got
            if group not in names:
                names.append(group)
    return results, names


def folder_argument() -> Path | None:
    """The folder after ``--folder`` on the command line, or None."""
    arguments = sys.argv[1:]
    if "--folder" in arguments and arguments.index("--folder") + 1 < len(arguments):
        return Path(arguments[arguments.index("--folder") + 1])
    return None


def words() -> list[str]:
    """The command line without ``--quick``, ``--child`` and ``--folder DIR``."""
    out, arguments = [], sys.argv[1:]
    skip = False
    for word in arguments:
        if skip:
            skip = False
        elif word == "--folder":
            skip = True
        elif word not in ("--quick", "--child"):
            out.append(word)
    return out


def option(arguments: list[str], name: str, default: str) -> str:
    """The value after ``name`` in ``arguments`` (both removed), else ``default``."""
    if name not in arguments:
        return default
    at = arguments.index(name)
    value = arguments[at + 1]
    del arguments[at:at + 2]
    return value


def quick_flag() -> bool:
    """``--quick`` on the command line: a few problems per group, one repeat."""
    return "--quick" in sys.argv[1:]
