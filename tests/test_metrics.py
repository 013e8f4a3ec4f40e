"""The metrics of docs/design.md section 2 on answers whose truth is known."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from other_cpu import printed_elsewhere

from qpbench.problem import friction_generate, friction_metrics, metrics
from qpbench.problem.generate import generate
from qpbench.problem.reference import attach_reference, enumeration


def x_velocities(problem, impulses) -> np.ndarray:
    return problem.v_plus(impulses).reshape(-1, 2)[:, 0]


@pytest.mark.parametrize("t", [0.0, 0.5, 1.0, 1.7, 2.0])
def test_every_point_of_the_k3_solution_segment_gives_the_same_v_plus(t: float) -> None:
    k3 = generate("k3")[0]
    impulses = np.array([t, 2.0 - t, t])
    assert metrics.residual(k3, impulses) == pytest.approx(0.0, abs=1e-15)
    assert x_velocities(k3, impulses) == pytest.approx([-1.0, 0.0, 1.0])


def test_off_the_segment_the_residual_is_positive() -> None:
    k3 = generate("k3")[0]
    assert metrics.residual(k3, np.array([1.0, 1.0, 0.5])) > 0.1
    assert metrics.infeasibility(k3, np.array([-0.5, 2.5, -0.5])) > 0.1


def test_newtons_cradle_lcp_gives_minus_a_third_and_two_thirds() -> None:
    cradle = generate("cradle", size=3)[0]
    impulses = enumeration(cradle)
    assert impulses == pytest.approx([4 / 3, 2 / 3])
    assert x_velocities(cradle, impulses) == pytest.approx([-1 / 3, 2 / 3, 2 / 3])
    assert metrics.energy_gain(cradle, impulses) < 0  # the LCP loses energy here


def test_two_equal_balls_with_c_one_swap_velocities() -> None:
    pair = generate("cradle", size=2)[0]
    impulses = enumeration(pair)
    assert x_velocities(pair, impulses) == pytest.approx([0.0, 1.0])
    assert metrics.energy_gain(pair, impulses) == pytest.approx(0.0, abs=1e-15)


def test_v_error_measures_the_m_norm_distance() -> None:
    cradle = generate("cradle", size=3)[0]
    exact = enumeration(cradle)
    v_ref = cradle.v_plus(exact)
    assert metrics.v_error(cradle, exact, v_ref) == pytest.approx(0.0, abs=1e-15)
    # ||v-||_M = 1; one unit of impulse on contact 0 moves two unit balls by 1 each
    assert metrics.v_error(cradle, exact + np.array([1.0, 0.0]), v_ref) == pytest.approx(
        np.sqrt(2.0))


def test_evaluate_judges_by_the_residual_alone() -> None:
    grid = attach_reference(generate("grid", size=3)[0])
    zero = np.zeros(grid.n_contacts)
    assert metrics.evaluate(grid, zero, 1e-8)["success"] is False
    assert metrics.evaluate(grid, None, 1e-8)["success"] is False
    assert metrics.evaluate(grid, np.full(grid.n_contacts, np.nan), 1e-8)["success"] is False
    exact = metrics.evaluate(grid, grid.reference.impulses, 1e-8)
    assert exact["success"] is True
    assert exact["v_error"] < 1e-12


@settings(max_examples=40, deadline=None)
@given(
    family=st.sampled_from(["k3", "k4", "k4-middle", "grid", "box"]),
    seed=st.integers(0, 1000),
    restitution=st.floats(0.0, 1.0),
    scale=st.floats(0.0, 3.0),
)
def test_energy_identity_holds_for_any_impulses(family, seed, restitution, scale) -> None:
    """KE+ - KE- = l^T w / (1 + c) - (1 - c) / (2 (1 + c)) l^T Q l for ANY l (nrel = 0)."""
    problem = generate(family, size=9 if family == "box" else None, seed=seed,
                       restitution=restitution)[0]
    impulses = scale * np.random.default_rng(seed).random(problem.n_contacts)
    c = restitution
    w = problem.w(impulses)
    identity = impulses @ w / (1 + c) - (1 - c) / (2 * (1 + c)) * impulses @ (
        problem.Q @ impulses)
    direct = problem.kinetic_energy(problem.v_plus(impulses)) - problem.kinetic_energy(
        problem.v_minus)
    assert direct == pytest.approx(identity, rel=1e-9, abs=1e-12)
    assert metrics.energy_identity_gap(problem, impulses) < 1e-9


@settings(max_examples=25, deadline=None)
@given(family=st.sampled_from(["k4-middle", "grid", "mass-ratio", "near-duplicate"]),
       seed=st.integers(0, 1000))
def test_ball_ball_impulses_conserve_momentum_whatever_l_is(family, seed) -> None:
    problem = generate(family, seed=seed)[0]
    impulses = np.random.default_rng(seed).random(problem.n_contacts)
    mass = 1.0 / problem.m_inv
    momentum_before = (mass * problem.v_minus).reshape(-1, 2).sum(axis=0)
    momentum_after = (mass * problem.v_plus(impulses)).reshape(-1, 2).sum(axis=0)
    assert momentum_after == pytest.approx(momentum_before, abs=1e-9 * mass.max())


def test_complementarity_of_a_problem_at_rest_is_finite_where_the_scale_squared_underflows(
        ) -> None:
    """b = 0 (nothing approaching): the scale is TINY = 1e-300, whose square is 0 in double
    precision; the metric divides by the scale twice and stays defined."""
    problem = generate("k3", seed=0)[0]
    problem.v_minus[:] = 0.0
    problem.b[:] = 0.0
    assert metrics.scale(problem) == metrics.TINY and metrics.TINY ** 2 == 0.0
    assert metrics.complementarity(problem, np.zeros(problem.n_contacts)) == 0.0
    assert metrics.complementarity(problem, np.ones(problem.n_contacts)) == np.inf


def judged_figures() -> list[str]:
    """Every metric of :func:`metrics.evaluate`, in hexadecimal, on a 30x30 grid, a packing of
    1,000 boxes and a 10x10 grid, and of the frictional ``friction_metrics.evaluate`` with
    FCLIB's merit on two frictional problems, each judged at impulses drawn from a fixed seed."""
    lines = []
    for family, size, seed in (("grid", 30, 2), ("box", 1000, 1), ("grid", 10, 1)):
        problem = generate(family, size, seed=seed)[0]
        impulses = np.random.default_rng(seed).random(problem.n_contacts)
        figures = metrics.evaluate(problem, impulses, 1e-8)
        lines.append(f"{family} {size} " + " ".join(
            f"{name}={float(value).hex()}" for name, value in sorted(figures.items())))
    for family, size in (("rough-box", 150), ("incline", 50)):
        frictional = friction_generate.generate(family, size, seed=3)[0]
        impulses = np.random.default_rng(size).random(2 * frictional.n_contacts)
        figures = friction_metrics.evaluate(frictional, impulses, 1e-8)
        figures["fclib_merit"] = friction_metrics.fclib_merit(frictional, impulses)
        lines.append(f"{family} {size} " + " ".join(
            f"{name}={float(value).hex()}" for name, value in sorted(figures.items())
            if isinstance(value, float)))
    return lines


def test_the_judged_figures_do_not_depend_on_blas_kernels_or_simd() -> None:
    """Judged on another CPU, an answer gets the same figures to the last bit: the same
    figures come out of a process whose OpenBLAS takes the kernels of an old CPU (whose dot
    sums in another order than this CPU's) and whose NumPy dispatches no vector
    instructions."""
    assert printed_elsewhere(__file__) == judged_figures()


if __name__ == "__main__":
    print("\n".join(judged_figures()))
