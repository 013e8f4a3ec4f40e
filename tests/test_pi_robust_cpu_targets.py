"""pi-robust gives the same answers, bit for bit, whatever CPU its kernel is compiled for.

numba compiles the kernel for the CPU it runs on. Sums that the compiler may reorder would be
reordered by the CPU's vector width (AVX2's four doubles, AVX-512's eight), and on problems
where block pivoting follows the rounding, the path and the answer would change with the CPU.
Here the kernel is compiled again in fresh processes, each for another CPU (``NUMBA_CPU_NAME``,
with a cache of its own), and every answer on problems of the hard families must equal this
process's, byte for byte. The targets: an AMD CPU with 512-bit vectors, an Intel one, and an
AVX2-only CPU of each vendor's older kind, all different from most hosts.

pi-robust's Python path (large sparse problems: the interior point, then policy iteration; on
dense ones also Lemke's method) sums in a fixed order too (``qpbench.problem.metrics.dot``,
CHOLMOD's simplicial factor, ``qpbench.solvers.fixed_order_dense``): its answers must not change
with the BLAS kernels OpenBLAS picks for the CPU (``OPENBLAS_CORETYPE``) nor with the vector
instructions NumPy dispatches to (``NPY_DISABLE_CPU_FEATURES``; ``tests/other_cpu.py``).

Run as a script (``python tests/test_pi_robust_cpu_targets.py [sparse]``) it prints the digests
of its answers (of the sparse problems with ``sparse``), one line per problem, which is what the
tests compare.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from other_cpu import printed_elsewhere

from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver

# two targets per run, compiled side by side (about a minute each on two cores)
FOREIGN_TARGETS = ("znver4", "haswell")
HOST_TWINS = {"znver4": "sapphirerapids", "haswell": "znver2"}


def problems() -> list[ImpactProblem]:
    """Problems whose solves take many pivots on nearly singular blocks: mass ratios,
    near-duplicate contacts, grids, a box packing, a cradle and K4."""
    chosen: list[ImpactProblem] = []
    for family, sizes, count in (("mass-ratio", (5, 7, 10), 4), ("near-duplicate", (4, 6), 2),
                                 ("grid", (5, 10), 2), ("box", (100,), 1),
                                 ("cradle", (50,), 1), ("k4", (None,), 2)):
        for size in sizes:
            chosen.extend(generate(family, size, seed=1, count=count))
    return chosen


def sparse_problems() -> list[ImpactProblem]:
    """Problems that pi-robust's compiled kernel hands to its Python path: grids of 26 and 30
    balls a side and the first impacts of dense piles of 1,000 circles and 400 boxes."""
    from qpbench.inner_solvers import choose_by_name
    from qpbench.simulation.scaling import PILES
    from qpbench.simulation.stepper import Simulator

    chosen = [generate("grid", 26, seed=1)[0], generate("grid", 30, seed=2)[0]]
    for kind, bodies in (("circles", 1000), ("boxes", 400)):
        simulator = Simulator(PILES[kind](bodies), choose_by_name("pi-robust"))
        found = simulator.find_contacts(simulator.positions, simulator.positions)
        chosen.append(simulator.impact_problem(found, simulator.dof_velocity()))
    return chosen


def digests(sparse: bool = False) -> list[str]:
    """``name digest path`` per problem: the SHA-1 of pi-robust's answer at 1e-8, as bytes,
    and whether the kernel or the Python path answered; of :func:`sparse_problems` with
    ``sparse``."""
    spec = get("pi-robust/lcp")
    assert spec.prepare is not None
    spec.prepare()
    lines = []
    for problem in sparse_problems() if sparse else problems():
        output = call_solver(spec, problem, 1e-8)
        assert output.impulses is not None, output.status
        answer = np.ascontiguousarray(output.impulses, dtype=np.float64)
        compiled = output.info.get("compiled") is True
        lines.append(f"{problem.name or problem.family} "
                     f"{hashlib.sha1(answer.tobytes()).hexdigest()} "
                     f"{'kernel' if compiled else 'python'}")
    return lines


def host_cpu_name() -> str:
    """LLVM's name of this machine's CPU (what numba compiles for by default)."""
    from llvmlite import binding  # (llvmlite comes with numba)

    return binding.get_host_cpu_name()


@pytest.mark.slow
def test_pi_robust_answers_do_not_depend_on_the_cpu_compiled_for(tmp_path: Path) -> None:
    host = host_cpu_name()
    targets = [HOST_TWINS[target] if target == host else target for target in FOREIGN_TARGETS]
    runs = []
    for target in targets:
        environment = dict(os.environ, NUMBA_CPU_NAME=target, NUMBA_CPU_FEATURES="",
                           NUMBA_CACHE_DIR=str(tmp_path / target))
        runs.append(subprocess.Popen([sys.executable, __file__], env=environment,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    here = digests()
    for target, run in zip(targets, runs, strict=True):
        out, err = run.communicate(timeout=900)
        assert run.returncode == 0, err[-2000:]
        there = out.splitlines()
        differing = [f"{mine} != {theirs}" for mine, theirs in zip(here, there, strict=True)
                     if mine != theirs]
        assert not differing, f"compiled for {target} (host {host}):\n" + "\n".join(differing)


@pytest.mark.slow
@pytest.mark.parametrize("sparse", [True, False], ids=["sparse", "hard"])
def test_answers_do_not_depend_on_blas_kernels_or_simd(sparse: bool) -> None:
    """The Python path's answers, on large sparse problems and on the hard families' problems
    that the kernel does not solve (mass ratios whose floor lies above 1e-8: policy iteration,
    the interior point and Lemke's method in Python on a dense Q), are the same bit for bit
    under an old CPU's OpenBLAS kernels, with or without NumPy's vector dispatch."""
    here = digests(sparse=sparse)
    python = [line for line in here if line.endswith(" python")]
    if sparse:
        assert python == here, here
    else:  # mass-ratio-10-s2, whose floor lies above 1e-8, takes the Python path
        assert python, here
    for core_type, baseline_numpy in (("Prescott", False), ("Sandybridge", True)):
        there = printed_elsewhere(__file__, *(["sparse"] if sparse else []), core_type=core_type,
                                  baseline_numpy=baseline_numpy, timeout=900)
        assert there == here, (core_type, baseline_numpy)


if __name__ == "__main__":
    print("\n".join(digests(sparse=sys.argv[1:] == ["sparse"])))
