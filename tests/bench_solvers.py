"""Test-only solvers that misbehave on purpose, and tiny problems to run them on.

Imported by the registry when ``QPBENCH_EXTRA_SOLVERS=bench_solvers`` (with this folder
on PYTHONPATH), so the runner's worker processes see them as well:

* ``test-exact``: enumerates supports (n <= 12), an exact LCP solve for tiny problems;
* ``test-slow``: test-exact after a 0.3 s pause (so a run can be killed mid-way);
* ``test-abort``: calls os.abort() (SIGABRT);
* ``test-segfault``: reads address 0 through ctypes (SIGSEGV);
* ``test-hang``: sleeps for an hour;
* ``test-greedy``: allocates 64 GiB (beyond any memory cap).
"""

from __future__ import annotations

import ctypes
import itertools
import os
import time
from pathlib import Path

import numpy as np

from qpbench.problem import files
from qpbench.problem.impact import ImpactProblem, Reference
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.registry import register

BACKEND = "qpbench-tests"


def exact_impulses(problem: ImpactProblem) -> np.ndarray:
    """The least-norm l >= 0 with w = Q l + b >= 0 and l_i w_i = 0, found by trying supports."""
    Q = problem.Q.toarray()
    b = problem.b
    n = problem.n_contacts
    for size in range(n + 1):
        for support in itertools.combinations(range(n), size):
            index = list(support)
            impulses = np.zeros(n)
            if index:
                impulses[index] = np.linalg.lstsq(Q[np.ix_(index, index)], -b[index],
                                                  rcond=None)[0]
            w = Q @ impulses + b
            scale = max(1.0, float(np.max(np.abs(b))))
            if impulses.min() >= -1e-12 * scale and w.min() >= -1e-12 * scale:
                return np.maximum(impulses, 0.0)
    raise ValueError("no support solves the LCP")


def _exact(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
           ) -> SolverOutput:
    start = time.perf_counter()
    impulses = exact_impulses(problem)
    return SolverOutput(impulses=impulses, status="solved", claimed_success=True,
                        solve_time_s=time.perf_counter() - start, iterations=1)


def _slow(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    time.sleep(0.3)
    return _exact(problem, accuracy, warm_start)


def _abort(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
           ) -> SolverOutput:
    os.abort()


def _segfault(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
    ctypes.string_at(0)
    raise AssertionError("unreachable: reading address 0 did not fault")


def _hang(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    time.sleep(3600)
    raise AssertionError("unreachable")


def _greedy(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
            ) -> SolverOutput:
    hoard = np.ones(8 * 1024**3)  # 64 GiB
    return SolverOutput(impulses=hoard[: problem.n_contacts], status="solved",
                        claimed_success=True, solve_time_s=0.0)


for _name, _solve in (("test-exact", _exact), ("test-slow", _slow), ("test-abort", _abort),
                      ("test-segfault", _segfault), ("test-hang", _hang),
                      ("test-greedy", _greedy)):
    register(SolverSpec(name=_name, formulation="lcp", backend=BACKEND, solve=_solve,
                        version="0", warm_start=False))


# --- tiny problems ---------------------------------------------------------------------------
def collinear_balls(name: str, count: int, restitution: float = 1.0) -> ImpactProblem:
    """``count`` unit balls on the x axis at spacing 1 (radius 1, so each overlaps its two
    neighbours on either side): contacts between all pairs closer than 2. The first ball moves
    right at 1, the last left at 1; the reference is the exact LCP solution."""
    positions = np.arange(count, dtype=float)
    pairs = [(a, b) for a, b in itertools.combinations(range(count), 2)
             if positions[b] - positions[a] < 2.0 + 1e-12]
    G = np.zeros((2 * count, len(pairs)))
    for k, (a, b) in enumerate(pairs):
        normal = np.array([positions[a] - positions[b], 0.0])
        normal /= np.linalg.norm(normal)
        G[2 * a: 2 * a + 2, k] = normal
        G[2 * b: 2 * b + 2, k] = -normal
    v_minus = np.zeros(2 * count)
    v_minus[0], v_minus[-2] = 1.0, -1.0
    problem = ImpactProblem.build(name, G, np.ones(2 * count), v_minus, restitution,
                                  family="k3" if count == 3 else "row", source="tests")
    impulses = exact_impulses(problem)
    v_plus = problem.v_plus(impulses)
    problem.reference = Reference(v_plus=v_plus, impulses=impulses, method="enumeration",
                                  v_plus_check=v_plus.copy(), check_method="enumeration",
                                  agreement=0.0, tolerance=1e-9)
    return problem


def write_tiny_problems(folder: Path, count: int = 2) -> list[Path]:
    """Saves ``count`` tiny problems (K3, then rows of 4, 5, ... balls) into ``folder``."""
    problems = [collinear_balls(f"row{size}", size, restitution=0.5 if size % 2 else 1.0)
                for size in range(3, 3 + count)]
    return [files.save(problem, folder / problem.name) for problem in problems]
