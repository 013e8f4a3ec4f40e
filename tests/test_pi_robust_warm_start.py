"""pi-robust from a warm start on a sparse problem: a settling pile's previous impulses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from qpbench.inner_solvers import choose_by_name
from qpbench.problem import files
from qpbench.problem.impact import ImpactProblem
from qpbench.simulation.scaling import circle_pile
from qpbench.simulation.stepper import Simulator
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


@pytest.fixture(scope="module")
def second_step(tmp_path_factory: pytest.TempPathFactory) -> tuple[ImpactProblem, np.ndarray]:
    """The second impact of a settling pile of 1,000 circles (2,921 contacts, 2,000 degrees
    of freedom: Q singular) and its warm start: the first step's impulses of the same
    contacts, as a scene that caches impulses carries them (SCISim's ``cache_impulses``) and
    the simulator's capture stores them beside the problem (``warm_start``). Its envelope is
    too wide for the compiled kernel, which declines it: the Python path solves it."""
    scene = circle_pile(1000)
    scene = dataclasses.replace(scene, impact=dataclasses.replace(scene.impact,
                                                                  cache_impulses=True))
    folder = tmp_path_factory.mktemp("pile")
    simulator = Simulator(scene, choose_by_name("pi-robust"), capture=folder)
    simulator.step()
    simulator.step()
    _, second = (files.load(path) for path in files.find([folder]))
    assert isinstance(second, ImpactProblem)
    return second, second.data["warm_start"]


def test_a_far_warm_start_is_left_to_the_interior_point(
        second_step: tuple[ImpactProblem, np.ndarray],
        pi_robust_methods: list[str]) -> None:
    """The previous step's impulses are a step off: one solve of their policy leaves hundreds
    of contacts infeasible, so the interior point runs first, as from a cold start, and the
    answer is judged solved (policy iteration from that start once spent 100 solves, and the
    interior point after it ended at a residual of 6e-6)."""
    problem, warm = second_step
    assert np.count_nonzero(warm) > 0.9 * problem.n_contacts
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8, warm_start=warm)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert pi_robust_methods[0] == "interior point", pi_robust_methods
    assert not output.info["path"].startswith("policy iteration from the start")


def test_a_near_warm_start_is_followed_by_policy_iteration(
        second_step: tuple[ImpactProblem, np.ndarray],
        pi_robust_methods: list[str]) -> None:
    """A start close to the answer (the answer scaled by 1.01) leaves few contacts
    infeasible after one solve of its policy; policy iteration goes on from it and ends the
    solve without the interior point."""
    problem, _ = second_step
    _, cold = solve_and_judge(get("pi-robust"), problem, 1e-8)
    pi_robust_methods.clear()
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8,
                                  warm_start=1.01 * cold.impulses)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert pi_robust_methods == ["policy iteration"], pi_robust_methods
