"""Frictional references: hand-solvable single contacts, a problem with two solutions, a
jammed wedge with no solution, and enumeration and Lemke agreeing on random small problems."""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.problem import friction_metrics as fm
from qpbench.problem import friction_reference as fr
from qpbench.problem.friction import FrictionalProblem


def ball_on_floor(u_normal: float, u_tangential: float, mu: float, restitution: float = 0.0,
                  mass: float = 1.0) -> FrictionalProblem:
    """A ball (2 dofs) on the floor: n = (0, 1), t = (-1, 0), so W = I / m."""
    return FrictionalProblem.build("ball", G=[[0.0], [1.0]], T=[[-1.0], [0.0]],
                                   m_inv=[1 / mass, 1 / mass], v_minus=[-u_tangential, u_normal],
                                   mu=mu, restitution=restitution)


def disc_on_floor(u_normal: float, u_tangential: float, mu: float, restitution: float,
                  mass: float = 2.0, radius: float = 0.5) -> FrictionalProblem:
    """A rigid disc (x, y, theta; I = m R^2 / 2) on the floor: the arm term r x t = -R gives
    W_TT = 1/m + R^2 / I = 3/m and W_NT = 0. Spin 0, so u_T- = -v_x."""
    inertia = 0.5 * mass * radius ** 2
    return FrictionalProblem.build("disc", G=[[0.0], [1.0], [0.0]], T=[[-1.0], [0.0], [-radius]],
                                   m_inv=[1 / mass, 1 / mass, 1 / inertia],
                                   v_minus=[-u_tangential, u_normal, 0.0], mu=mu,
                                   restitution=restitution, dofs_per_body=3)


def sticks(problem: FrictionalProblem) -> bool:
    normal, tangential = problem.split(problem.reference.impulses)
    return bool(abs(tangential[0]) < problem.mu[0] * normal[0] * (1 - 1e-9))


@pytest.mark.parametrize("u_tangential", [0.3, 0.74, 0.76, 2.0, -0.5, -1.5])
def test_a_ball_on_a_rough_floor_sticks_iff_the_slip_is_within_mu_1_plus_e(
        u_tangential: float) -> None:
    """W = I/m: sticks iff |u_T-| <= mu (1 + e) |u_N-| (here 0.5 * 1.5 * 1 = 0.75)."""
    problem = fr.attach_reference(ball_on_floor(-1.0, u_tangential, mu=0.5, restitution=0.5,
                                                mass=2.0))
    reference = problem.reference
    assert reference.verified and reference.unique and reference.method == "enumeration"
    assert sticks(problem) == (abs(u_tangential) <= 0.75)
    normal, tangential = problem.split(reference.impulses)
    assert normal[0] == pytest.approx(2.0 * 1.5 * 1.0)  # m (1 + e) |u_N-|
    expected = -2.0 * u_tangential if sticks(problem) else -0.5 * normal[0] * np.sign(u_tangential)
    assert tangential[0] == pytest.approx(expected)


@pytest.mark.parametrize("u_tangential", [0.5, 1.1, 1.3, -2.0])
def test_a_rigid_disc_sticks_iff_the_slip_is_within_3_mu_1_plus_e(u_tangential: float) -> None:
    """W_TT = 3/m: sticks iff |u_T-| <= 3 mu (1 + e) |u_N-| (3 * 0.3 * (1 + 0.333..) = 1.2)."""
    problem = fr.attach_reference(disc_on_floor(-1.0, u_tangential, mu=0.3, restitution=1 / 3))
    assert problem.W.toarray()[1, 1] == pytest.approx(3 / 2.0)
    assert problem.reference.verified
    assert sticks(problem) == (abs(u_tangential) <= 1.2)


def two_solutions() -> FrictionalProblem:
    """One contact with a strong normal-tangent coupling and large mu (a Painleve-like case):
    W = [[1, 0.9], [0.9, 1]], q = (0.8, 2), mu = 2. Separating (r = 0) is a solution; so is
    sliding, l_N = 0.8 / (1.8 - 1) = 1, l_T = -2, u_T = 0.9 >= 0; and sticking,
    r = -W^-1 q. H is a square root of W, v- = H^-T q."""
    W = np.array([[1.0, 0.9], [0.9, 1.0]])
    H = np.linalg.cholesky(W).T
    q = np.array([0.8, 2.0])
    return FrictionalProblem.build("two", G=H[:, [0]], T=H[:, [1]], m_inv=[1.0, 1.0],
                                   v_minus=np.linalg.solve(H.T, q), mu=2.0)


