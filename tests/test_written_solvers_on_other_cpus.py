"""The solvers written here give the same answers, bit for bit, whatever CPU the BLAS is for.

OpenBLAS picks its kernels, and so the order of a dot product's sums, for the CPU it runs on;
NumPy dispatches to the CPU's vector instructions. Every solver whose backend is qpbench itself
(its twins on the frictional formulations included) is run here and in a process that rounds
as an old CPU does (``tests/other_cpu.py``), and the answers must agree to the last bit.

pi-robust's compiled kernel, compiled for other CPUs, is tested in
``tests/test_pi_robust_cpu_targets.py``.

Run as a script (``python tests/test_written_solvers_on_other_cpus.py``) it prints the digests
the test compares, one line per problem.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from other_cpu import printed_elsewhere

from qpbench.problem import friction_generate
from qpbench.problem.generate import generate
from qpbench.solvers import registry
from qpbench.solvers.run import call_solver

IMPACT_FAMILIES = (("grid", 10), ("mass-ratio", 3), ("box", 100), ("k4", None),
                   ("near-duplicate", 4), ("cradle", 10))
# (family, size, problems): one wedge, where nsgs sweeps to its limit and then pivots
FRICTIONAL_FAMILIES = (("incline", 10, 2), ("rough-floor", 20, 2), ("pyramid", 6, 2),
                       ("wedge", 3, 1), ("friction-mass-ratio", 5, 2), ("rough-box", 10, 2))


def digests() -> list[str]:
    """``problem digest...`` per problem: the SHA-1 of each written solver's answer at 1e-8 (the
    solvers in name order, ``none`` for no answer), on the problems of the families above."""
    lines = []
    for kind, problems in (
            ("impact", [problem for family, size in IMPACT_FAMILIES
                        for problem in generate(family, size, seed=5, count=2)]),
            ("frictional", [problem for family, size, count in FRICTIONAL_FAMILIES
                            for problem in friction_generate.generate(family, size, seed=3,
                                                                      count=count)])):
        specs = sorted((spec for spec in registry.usable_solvers()
                        if spec.backend == "qpbench" and kind in spec.kinds),
                       key=lambda spec: (spec.name, spec.formulation))
        for spec in specs:
            if spec.prepare is not None:
                spec.prepare()
        for problem in problems:
            answers = []
            for spec in specs:
                impulses = call_solver(spec, problem, 1e-8).impulses
                answers.append("none" if impulses is None else hashlib.sha1(
                    np.ascontiguousarray(impulses, dtype=np.float64).tobytes()).hexdigest()[:12])
            lines.append(f"{problem.name} " + " ".join(answers))
    return lines


@pytest.mark.slow
def test_the_written_solvers_answer_alike_under_another_cpus_blas() -> None:
    here = digests()
    assert len(here) == 2 * len(IMPACT_FAMILIES) + sum(
        count for _, _, count in FRICTIONAL_FAMILIES)
    assert printed_elsewhere(__file__, timeout=900) == here


if __name__ == "__main__":
    print("\n".join(digests()))
