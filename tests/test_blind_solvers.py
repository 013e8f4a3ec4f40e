"""Solvers are blind and judged on untouched data: a solver gets a copy of the problem without
its reference or stored data, and whatever it does to that copy cannot change its verdict."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bench_problems import collinear_balls

from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.problem import files
from qpbench.problem.reference import attach_reference
from qpbench.solvers.registry import resolve
from qpbench.solvers.run import call_solver, solve_and_judge

VERDICT = ("status", "success", "residual", "v_error", "energy_gain", "complementarity",
           "infeasibility", "energy_identity_gap")


@pytest.fixture()
def test_solvers():
    import bench_solvers

    with bench_solvers.registered():
        yield {spec.name: spec for spec in resolve(["test-exact/lcp", "test-vandal/lcp"])}


def dumped_problem():
    """A problem with a verified reference and stored data, as imported dumps have."""
    problem = attach_reference(collinear_balls("three-in-a-row", 3))
    problem.data["policy_sol"] = np.array([0.0, 0.0, 2.0])
    problem.metadata["note"] = "stored with the problem"
    return problem


def test_a_vandal_gets_the_honest_verdict_and_saw_no_answer(test_solvers) -> None:
    problem = dumped_problem()
    before = (problem.G.copy(), problem.v_minus.copy(), problem.m_inv.copy(), problem.b.copy())
    honest, _ = solve_and_judge(test_solvers["test-exact"], problem, 1e-8)
    vandal, output = solve_and_judge(test_solvers["test-vandal"], problem, 1e-8)
    assert honest["success"] is True
    assert {key: vandal[key] for key in VERDICT} == {key: honest[key] for key in VERDICT}
    assert output.info["saw"] == {"reference": False, "data": [], "metadata": [], "family": ""}
    assert (before[0] != problem.G).nnz == 0
    for now, then in zip((problem.v_minus, problem.m_inv, problem.b), before[1:], strict=True):
        np.testing.assert_array_equal(now, then)
    assert problem.reference is not None and "policy_sol" in problem.data


def test_every_call_gets_a_posed_copy_of_its_own_and_the_posing_is_timed_once(
        test_solvers) -> None:
    """The formulation is posed once per problem; each call gets a fresh copy of that posed
    problem, so what a vandal wrote into its copy never reaches a later call."""
    problem = dumped_problem()
    outputs = [call_solver(test_solvers["test-vandal"], problem, 1e-8) for _ in range(3)]
    for output in outputs:  # the exact answer, computed before the vandal wrote its NaNs
        np.testing.assert_allclose(output.impulses, outputs[0].impulses, rtol=0, atol=0)
        assert np.all(np.isfinite(output.impulses))
    assert len({output.formulation_time_s for output in outputs}) == 1
    assert outputs[0].formulation_time_s > 0


def test_a_vandal_in_a_bench_worker_gets_the_honest_row_on_every_repeat(
        test_solvers, tmp_path: Path) -> None:
    path = files.save(dumped_problem(), tmp_path / "three.npz")
    worker = CellSolver()
    limits = Limits(timeout_s=10.0, repeats=3)
    rows = {}
    for name in ("test-exact", "test-vandal"):
        cell = Cell(problem_file=str(path), problem="three-in-a-row", solver=name,
                    formulation="lcp", accuracy=1e-8, mode="warm")
        rows[name] = worker.solve(cell, limits)
    assert rows["test-vandal"]["repeats"] == 3
    assert rows["test-vandal"]["warm_start_source"] == "none"  # no reference ever leaks
    assert {key: rows["test-vandal"][key] for key in VERDICT} == {
        key: rows["test-exact"][key] for key in VERDICT}
