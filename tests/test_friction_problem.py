"""The frictional problem kind: its matrices, the views frictionless solvers take, the
natural-map residual (the frictionless one at mu = 0), and its problem files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from friction_cases import ball_on_floor, pair_on_floor

from qpbench.errors import InputError
from qpbench.problem import files, metrics
from qpbench.problem import friction_metrics as fm
from qpbench.problem.friction import FrictionalProblem, FrictionalReference


def three_contacts(mu: float, seed: int = 0) -> FrictionalProblem:
    """Two balls on a floor touching each other, random velocities, a moving floor."""
    return pair_on_floor(mu, seed, falling=False, d_rel=[0.1, 0.0, 0.0])


def test_w_and_q_of_a_ball_on_the_floor() -> None:
    problem = ball_on_floor(u_normal=-2.0, u_tangential=1.0, mu=0.5, restitution=0.5)
    np.testing.assert_allclose(problem.W.toarray(), np.eye(2))
    np.testing.assert_allclose(problem.q, [(1 + 0.5) * -2.0, 1.0])


@pytest.mark.parametrize("u_tangential, sticks", [(0.6, True), (1.5, False)])
def test_the_hand_solution_of_a_ball_on_the_floor_has_zero_residual(
        u_tangential: float, sticks: bool) -> None:
    """W = I/m: the ball sticks iff |u_T-| <= mu (1 + e) |u_N-| (here mu (1 + e) |u_N-| = 1)."""
    problem = ball_on_floor(u_normal=-2.0, u_tangential=u_tangential, mu=0.5)
    normal = 2.0
    tangential = -u_tangential if sticks else -0.5 * normal
    answer = np.array([normal, tangential])
    assert fm.residual(problem, answer) == pytest.approx(0.0, abs=1e-15)
    wrong = np.array([normal, -0.5 * normal if sticks else -u_tangential])
    assert fm.residual(problem, wrong) > 0.1


def test_scaling_the_velocities_by_a_power_of_two_scales_q_and_the_answer_exactly() -> None:
    # the hand solution of a sliding ball, at a quarter of the speed: the same law holds for
    # a quarter of the impulses, to the last bit, on a problem that keeps no reference
    problem = ball_on_floor(u_normal=-2.0, u_tangential=1.5, mu=0.5)
    quarter = problem.with_velocities_scaled(0.25)
    assert quarter.reference is None and quarter.q.tolist() == (0.25 * problem.q).tolist()
    answer = np.array([2.0, -1.0])
    assert fm.residual(problem, answer) == pytest.approx(0.0, abs=1e-15)
    assert fm.residual(quarter, 0.25 * answer) == fm.residual(problem, answer)
    assert quarter.largest_velocity == 0.25 * problem.largest_velocity


def test_at_mu_zero_the_residual_is_the_frictionless_one_to_the_last_bit() -> None:
    problem = three_contacts(mu=0.0)
    rng = np.random.default_rng(1)
    for _ in range(20):
        normal = rng.random(3) * rng.integers(0, 2, 3)
        answer = np.concatenate([normal, np.zeros(3)])
        assert fm.residual(problem, answer) == metrics.residual(problem.normal, normal)


def test_the_relaxed_problem_is_an_impact_problem_with_the_same_velocities() -> None:
    problem = three_contacts(mu=0.4)
    relaxed = problem.relaxed()
    n = problem.n_contacts
    q_normal, q_tangential = problem.q[:n], problem.q[n:]
    np.testing.assert_allclose(relaxed.b, np.concatenate([q_normal + 0.4 * q_tangential,
                                                          q_normal - 0.4 * q_tangential]))
    z = np.random.default_rng(2).random(2 * n)
    np.testing.assert_allclose(relaxed.v_plus(z), problem.v_plus(problem.from_relaxed(z)))


def test_the_relaxed_optimum_has_zero_ccp_residual_but_not_zero_coulomb_residual() -> None:
    """A sliding ball: the relaxation makes it separate (u_N = mu |u_T| > 0), which Coulomb's
    law forbids; its ccp residual is zero, its Coulomb residual (the model error) is not."""
    problem = ball_on_floor(u_normal=-1.0, u_tangential=3.0, mu=0.5)
    z_plus_only = np.array([0.0, 0.0])
    # solve the 2x2 relaxed LCP by hand: only the column n - mu t can be active (u_T > 0)
    relaxed = problem.relaxed()
    column = 1
    z_plus_only[column] = -relaxed.b[column] / relaxed.Q.toarray()[column, column]
    assert metrics.residual(relaxed, z_plus_only) == pytest.approx(0.0, abs=1e-15)
    answer = problem.from_relaxed(z_plus_only)
    assert fm.residual(problem, answer, "ccp") == pytest.approx(0.0, abs=1e-15)
    assert fm.residual(problem, answer, "coulomb") > 1e-3


def test_staggered_views_carry_the_other_block() -> None:
    problem = three_contacts(mu=0.5)
    n = problem.n_contacts
    W = problem.W.toarray()
    tangential = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(problem.normal_given(tangential).b,
                               problem.q[:n] + W[:n, n:] @ tangential)
    normal = np.array([1.0, 0.0, 2.0])
    W_TT, linear, lower, upper = problem.friction_box(normal)
    np.testing.assert_allclose(W_TT.toarray(), W[n:, n:])
    np.testing.assert_allclose(linear, problem.q[n:] + W[n:, :n] @ normal)
    np.testing.assert_allclose(upper, 0.5 * normal)
    np.testing.assert_allclose(lower, -0.5 * normal)


def test_a_stewart_trinkle_solution_maps_to_a_coulomb_solution() -> None:
    """Sliding ball: z = (l_N, b+, b-, s) with l_T = b+ - b- and the slip speed s."""
    problem = ball_on_floor(u_normal=-2.0, u_tangential=1.5, mu=0.5)
    A, c = problem.stewart_trinkle()
    z = np.array([2.0, 0.0, 1.0, 0.5])  # l_N = 2, l_T = -1 = -mu l_N, slip 1.5 - 1 = 0.5
    w = A @ z + c
    assert np.min(w) >= -1e-15 and abs(z @ w) <= 1e-15
    assert fm.residual(problem, problem.from_stewart_trinkle(z)) == pytest.approx(0.0, abs=1e-15)


def test_a_frictional_problem_file_round_trips(tmp_path: Path) -> None:
    problem = three_contacts(mu=0.5)
    problem.reference = FrictionalReference(
        impulses=np.arange(6.0), v_plus=np.ones(4), method="enumeration", residual=1e-14,
        unique=True)
    loaded = files.load(files.save(problem, tmp_path / "pair"))
    assert isinstance(loaded, FrictionalProblem)
    assert (loaded.T != problem.T).nnz == 0 and (loaded.G != problem.G).nnz == 0
    np.testing.assert_array_equal(loaded.mu, problem.mu)
    np.testing.assert_array_equal(loaded.d_rel, problem.d_rel)
    assert loaded.reference is not None and loaded.reference.verified
    np.testing.assert_array_equal(loaded.reference.impulses, np.arange(6.0))


@pytest.mark.parametrize("field, value, message", [
    ("mu", -0.1, "friction coefficients must be >= 0"),
    ("mu", float("nan"), "contains NaN or infinity"),
    ("d_rel", [float("inf")], "contains NaN or infinity"),
])
def test_bad_friction_data_is_one_line_naming_the_field(field: str, value: object,
                                                        message: str) -> None:
    arguments = {"mu": 0.5, "d_rel": None, field: value}
    with pytest.raises(InputError, match=f"attribute '{field}': {message}"):
        FrictionalProblem.build("bad", G=[[0.0], [1.0]], T=[[-1.0], [0.0]], m_inv=[1.0, 1.0],
                                v_minus=[0.0, -1.0], **arguments)
