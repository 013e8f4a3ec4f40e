"""Test-only solvers that misbehave on purpose.

Imported by the registry when ``QPBENCH_EXTRA_SOLVERS=bench_solvers`` (with this folder
on the path), so the runner's worker processes see them as well. Never import this
module at the top of a test file: use :func:`registered` (a context manager) so the
solvers leave the registry again and no other test ever runs them.

* ``test-exact``: enumerates supports (n <= 12), an exact LCP solve for tiny problems;
* ``test-slow``: test-exact after a 0.3 s pause (so a run can be killed mid-way);
* ``test-abort``: calls os.abort() (SIGABRT);
* ``test-segfault``: reads address 0 through ctypes (SIGSEGV);
* ``test-hang``: sleeps for an hour;
* ``test-greedy``: allocates 64 GiB (beyond any memory cap);
* ``test-vandal``: test-exact, then overwrites every array of the problem it was handed and
  records whether it could see a reference or stored data (it must not).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import time
from collections.abc import Iterator

import numpy as np
from bench_problems import exact_impulses

from qpbench import EXTRA_SOLVERS_ENV
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy, registry
from qpbench.solvers.base import SolverOutput, SolverSpec

BACKEND = "qpbench-tests"


def _exact(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
           ) -> SolverOutput:
    impulses = exact_impulses(problem)
    return SolverOutput(impulses=impulses, status="solved", claimed_success=True, iterations=1)


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
                        claimed_success=True)


def _vandal(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
            ) -> SolverOutput:
    output = _exact(problem, accuracy, warm_start)
    saw = {"reference": problem.reference is not None, "data": sorted(problem.data),
           "metadata": sorted(problem.metadata), "family": problem.family}
    for array in (problem.G.data, problem.m_inv, problem.v_minus, problem.restitution,
                  problem.n_rel, problem.Q.data, problem.b, problem.diag_Q):
        array[...] = np.nan
    if warm_start is not None:
        warm_start[...] = np.nan
    output.info["saw"] = saw
    return output


for _name, _solve in (("test-exact", _exact), ("test-slow", _slow), ("test-abort", _abort),
                      ("test-segfault", _segfault), ("test-hang", _hang),
                      ("test-greedy", _greedy), ("test-vandal", _vandal)):
    accuracy.OPTIONS.setdefault(_name, {})  # no options: an exact method
    registry.register(SolverSpec(name=_name, formulation="lcp", backend=BACKEND, solve=_solve,
                                 version="0", warm_start=False))


@contextlib.contextmanager
def registered() -> Iterator[None]:
    """Within the block: the test solvers are registered here and, through
    $QPBENCH_EXTRA_SOLVERS, in every worker process the runner starts."""
    previous = os.environ.get(EXTRA_SOLVERS_ENV)
    os.environ[EXTRA_SOLVERS_ENV] = __name__
    registry.all_solvers()
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(EXTRA_SOLVERS_ENV, None)
        else:
            os.environ[EXTRA_SOLVERS_ENV] = previous
        for key in [key for key, spec in registry._SOLVERS.items() if spec.backend == BACKEND]:
            accuracy.OPTIONS.pop(registry._SOLVERS[key].name, None)
            del registry._SOLVERS[key]
        sys.modules.pop(__name__, None)


