"""pi-robust's policy blocks on a dense box pile: kept, updated, and solved to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.inner_solvers import choose_by_name
from qpbench.problem.impact import ImpactProblem
from qpbench.simulation.scaling import box_pile, circle_pile
from qpbench.simulation.stepper import Simulator
from qpbench.solvers import sparse_cholesky
from qpbench.solvers.lcp import Lcp
from qpbench.solvers.lcp_interior import NOT_TRIED, interior_point
from qpbench.solvers.pi_robust import _normal_matrix
from qpbench.solvers.pi_robust_blocks import BlockSolver


@pytest.fixture(scope="module")
def pile() -> ImpactProblem:
    """The first impact of a dense pile of 200 unit boxes (1,504 contacts, 600 degrees of
    freedom: Q singular)."""
    simulator = Simulator(box_pile(200), choose_by_name("pi-robust"))
    found = simulator.find_contacts(simulator.positions, simulator.positions)
    return simulator.impact_problem(found, simulator.dof_velocity())


def backward_error(lcp: Lcp, policy: np.ndarray, rho: float, x: np.ndarray,
                   rhs: np.ndarray) -> float:
    """``|(Q_FF + rho D_F) x - rhs|`` relative to ``|Q_FF + rho D_F| |x| + |rhs|``."""
    index = np.flatnonzero(policy)
    block = lcp.Q[index][:, index].toarray() + np.diag(rho * lcp.safe_diag[index])
    size = np.abs(block) @ np.abs(x) + np.abs(rhs)
    return float(np.max(np.abs(block @ x - rhs)) / np.max(size))


def test_a_block_a_few_contacts_from_the_last_is_updated_and_solved_to_rounding(
        pile: ImpactProblem) -> None:
    lcp = Lcp.of(pile, dense_limit=300)
    blocks = BlockSolver(lcp)
    rng = np.random.default_rng(0)
    policy = rng.random(lcp.n) < 0.9
    rho = 1e-5
    for _ in range(4):
        assert blocks.updatable(policy)
        rhs = rng.normal(size=int(policy.sum()))
        x = blocks.solve(policy, np.flatnonzero(policy), rho, rhs)
        assert backward_error(lcp, policy, rho, x, rhs) <= 1e-14
        policy = policy.copy()
        policy[rng.choice(lcp.n, 5, replace=False)] ^= True  # five contacts change
    counts = blocks.counts()
    assert counts["factorizations"] == counts["factorizations_over_dofs"] == 4
    assert counts["factor_updates"] == 3


def test_a_new_prox_weight_or_a_large_change_factors_afresh(pile: ImpactProblem) -> None:
    lcp = Lcp.of(pile, dense_limit=300)
    blocks = BlockSolver(lcp)
    rng = np.random.default_rng(1)
    policy = rng.random(lcp.n) < 0.9
    index = np.flatnonzero(policy)
    blocks.solve(policy, index, 1e-5, np.ones(index.size))
    blocks.solve(policy, index, 1e-7, np.ones(index.size))  # another rho
    changed = policy.copy()
    changed[rng.choice(lcp.n, 200, replace=False)] ^= True  # more than UPDATE_CONTACTS
    blocks.solve(changed, np.flatnonzero(changed), 1e-7, np.ones(int(changed.sum())))
    assert blocks.counts()["factorizations"] == 3
    assert blocks.counts()["factor_updates"] == 0


def test_without_cholmod_no_block_is_updatable(pile: ImpactProblem,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sparse_cholesky, "cholmod", None)
    lcp = Lcp.of(pile, dense_limit=300)
    assert not BlockSolver(lcp).updatable(np.ones(lcp.n, dtype=bool))


def test_an_iterate_not_tried_leaves_the_next_one_offered(pile: ImpactProblem) -> None:
    """A finish that declines an iterate (NOT_TRIED) is offered every later iterate below
    the same residual, where one that failed (None) waits for a residual ten times smaller;
    on a stall the best iterate goes to ``stall_finish``."""
    lcp = Lcp.of(pile, dense_limit=300)

    def offered_residuals(answer: object) -> tuple[list[float], list[float]]:
        offered: list[float] = []
        at_stall: list[float] = []

        def finish(impulses: np.ndarray, w: np.ndarray) -> object:
            offered.append(lcp.residual(impulses))
            return answer

        def stall(impulses: np.ndarray, w: np.ndarray) -> None:
            at_stall.append(lcp.residual(impulses))

        normal = _normal_matrix(lcp)
        interior_point(lcp, normal.lcp, normal.root, normal, 1e-14, 25, finish, 1e-2,
                       end_on_stall=True, stall_finish=stall)
        return offered, at_stall

    declined, _ = offered_residuals(NOT_TRIED)
    failed, _ = offered_residuals(None)
    assert len(declined) > len(failed) >= 1
    assert all(later <= 0.1 * earlier for earlier, later in zip(failed, failed[1:], strict=False))
    assert all(residual <= 1e-2 for residual in declined)


def test_a_stall_that_is_not_tried_ends_unconverged(pile: ImpactProblem) -> None:
    """Without a ``stall_finish``, a ``try_finish`` that declines every iterate declines the
    stall's best one too, and the interior point ends on it unconverged, never handing back
    the NOT_TRIED marker as an answer."""
    lcp = Lcp.of(pile, dense_limit=300)
    normal = _normal_matrix(lcp)
    impulses, converged, _, finishing = interior_point(
        lcp, normal.lcp, normal.root, normal, 1e-14, 80,
        lambda impulses, w: NOT_TRIED, 1e-2, end_on_stall=True)
    assert not converged and finishing == 1
    assert impulses is not NOT_TRIED and impulses.shape == (lcp.n,)


def test_each_step_of_a_settling_pile_of_5000_boxes_meets_the_accuracy() -> None:
    """Where a step is degenerate (contacts where both l and w go to zero, which slows the
    interior point near its end), the interior iterates are finished by policy iteration on
    updated blocks at the prox weight ``UPDATED_FINISH_RHO``: each step of the settling pile
    is solved to the accuracy the simulator asks."""
    simulator = Simulator(box_pile(5000), choose_by_name("pi-robust"), accuracy=1e-8)
    for _ in range(2):
        simulator.step()
    assert simulator.log.solves == 2
    assert simulator.log.inaccurate == 0 and simulator.log.max_residual <= 1e-8


def test_each_step_of_a_settling_pile_of_20000_circles_meets_the_accuracy() -> None:
    """A step where the interior point's residual wavers for a while, its steps short, while
    its infeasibility still falls: a stall is declared only when neither falls, so the
    interior point goes on to where policy iteration finishes it, and every step of the
    settling pile is solved to the accuracy the simulator asks."""
    simulator = Simulator(circle_pile(20000), choose_by_name("pi-robust"), accuracy=1e-8)
    for _ in range(4):
        simulator.step()
    assert simulator.log.solves == 4
    assert simulator.log.inaccurate == 0 and simulator.log.max_residual <= 1e-8
