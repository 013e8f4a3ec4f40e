"""References come from two independent methods that agree; disagreement is flagged."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.problem import metrics
from qpbench.problem import reference as reference_module
from qpbench.problem.generate import generate
from qpbench.problem.impact import Reference
from qpbench.problem.reference import (
    REFERENCE_TOLERANCE,
    _least_change_solve,
    _min_norm_solve,
    active_set_polish,
    attach_reference,
)


@pytest.mark.parametrize(
    ("family", "size"),
    [("k3", None), ("k4", None), ("k4-middle", None), ("cradle", 50), ("grid", 10),
     ("box", 200), ("mass-ratio", 5), ("near-duplicate", 4)],
)
def test_hard_families_get_verified_references(family: str, size: int | None) -> None:
    problem = attach_reference(generate(family, size=size, seed=1)[0])
    reference = problem.reference
    assert reference.method != reference.check_method
    assert reference.verified, (reference.method, reference.check_method, reference.agreement)
    assert metrics.residual(problem, reference.impulses) < 1e-6
    assert problem.metadata["reference_verified"] is True


def test_k3_reference_is_the_reflection() -> None:
    k3 = attach_reference(generate("k3")[0])
    assert k3.reference.v_plus.reshape(-1, 2)[:, 0] == pytest.approx([-1.0, 0.0, 1.0])


def test_references_that_disagree_are_flagged_and_v_error_is_not_computed() -> None:
    problem = generate("cradle", size=3)[0]
    far = problem.v_minus + 1.0
    problem.reference = Reference(far, np.zeros(2), "a", problem.v_minus, "b",
                                  agreement=0.5, tolerance=REFERENCE_TOLERANCE)
    assert not problem.reference.verified
    assert np.isnan(metrics.evaluate(problem, np.zeros(2), 1e-8)["v_error"])


def test_large_blocks_are_polished_near_the_minimum_norm_solution() -> None:
    rows = np.random.default_rng(0).standard_normal((40, 60))  # Q = L^T L: rank 40 of 60
    Q = rows.T @ rows
    rhs = Q @ np.random.default_rng(1).standard_normal(60)  # a consistent right side
    found = _least_change_solve(sp.csc_matrix(Q), rhs)
    minimum_norm = _min_norm_solve(Q, rhs)
    assert np.abs(Q @ found - rhs).max() <= 1e-9 * np.abs(rhs).max()
    assert np.abs(found - minimum_norm).max() <= 1e-6 * np.abs(minimum_norm).max()


def test_the_sparse_polish_reaches_the_dense_polish_residual(
        monkeypatch: pytest.MonkeyPatch) -> None:
    problem = generate("box", size=200, seed=1)[0]
    start = np.full(problem.n_contacts, 1e-3)  # every contact active
    dense = active_set_polish(problem, start)
    monkeypatch.setattr(reference_module, "DENSE_POLISH_LIMIT", 0)
    sparse = active_set_polish(problem, start)
    assert metrics.residual(problem, sparse) <= max(10 * metrics.residual(problem, dense), 1e-12)
