"""pi-robust on dense circle piles with CHOLMOD's simplicial or supernodal factors.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_supernodal.py [--bodies 1000,10000]``.
The pile's first two steps are captured (pi-robust the inner solver), then solved cold at
1e-8 with each CHOLMOD setting of ``qpbench.solvers.sparse_cholesky`` (``CHOLMOD_MODE`` and
``CHOLMOD_ORDERING``, read at every factorization, so they change in this process): the
fastest of three solves per step, summed. Beside it, one factorization of the interior
point's matrix over the degrees of freedom, ``I + B S^2 B^T`` (B = M^-1/2 G, S random
scales), alone: its symbolic analysis made once, the fastest of five numeric factorizations.
The supernodal factor calls BLAS, which uses as many threads as ``OPENBLAS_NUM_THREADS``
allows (the benchmark's workers set 1).
"""

from __future__ import annotations

import sys
import time

import numpy as np
import scipy.sparse as sp
from pi_robust_common import ACCURACY, captured_impacts
from sksparse import cholmod

from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual
from qpbench.simulation.scaling import PILES
from qpbench.solvers import sparse_cholesky
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

SETTINGS = (("simplicial", "amd"), ("simplicial", "metis"), ("supernodal", "amd"),
            ("supernodal", "nesdis"))


def factorization_ms(problem: ImpactProblem, mode: str, ordering: str) -> float:
    """The fastest of five numeric factorizations of ``I + B S^2 B^T`` (ms)."""
    B = sp.csc_matrix(sp.diags(np.sqrt(np.asarray(problem.m_inv).ravel())) @ problem.G)
    analysis = cholmod.analyze_AAt(B, mode=mode, ordering_method=ordering)
    generator = np.random.default_rng(0)
    fastest = np.inf
    for _ in range(5):
        scaled = B @ sp.diags(np.exp(generator.uniform(-8.0, 8.0, B.shape[1])))
        start = time.perf_counter()
        analysis.cholesky_AAt(scaled, beta=1.0)
        fastest = min(fastest, time.perf_counter() - start)
    return 1e3 * fastest


def main() -> None:
    arguments = sys.argv[1:]
    bodies = [int(value) for value in
              (arguments[arguments.index("--bodies") + 1] if "--bodies" in arguments
               else "1000,10000").split(",")]
    spec = get("pi-robust")
    spec.prepare()
    print("\n| bodies | mode | ordering | pi-robust, steps 0-1 (ms) | failed | "
          "one factorization (ms) |")
    print("|---:|---|---|---:|---:|---:|")
    for count in bodies:
        problems = captured_impacts(PILES["circles"](count), 2)
        for mode, ordering in SETTINGS:
            sparse_cholesky.CHOLMOD_MODE, sparse_cholesky.CHOLMOD_ORDERING = mode, ordering
            total, failed = 0.0, 0
            for problem in problems:
                call_solver(spec, problem, ACCURACY)  # (the first call of a setting, untimed)
                outputs = [call_solver(spec, problem, ACCURACY) for _ in range(3)]
                total += min(output.time_s for output in outputs)
                failed += residual(problem, outputs[0].impulses) > ACCURACY
            print(f"| {count} | {mode} | {ordering} | {1e3 * total:.0f} | {failed} | "
                  f"{factorization_ms(problems[-1], mode, ordering):.1f} |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
