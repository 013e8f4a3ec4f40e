"""pi-robust's presolve of parallel contacts: the looser constraint of each parallel group is
dropped, the smaller problem solved, and its answer taken on the whole problem's residual."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.problem import metrics
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


def ball_on_a_corner(offset: float) -> ImpactProblem:
    """One ball (2 dofs) with three contacts: a floor contact captured twice, the copy's
    n_rel raised by ``offset`` (a looser constraint when positive), and a wall."""
    G = sp.csc_matrix(np.array([[0.0, 0.0, 1.0],
                                [1.0, 1.0, 0.0]]))
    return ImpactProblem(name="ball on a corner", G=G, m_inv=np.array([0.5, 0.5]),
                         v_minus=np.array([-1.0, -2.0]), restitution=np.zeros(3),
                         n_rel=np.array([0.0, offset, 0.0]))


@pytest.mark.parametrize("offset", [0.0, 0.25, -0.25])
def test_the_looser_of_two_parallel_contacts_is_dropped_and_the_answer_solves_the_whole(
        offset: float) -> None:
    """The floor contact and its copy: the one whose constraint the other implies (the copy
    when its n_rel is larger, the first of equals) is dropped and ends at zero; the answer
    solves the whole problem."""
    from qpbench.solvers.pi_robust_kernel.parallel import diagonal_into, looser_parallel

    problem = ball_on_a_corner(offset)
    pose(problem, "lcp")
    Q = problem.Q
    diag = np.empty(3)
    assert diagonal_into(Q.indptr, Q.indices, Q.data, diag)
    assert np.array_equal(diag, Q.diagonal())
    dropped = looser_parallel(Q.indptr, Q.indices, Q.data, problem.b, diag)
    expected = 0 if offset < 0 else 1
    assert dropped.tolist() == [i == expected for i in range(3)]
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success
    assert output.impulses[expected] == 0.0
    assert output.info["path"].endswith("looser parallel contacts dropped")


def test_contacts_at_an_angle_or_facing_each_other_are_not_parallel() -> None:
    """A contact facing the floor from above (Q_ij < 0) and the wall (Q_ij = 0) are not
    parallel to the floor contact: nothing is dropped on a problem without a copy."""
    from qpbench.solvers.pi_robust_kernel.parallel import diagonal_into

    G = sp.csc_matrix(np.array([[0.0, 1.0, 0.0],
                                [1.0, 0.0, -1.0]]))
    problem = ImpactProblem(name="ball in a slot", G=G, m_inv=np.array([1.0, 1.0]),
                            v_minus=np.array([-1.0, -1.0]), restitution=np.zeros(3),
                            n_rel=np.zeros(3))
    pose(problem, "lcp")
    Q = problem.Q
    assert not diagonal_into(Q.indptr, Q.indices, Q.data, np.empty(3))


@pytest.mark.parametrize("family, size", [("grid", 6), ("box", 100), ("cradle", 10),
                                          ("mass-ratio", 5), ("k4-middle", None)])
def test_generated_families_without_copies_have_no_parallel_contacts(family: str,
                                                                     size: int | None) -> None:
    """The pass that reads diag(Q) finds no parallel pair where no contact is a copy, so
    these problems are solved whole, as before the presolve."""
    from qpbench.solvers.pi_robust_kernel.parallel import diagonal_into

    for seed in range(3):
        problem = generate(family, size, seed=seed)[0]
        pose(problem, "lcp")
        Q = problem.Q
        diag = np.empty(Q.shape[0])
        assert not diagonal_into(Q.indptr, Q.indices, Q.data, diag)
        assert np.array_equal(diag, Q.diagonal())


def test_the_smaller_problem_is_the_kept_rows_and_columns() -> None:
    """without() keeps Q's rows and columns of the kept contacts, in order, as SciPy's
    slicing does, and b's entries."""
    from qpbench.solvers.pi_robust_kernel.parallel import without

    problem = generate("near-duplicate", 4, seed=5)[0]
    pose(problem, "lcp")
    Q, b = problem.Q, problem.b
    dropped = np.zeros(b.size, dtype=bool)
    dropped[::3] = True
    kept, indptr, indices, data, small_b = without(Q.indptr, Q.indices, Q.data, b, dropped)
    assert kept.tolist() == np.flatnonzero(~dropped).tolist()
    small = sp.csc_matrix((data, indices, indptr), shape=(kept.size, kept.size))
    assert (small != Q[kept][:, kept]).nnz == 0
    assert np.array_equal(small_b, b[kept])


@pytest.mark.parametrize("size, seed", [(4, 11), (5, 12), (6, 13)])
def test_near_duplicate_contacts_are_solved_on_half_the_contacts(size: int, seed: int) -> None:
    """Every ball-ball contact of a near-duplicate grid has a copy at 1e-9 rad: one of each
    pair is dropped, and the answer, judged by qpbench on the whole problem, is accurate."""
    problem = generate("near-duplicate", size, seed=seed)[0]
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success
    assert metrics.residual(problem, output.impulses) <= 1e-8
    assert output.info["path"].endswith("looser parallel contacts dropped")
