"""pi-robust's dense pivoting path for problems of a few contacts."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from qpbench.problem import metrics
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


def csc_of(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    matrix = sp.csc_matrix(Q)
    matrix.sort_indices()
    return matrix.indptr, matrix.indices, matrix.data


def enumerated_solution(Q: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The LCP's solution found by trying every free set (Q positive definite: it is unique)."""
    n = b.size
    for size in range(n + 1):
        for free in itertools.combinations(range(n), size):
            index = list(free)
            impulses = np.zeros(n)
            impulses[index] = np.linalg.solve(Q[np.ix_(index, index)], -b[index])
            if impulses.min() >= -1e-12 and (Q @ impulses + b).min() >= -1e-12:
                return impulses
    raise AssertionError("no free set solves it")


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 8), seed=st.integers(0, 2**31 - 1))
def test_dense_pivoting_finds_the_unique_solution_when_q_is_positive_definite(
        n: int, seed: int) -> None:
    from qpbench.solvers.pi_robust_kernel.dense import dense_pivoting

    generator = np.random.default_rng(seed)
    J = generator.normal(size=(n, n + 2))
    Q, b = J @ J.T, generator.normal(size=n)
    impulses, solves, found = dense_pivoting(csc_of(Q), b, np.zeros(n), 1e-12, 4 * n + 8)
    assert found and 1 <= solves <= 4 * n + 8
    np.testing.assert_allclose(impulses, enumerated_solution(Q, b), rtol=1e-8, atol=1e-10)


def test_dense_pivoting_holds_a_duplicated_contact_at_zero() -> None:
    """Two contacts with the same row of J (Q singular): the pair's impulses together are
    what one of them alone would take, and the answer is complementary."""
    from qpbench.solvers.pi_robust_kernel.dense import dense_pivoting

    J = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 1.0, 0.0], [0.0, 0.2, 1.0]])
    v = np.array([-1.0, -0.5, 0.4])  # approaching along the first two contacts
    Q, b = J @ J.T, J @ v
    impulses, _, found = dense_pivoting(csc_of(Q), b, np.zeros(4), 1e-12, 16)
    assert found and impulses.min() >= 0.0
    w = Q @ impulses + b
    assert w.min() >= -1e-12 and abs(impulses @ w) <= 1e-12
    single = enumerated_solution(Q[1:, 1:], b[1:])
    assert impulses[0] + impulses[1] == pytest.approx(single[0], rel=1e-12)
    np.testing.assert_allclose(impulses[2:], single[1:], rtol=1e-12, atol=1e-14)


def test_dense_pivoting_gives_up_after_its_budget_when_no_policy_is_feasible() -> None:
    """w_1 + w_2 = -2 for every l: the LCP has no solution, and the budget ends the try."""
    from qpbench.solvers.pi_robust_kernel.dense import dense_pivoting

    Q, b = np.array([[1.0, -1.0], [-1.0, 1.0]]), np.array([-1.0, -1.0])
    _, solves, found = dense_pivoting(csc_of(Q), b, np.zeros(2), 1e-12, 5)
    assert not found and solves == 5


def test_dense_pivoting_never_finds_an_answer_with_a_nan() -> None:
    """A NaN in Q counts as infeasible wherever it reaches, so the try ends unfound."""
    from qpbench.solvers.pi_robust_kernel.dense import dense_pivoting

    Q = np.array([[2.0, np.nan], [np.nan, 2.0]])
    _, solves, found = dense_pivoting(csc_of(Q), np.array([-1.0, -1.0]), np.zeros(2), 1e-12, 4)
    assert not found and solves == 4


@pytest.mark.parametrize("family,size", [("k3", None), ("k4", None), ("k4-middle", None),
                                         ("cradle", 10), ("cradle", 30), ("grid", 3),
                                         ("grid", 4), ("box", 8), ("box", 25),
                                         ("near-duplicate", 3)])
def test_pi_robust_answers_problems_of_a_few_contacts_at_1e8(family: str,
                                                             size: int | None) -> None:
    """Problems of at most DENSE_CONTACTS contacts (singular Q on K3, K4 and grids) are
    solved to qpbench's residual, whichever path ends the solve, with no negative impulse."""
    from qpbench.solvers.pi_robust_kernel.constants import DENSE_CONTACTS

    for seed in range(5):
        problem = generate(family, size, seed=seed)[0]
        assert problem.n_contacts <= DENSE_CONTACTS
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
        assert row["success"] and output.claimed_success, (family, seed)
        assert metrics.residual(problem, output.impulses) <= 1e-8
        assert output.impulses.min() >= 0.0


def test_pi_robust_counts_the_dense_tries_solves_when_the_general_path_ends_the_solve() -> None:
    """On near-duplicate contacts solved whole (the wide entry, which does not drop parallel
    contacts first) whose dense try spends its budget, the general path then solves the
    problem, and the reported solves include the dense try's."""
    from qpbench.solvers import pi_robust
    from qpbench.solvers.pi_robust_kernel import entry
    from qpbench.solvers.pi_robust_kernel.constants import DENSE_BUDGET, PATH_POLICY_ITERATION

    settings = pi_robust.settings_for(1e-8)
    fell_through = 0
    for seed in range(40):
        problem = generate("near-duplicate", 2, seed=seed)[0]
        pose(problem, "lcp")
        impulses, converged, path, solves, *_ = pi_robust.kernel_call(
            entry.envelope_pi_robust, problem, settings, None)
        assert converged and metrics.residual(problem, impulses) <= 1e-8, seed
        if path == PATH_POLICY_ITERATION:
            fell_through += 1
            assert solves > DENSE_BUDGET
    assert fell_through > 0
