"""The formulations pose the same impact problem: primal constraints are w, the factored
dual has the dual's objective, and positive semi-definiteness is certified, not assumed."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from backend_cases import ALL_CASES, balls

from qpbench.problem import formulations
from qpbench.problem.formulations import (
    certify_psd,
    factored_dual_qp,
    factored_rows,
    primal_qp,
    regularized,
)
from qpbench.problem.impact import ImpactProblem


def moving_boundary_problem() -> ImpactProblem:
    """Three balls, one kinematic, mixed restitution and a non-zero nrel: every affine term."""
    problem = balls("mixed", [(0, 0), (1, 0.2), (2, 0)], [(0, 1), (1, 2), (0, 2)],
                    [(1, 0.3), (-0.5, 0), (-1, 0.1)], masses=[1.0, 2.0, float("inf")])
    return ImpactProblem.build("mixed", problem.G, problem.m_inv, problem.v_minus,
                               restitution=[0.0, 0.5, 1.0], n_rel=[0.1, -0.2, 0.05])


@pytest.mark.parametrize("seed", range(3))
def test_primal_constraint_at_v_plus_is_w(seed: int) -> None:
    """G^T v+ + c (G^T v- + nrel) + nrel = Q l + b for ANY l: the primal's affine term."""
    problem = moving_boundary_problem()
    impulses = np.random.default_rng(seed).uniform(-1, 2, problem.n_contacts)
    primal = primal_qp(problem)
    v_plus = problem.v_plus(impulses)
    assert np.all(v_plus[~primal.free] == problem.v_minus[~primal.free])
    constraint = primal.A @ v_plus[primal.free] - primal.lower
    assert constraint == pytest.approx(problem.w(impulses), abs=1e-12)


def test_primal_stationarity_gives_the_impulses() -> None:
    """M (v - v-) = G l on free dofs: the gradient of the objective at v+(l) is A^T l."""
    problem = moving_boundary_problem()
    impulses = np.array([0.4, 1.5, 0.2])
    primal = primal_qp(problem)
    v_free = problem.v_plus(impulses)[primal.free]
    gradient = primal.P @ v_free + primal.q
    assert gradient == pytest.approx(primal.A.T @ impulses, abs=1e-12)


def test_factored_dual_has_the_dual_objective_and_no_q() -> None:
    problem = moving_boundary_problem()
    factored = factored_dual_qp(problem)
    impulses = np.array([0.3, 0.0, 1.2])
    L = factored_rows(problem)
    x = np.concatenate([impulses, L @ impulses])
    assert factored.A @ x == pytest.approx(factored.b_eq, abs=1e-14)
    assert np.all(factored.G @ x <= factored.h + 1e-15)
    dual_objective = 0.5 * impulses @ (problem.Q @ impulses) + problem.b @ impulses
    factored_objective = 0.5 * x @ (factored.P @ x) + factored.q @ x
    assert factored_objective == pytest.approx(dual_objective, rel=1e-12)
    assert factored.impulses(x) == pytest.approx(impulses)
    # the kinematic ball's rows are dropped: k = free dofs
    assert L.shape == (int(np.count_nonzero(problem.m_inv > 0)), problem.n_contacts)


def test_singular_k3_is_certified_psd_by_eigenvalues() -> None:
    problem = ALL_CASES["k3"].problem
    assert problem.rank_deficiency == 1
    certificate = certify_psd(problem)
    assert certificate.psd and certificate.method == "eigenvalues"
    assert abs(certificate.value) <= certificate.tolerance


def test_gram_certificate_for_large_problems(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(formulations, "EIGENVALUE_LIMIT", 1)
    certificate = certify_psd(ALL_CASES["k3"].problem)
    assert certificate.psd and certificate.method == "gram"
    assert certificate.value <= certificate.tolerance


@pytest.mark.parametrize("limit", [10_000, 1])
def test_an_indefinite_q_is_not_certified(monkeypatch: pytest.MonkeyPatch, limit: int) -> None:
    monkeypatch.setattr(formulations, "EIGENVALUE_LIMIT", limit)
    problem = ALL_CASES["k3"].problem
    tampered = ImpactProblem.build("tampered", problem.G, problem.m_inv, problem.v_minus)
    # a Q that is not G^T M^-1 G: one eigenvalue of -1
    tampered.__dict__["Q"] = sp.csc_matrix(np.diag([1.0, 1.0, -1.0]))
    assert not certify_psd(tampered).psd


def test_regularized_adds_delta_on_the_diagonal_only() -> None:
    Q = ALL_CASES["k3"].problem.Q
    shifted = regularized(Q, 1e-3)
    assert (shifted - Q).toarray() == pytest.approx(1e-3 * np.eye(3))
