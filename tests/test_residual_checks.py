"""Residual checks across every usable solver on the hard families (issue: the working slice).

For every solver-formulation pair at accuracy 1e-8 on small members of every hard family and
on the shared dumps: qpbench's verdict must agree with a residual recomputed here from the raw
impulses with dense numpy, and every answer judged a success must have v+ within 1e-6 of the
verified reference. A solver that cannot reach 1e-8 must be reported as a failure.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference
from qpbench.solvers.registry import usable_solvers
from qpbench.solvers.run import solve_and_judge

ACCURACY = 1e-8
DUMPS = Path(__file__).resolve().parents[1] / "problems" / "dumps"
CASES = {
    "k3": ("k3", None, 0), "k3-rotated": ("k3", None, 1), "k4": ("k4", None, 1),
    "k4-middle": ("k4-middle", None, 1), "cradle": ("cradle", 6, 0), "grid": ("grid", 3, 2),
    "box": ("box", 25, 0), "mass-ratio": ("mass-ratio", 3, 0),
    "near-duplicate": ("near-duplicate", 3, 0),
}


@cache
def hard_problems() -> tuple[ImpactProblem, ...]:
    problems = [generate(family, size=size, seed=seed)[0]
                for family, size, seed in CASES.values()]
    dumps = sorted(DUMPS.glob("*"))
    assert len(dumps) == 4, f"the four SCISim dumps belong in {DUMPS}"
    problems += [import_dump(path) for path in dumps]
    return tuple(attach_reference(problem) for problem in problems)


def independent_residual(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """||min(diag(Q) l, Q l + b)||_inf / ||b||_inf, recomputed densely."""
    Q = problem.G.toarray().T @ np.diag(problem.m_inv) @ problem.G.toarray()
    u_minus = problem.G.toarray().T @ problem.v_minus
    b = (1 + problem.restitution) * u_minus
    return float(np.max(np.abs(np.minimum(np.diag(Q) * impulses, Q @ impulses + b)))
                 / np.max(np.abs(b)))


@pytest.mark.parametrize("spec", [spec for spec in usable_solvers() if "impact" in spec.kinds],
                         ids=lambda spec: spec.key)
def test_success_means_residual_and_velocity_within_bounds(spec) -> None:
    for problem in hard_problems():
        assert problem.reference.verified, problem.name
        row, output = solve_and_judge(spec, problem, ACCURACY)
        if output.impulses is None or not np.all(np.isfinite(output.impulses)):
            assert row["success"] is False and row["status"] == "failed"
            continue
        residual = independent_residual(problem, output.impulses)
        assert row["success"] == (residual <= ACCURACY), (problem.name, residual)
        if row["success"]:
            velocity_error = problem.m_norm(problem.v_plus(output.impulses)
                                            - problem.reference.v_plus)
            assert velocity_error <= 1e-6 * problem.m_norm(problem.v_minus), problem.name
        else:
            assert row["status"] != "solved", problem.name