def test_a_problem_with_several_solutions_is_not_unique() -> None:
    problem = two_solutions()
    enumeration = fr.enumerate_solutions(problem)
    found = {tuple(np.round(r, 9)) for r in enumeration.solutions}
    assert (0.0, 0.0) in found and (1.0, -2.0) in found
    assert len(fr.distinct_velocities(problem, enumeration.solutions)) == 3
    reference = fr.attach_reference(problem).reference
    assert reference.unique is False and not reference.verified
    assert reference.residual <= 1e-12
    assert problem.metadata["reference_solutions"] == 3


def jammed_wedge(restitution: float) -> FrictionalProblem:
    """A ball falling into a V whose face normals are 0.3 rad above horizontal, below the
    friction angle atan(0.8) = 0.67: the two friction cones hold each other."""
    phi = 0.3
    normals = np.array([[np.cos(phi), np.sin(phi)], [-np.cos(phi), np.sin(phi)]])
    tangents = np.column_stack([-normals[:, 1], normals[:, 0]])
    return FrictionalProblem.build("wedge", G=normals.T, T=tangents.T, m_inv=[1.0, 1.0],
                                   v_minus=[0.05, -1.0], mu=0.8, restitution=restitution)


def test_a_jammed_wedge_with_restitution_has_no_solution() -> None:
    problem = fr.attach_reference(jammed_wedge(0.5))
    reference = problem.reference
    assert reference.solvable is False and not reference.verified
    assert problem.metadata["ccp_unbounded"] and problem.metadata["reference_no_solution_proven"]
    value, direction = fr.ccp_certificate(problem)
    assert value < 0
    normal, tangential = problem.split(direction)
    assert np.all(np.abs(tangential) <= problem.mu * normal + 1e-12)  # d in K_mu
    assert np.linalg.norm(problem.H @ direction) < 1e-8  # H d = 0
    assert problem.q @ direction < 0


def test_the_same_wedge_without_restitution_is_solvable() -> None:
    """e = 0: q = H^T v-, so q^T d = 0 for every d with H d = 0 and the ball just stops."""
    problem = fr.attach_reference(jammed_wedge(0.0))
    assert problem.reference.verified
    assert not problem.metadata["ccp_unbounded"]
    assert problem.reference.v_plus == pytest.approx([0.0, 0.0], abs=1e-12)


def random_problem(seed: int, contacts: int, dofs: int, restitution: float) -> FrictionalProblem:
    rng = np.random.default_rng(seed)
    return FrictionalProblem.build(
        f"random-{seed}", rng.standard_normal((dofs, contacts)),
        rng.standard_normal((dofs, contacts)), m_inv=rng.uniform(0.5, 2.0, dofs),
        v_minus=rng.standard_normal(dofs), mu=rng.uniform(0.1, 1.0, contacts),
        restitution=restitution)


@pytest.mark.parametrize("seed", range(12))
def test_lemke_finds_one_of_the_enumerated_solutions(seed: int) -> None:
    """W singular for dofs < 2n; e = 0 half the time (then Lemke always ends at a solution)."""
    contacts = 2 + seed % 3
    problem = random_problem(seed, contacts, dofs=[contacts, 2 * contacts, 3][seed % 3],
                             restitution=0.0 if seed % 2 else 0.4)
    enumeration = fr.enumerate_solutions(problem)
    found = fr.lemke_solution(problem)
    if seed % 2:
        assert found is not None
    if found is not None:
        assert fm.residual(problem, found) <= 1e-12
        assert any(fr.same_velocity(problem, problem.v_plus(found), problem.v_plus(r))
                   for r in enumeration.solutions)
    for r in enumeration.solutions:
        assert fm.residual(problem, r) <= 1e-12


def test_lemke_solves_a_small_lcp_by_hand() -> None:
    """w = A z + c with A = [[2, 1], [1, 2]], c = (-1, -1): z = (1/3, 1/3), w = 0."""
    z = fr.lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-1.0, -1.0]))
    assert z == pytest.approx([1 / 3, 1 / 3])


def test_independent_contacts_are_solved_one_component_at_a_time() -> None:
    """Two balls on the floor, far apart: two components, each enumerated alone."""
    G = np.zeros((4, 2))
    T = np.zeros((4, 2))
    G[1, 0], T[0, 0], G[3, 1], T[2, 1] = 1.0, -1.0, 1.0, -1.0
    problem = FrictionalProblem.build("two balls", G, T, m_inv=np.ones(4),
                                      v_minus=[0.2, -1.0, 2.0, -1.0], mu=0.5)
    assert [list(c) for c in fr.components(problem)] == [[0], [1]]
    reference = fr.attach_reference(problem).reference
    assert reference.verified and "per component (2)" in reference.method
    assert reference.v_plus == pytest.approx([0.0, 0.0, 1.5, 0.0])
