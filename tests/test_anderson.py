"""Anderson acceleration (qpbench.solvers.anderson) and the staggered loop that uses it."""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.problem import friction_metrics
from qpbench.problem.friction_generate import generate
from qpbench.solvers import accuracy, registry
from qpbench.solvers.anderson import anderson_start, step_length
from qpbench.solvers.run import call_solver


def test_mixing_four_rounds_of_an_affine_map_in_three_dimensions_lands_on_its_fixed_point(
        ) -> None:
    """On an affine map the mixing is GMRES in disguise: k rounds are exact in k - 1
    dimensions, where the plain iteration is still far off."""
    rng = np.random.default_rng(3)
    A = 0.9 * np.linalg.qr(rng.standard_normal((3, 3)))[0]  # a contraction, rate 0.9
    b = rng.standard_normal(3)
    fixed_point = np.linalg.solve(np.eye(3) - A, b)
    starts, answers = [np.zeros(3)], [b.copy()]
    for _ in range(3):
        start = anderson_start(np.array(starts), np.array(answers))
        starts.append(start)
        answers.append(A @ start + b)
    mixed = anderson_start(np.array(starts), np.array(answers))
    np.testing.assert_allclose(mixed, fixed_point, rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(answers[-1] - fixed_point) > 1e-3  # what the map alone reaches


def test_one_round_or_repeated_rounds_start_from_the_last_answer() -> None:
    start, answer = np.array([1.0, -2.0]), np.array([0.5, 0.25])
    np.testing.assert_array_equal(anderson_start(start[None], answer[None]), answer)
    repeated = anderson_start(np.array([start, start, start]), np.array([answer] * 3))
    np.testing.assert_array_equal(repeated, answer)  # every difference dropped
    assert step_length(start, answer) == pytest.approx(np.hypot(0.5, 2.25))


@pytest.mark.parametrize("key", ["pi-robust/staggered", "pgs/staggered"])
def test_staggered_rounds_fall_with_anderson_mixing_and_the_answer_meets_the_law(
        key: str) -> None:
    """A pyramid of 21 contacts: the plain loop (depth 0) takes 56 rounds, the table's mixing
    far fewer, and both answers meet Coulomb's law at 1e-8 by qpbench's own residual."""
    problem = generate("pyramid", 5, seed=100)[0]
    spec = registry.get(key, "frictional")
    mixed = call_solver(spec, problem, 1e-8)
    with accuracy.overridden("staggered", anderson_depth=0):
        plain = call_solver(spec, problem, 1e-8)
    assert accuracy.OPTIONS["staggered"]["anderson_depth"] > 0
    for output in (mixed, plain):
        assert friction_metrics.residual(problem, output.impulses) <= 1e-8
    assert 3 * mixed.info["outer_iterations"] <= plain.info["outer_iterations"]


@pytest.mark.parametrize("seed", [0, 630601])
def test_on_the_wedge_which_has_no_solution_mixing_does_not_extrapolate_without_end(
        seed: int) -> None:
    """Without a fixed point the fit would extrapolate further each round (impulses of 3e14
    after 2,000 rounds on seed 630601, each round slower); with the longest mixes refused the
    answer stays within two orders of magnitude of the plain loop's."""
    problem = generate("wedge", 1, seed=seed)[0]
    spec = registry.get("pi-robust/staggered", "frictional")
    with accuracy.overridden("staggered", max_outer=2000):
        mixed = call_solver(spec, problem, 1e-8)
        with accuracy.overridden("staggered", anderson_depth=0):
            plain = call_solver(spec, problem, 1e-8)
    assert mixed.info["outer_iterations"] == 2000
    assert np.abs(mixed.impulses).max() <= 100 * np.abs(plain.impulses).max()
