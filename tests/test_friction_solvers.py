"""The frictional solvers: nsgs, the ccp twins, staggered projections and Lemke on the
Stewart-Trinkle LCP, each judged by qpbench on problems with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.problem import friction_metrics as fm
from qpbench.problem import metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import registry
from qpbench.solvers.run import solve_and_judge


def ball_on_floor(u_normal: float, u_tangential: float, mu: float, restitution: float = 0.0,
                  mass: float = 1.0) -> FrictionalProblem:
    """One ball2d ball (2 dofs) on the floor y = 0: n = (0, 1), t = (-1, 0), W = I / m."""
    return FrictionalProblem.build("ball", G=[[0.0], [1.0]], T=[[-1.0], [0.0]],
                                   m_inv=[1.0 / mass, 1.0 / mass],
                                   v_minus=[-u_tangential, u_normal], mu=mu,
                                   restitution=restitution)


def hand_answer(u_normal: float, u_tangential: float, mu: float, restitution: float = 0.0,
                mass: float = 1.0) -> np.ndarray:
    """The ball sticks iff |u_T-| <= mu (1 + e) |u_N-|; else it slides with
    l_T = -mu l_N sign(u_T-)."""
    normal = mass * (1.0 + restitution) * -u_normal
    if abs(u_tangential) <= mu * normal / mass:
        return np.array([normal, -mass * u_tangential])
    return np.array([normal, -mu * normal * np.sign(u_tangential)])


def pair_on_floor(mu: float, seed: int = 0) -> FrictionalProblem:
    """Two balls on a floor, touching each other: three contacts."""
    rng = np.random.default_rng(seed)
    G = np.zeros((4, 3))
    T = np.zeros((4, 3))
    G[1, 0], T[0, 0] = 1.0, -1.0  # ball 0 on the floor
    G[3, 1], T[2, 1] = 1.0, -1.0  # ball 1 on the floor
    G[0, 2], G[2, 2] = -1.0, 1.0  # ball 0 left of ball 1: n = (-1, 0) on ball 0
    T[1, 2], T[3, 2] = -1.0, 1.0
    velocity = rng.standard_normal(4)
    velocity[[1, 3]] = -np.abs(velocity[[1, 3]]) - 0.5  # both fall onto the floor
    return FrictionalProblem.build("pair", G, T, m_inv=[1.0, 1.0, 0.5, 0.5], v_minus=velocity,
                                   mu=mu, restitution=0.3)


def row_of(key: str, problem: FrictionalProblem, accuracy: float = 1e-10,
           warm_start: np.ndarray | None = None):
    spec = registry.get(key)
    return solve_and_judge(spec, problem, accuracy, warm_start)


BALLS = [(-2.0, 0.6, 0.5), (-2.0, 1.5, 0.5), (-1.0, -3.0, 0.5), (-1.0, 0.0, 0.2)]


# --- nsgs ------------------------------------------------------------------------------
@pytest.mark.parametrize("u_normal, u_tangential, mu", BALLS)
def test_nsgs_finds_the_hand_answer_of_a_ball_on_the_floor(u_normal: float, u_tangential: float,
                                                           mu: float) -> None:
    problem = ball_on_floor(u_normal, u_tangential, mu, restitution=0.5, mass=2.0)
    row, output = row_of("nsgs/nsgs", problem)
    assert row["status"] == "solved" and row["status_honest"]
    np.testing.assert_allclose(output.impulses,
                               hand_answer(u_normal, u_tangential, mu, 0.5, 2.0), atol=1e-12)
    assert output.iterations == 1  # one contact: one exact local solve


def test_nsgs_on_three_coupled_contacts_reaches_1e_10() -> None:
    for seed in range(5):
        row, output = row_of("nsgs/nsgs", pair_on_floor(mu=0.6, seed=seed))
        assert row["status"] == "solved" and row["residual"] <= 1e-10
        assert output.info["outer_iterations"] == output.iterations


def test_nsgs_warm_started_from_its_answer_needs_at_most_one_sweep() -> None:
    problem = pair_on_floor(mu=0.6, seed=3)
    _, first = row_of("nsgs/nsgs", problem)
    row, again = row_of("nsgs/nsgs", problem, warm_start=first.impulses)
    assert row["status"] == "solved" and again.iterations <= 1


def test_nsgs_at_mu_zero_gives_the_frictionless_answer() -> None:
    problem = pair_on_floor(mu=0.0, seed=1)
    row, output = row_of("nsgs/nsgs", problem)
    normal, tangential = problem.split(output.impulses)
    assert np.all(tangential == 0.0)
    assert metrics.residual(problem.normal, normal) == fm.residual(problem, output.impulses)
    assert row["status"] == "solved"
