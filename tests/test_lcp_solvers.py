"""The LCP solvers written here (pi, pi-v2, pi-robust, pgs, lemke, penalty, apgd), judged by
qpbench's own metrics on the hard families and on known answers (pi-robust's kernel function
by function: test_pi_robust_kernel.py)."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import pytest
import scipy.sparse as sp
from bench_problems import CYCLING_DUMP

from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


@pytest.fixture
def pi_robust_row(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[str, object], None]]:
    """``set(key, value)``: changes one entry of pi-robust's accuracy-table row for this test
    (pi-robust reads its row once per level, so that reading is redone on both ends)."""
    from qpbench.solvers import accuracy
    from qpbench.solvers.pi_robust import settings_for

    def set_entry(key: str, value: object) -> None:
        monkeypatch.setitem(accuracy.OPTIONS["pi-robust"], key, value)
        settings_for.cache_clear()

    yield set_entry
    settings_for.cache_clear()

HARD_CASES = [("k3", 3), ("k4", 4), ("k4-middle", 5), ("grid", 3), ("grid", 5), ("grid", 7),
              ("grid", 10), ("cradle", 50), ("mass-ratio", 5), ("near-duplicate", 4)]


def hard_problem(family: str, size: int, seed: int) -> ImpactProblem:
    return attach_reference(generate(family, size, seed=seed)[0])


def cradle_of_three() -> ImpactProblem:
    """Three touching unit balls in a row, the first moving at v = 1: G has two columns."""
    G = np.array([[-1.0, 0.0], [0.0, 0.0], [1.0, -1.0], [0.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    return ImpactProblem.build("cradle-3", G, np.ones(6), [1.0, 0, 0, 0, 0, 0], 1.0)


def k3_collinear() -> ImpactProblem:
    """Balls at x = -1/2, 0, 1/2 (radius 1) with v- = (1, 0, -1): contacts (0,1), (0,2), (1,2);
    Q = [[2,1,-1],[1,2,1],[-1,1,2]] is singular and every solution gives v+ = (-1, 0, 1)."""
    G = np.zeros((6, 3))
    for column, (a, b) in enumerate(((0, 1), (0, 2), (1, 2))):
        G[2 * a, column], G[2 * b, column] = -1.0, 1.0  # n_ab = (x_a - x_b)/|.| = (-1, 0)
    return ImpactProblem.build("k3", G, np.ones(6), [1.0, 0, 0, 0, -1.0, 0], 1.0)


def separate_pairs(count: int) -> ImpactProblem:
    """``count`` pairs of unit balls, each pair closing head-on and touching no other ball:
    no two contacts share a ball, so Q is diagonal."""
    G = np.zeros((4 * count, count))
    v_minus = np.zeros(4 * count)
    for pair in range(count):
        left, right = 2 * pair, 2 * pair + 1
        G[2 * left, pair], G[2 * right, pair] = -1.0, 1.0
        v_minus[2 * left], v_minus[2 * right] = 1.0 + pair, -1.0
    return ImpactProblem.build("separate-pairs", G, np.ones(4 * count), v_minus, 1.0)


@pytest.mark.parametrize(("family", "size"), HARD_CASES)
@pytest.mark.parametrize(("solver", "eps"), [("pi-robust", 1e-8), ("lemke", 1e-8),
                                             ("pgs", 1e-6)])
def test_converges_on_the_hard_families(solver: str, eps: float, family: str, size: int) -> None:
    for seed in (0, 1):
        problem = hard_problem(family, size, seed)
        row, _ = solve_and_judge(get(solver), problem, eps)
        assert row["success"], f"{solver} on {problem.name}: {row['solver_status']}"
        assert row["claimed_success"]
        assert row["residual"] <= eps
        assert problem.reference is not None and problem.reference.verified
        assert row["v_error"] <= (1e-7 if eps <= 1e-8 else 1e-3)


@pytest.mark.parametrize("solver", ["pi-robust", "lemke", "pgs", "pi", "pi-v2", "penalty",
                                    "apgd"])
def test_known_answers(solver: str) -> None:
    cradle = cradle_of_three()
    row, output = solve_and_judge(get(solver), cradle, 1e-8)
    assert row["success"], row["solver_status"]
    np.testing.assert_allclose(cradle.v_plus(output.impulses)[0::2], [-1 / 3, 2 / 3, 2 / 3],
                               atol=1e-6)
    k3 = k3_collinear()
    row, output = solve_and_judge(get(solver), k3, 1e-8)
    if row["success"]:  # pi and penalty may fail on the singular Q, but never claim falsely
        np.testing.assert_allclose(k3.v_plus(output.impulses)[0::2], [-1.0, 0.0, 1.0], atol=1e-6)
    assert row["claimed_success"] == row["success"]


@pytest.mark.parametrize(("solver", "eps"), [("pi", 1e-8), ("pi-v2", 1e-8), ("penalty", 1e-8),
                                             ("lemke", 1e-8), ("pi-robust", 1e-8),
                                             ("apgd", 1e-6), ("pgs", 1e-6)])
def test_claims_success_only_when_qpbench_agrees(solver: str, eps: float) -> None:
    """A claimed success must pass qpbench's residual test: no wrong answer sold as right."""
    problems = [generate("grid", 10, seed=1)[0], generate("mass-ratio", 5, seed=0)[0],
                generate("near-duplicate", 4, seed=2)[0]]
    failures = 0
    for problem in problems:
        row, output = solve_and_judge(get(solver), problem, eps)
        assert output.claimed_success == row["success"], (problem.name, row["solver_status"])
        failures += not row["success"]
    if solver == "pi":
        assert failures >= 1, "plain policy iteration is known to fail on 10 x 10 grids"


def test_pi_reports_a_cycle_or_max_iters_on_a_hard_grid() -> None:
    problem = generate("grid", 10, seed=1)[0]
    row, output = solve_and_judge(get("pi"), problem, 1e-8)
    assert not output.claimed_success
    assert output.status.startswith(("cycled", "max_iters", "diverged"))
    assert metrics.residual(problem, output.impulses) > 1e-8


def test_warm_start_from_the_solution_takes_no_linear_solve() -> None:
    problem = generate("grid", 7, seed=2)[0]
    _, first = solve_and_judge(get("pi-robust"), problem, 1e-8)
    row, again = solve_and_judge(get("pi-robust"), problem, 1e-8, warm_start=first.impulses)
    assert row["success"] and again.iterations == 0


def test_pi_robust_stops_after_its_start_sweeps_when_they_solve_the_problem() -> None:
    """Contacts that share no ball: the Gauss-Seidel start sweeps solve the diagonal LCP, and
    pi-robust answers without a factorization."""
    row, output = solve_and_judge(get("pi-robust"), separate_pairs(5), 1e-8)
    assert row["success"] and output.claimed_success
    assert output.info["path"] == "start sweeps" and output.info["factorizations"] == 0
    assert output.iterations == 0


def test_lemke_declines_above_its_size_limit_and_says_so() -> None:
    from qpbench.solvers import accuracy

    limit = accuracy.OPTIONS["lemke"]["max_contacts"]
    problem = generate("box", 2 * limit, seed=0)[0]
    assert problem.n_contacts > limit
    row, output = solve_and_judge(get("lemke"), problem, 1e-8)
    assert not output.claimed_success and output.status.startswith("declined")
    assert row["status"] == "failed"


@pytest.mark.parametrize(("family", "size"), [("grid", 20), ("box", 1000), ("mass-ratio", 10)])
def test_pi_robust_on_larger_problems(family: str, size: int) -> None:
    """20 x 20 grids need the interior-point path; boxes of 1,000 balls the sparse one."""
    problem = generate(family, size, seed=3)[0]
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success, row["solver_status"]
    assert row["residual"] <= 1e-8


def test_pi_robust_claims_exactly_what_qpbench_measures_on_extreme_mass_ratios() -> None:
    """At 1e-8 with masses over 1e-6..1e6 the residual sits at double precision's floor; the
    solver's claim must still be qpbench's verdict, both ways."""
    for seed in range(100, 106):
        problem = generate("mass-ratio", 10, seed=seed)[0]
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
        assert output.claimed_success == row["success"], (problem.name, output.status)


@pytest.mark.parametrize(("family", "size"), HARD_CASES)
def test_pi_robust_compiled_path_matches_qpbench_and_the_python_path(
        family: str, size: int, pi_robust_row: Callable[[str, object], None]) -> None:
    """The compiled dense path answers (info "compiled": True) with qpbench's verdict; the
    Python path, run with the compiled path switched off, reaches the same v+."""
    problem = hard_problem(family, size, seed=1)
    row, compiled = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and compiled.claimed_success
    assert compiled.info["compiled"] is True, compiled.info
    pi_robust_row("compiled_limit", 0)
    python_row, python = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert python_row["success"] and "compiled" not in python.info
    assert problem.m_norm(problem.v_plus(compiled.impulses) - problem.v_plus(python.impulses)) \
        <= 1e-7 * max(problem.m_norm(problem.v_minus), 1e-300)


def test_compiled_residual_is_qpbench_residual_bit_for_bit() -> None:
    """The kernel sums Q l column by column like scipy's CSC product (skipping the columns of
    zero impulses, whose terms are zeros), so its residual is qpbench's exactly, even on masses
    over 1e-6 .. 1e6; the rounding bound covers any order, and the loose bound that is tried
    first is never below it."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.pi_robust_call import csc_arrays
    from qpbench.solvers.pi_robust_kernel.residual import (
        _loose_rounding_bound,
        natural_residual,
        residual_rounding_bound,
    )

    rng = np.random.default_rng(7)
    for problem in [generate("mass-ratio", 10, seed=3)[0], generate("grid", 7, seed=0)[0],
                    k3_collinear()]:
        lcp = Lcp.of(problem, dense_limit=300)
        csc = csc_arrays(problem.Q)
        for _ in range(5):
            impulses = rng.uniform(0.0, 1.0, problem.n_contacts) * lcp.scale / lcp.safe_diag
            impulses[rng.uniform(size=problem.n_contacts) < 0.4] = 0.0  # as on separating contacts
            ours = natural_residual(csc, lcp.b, lcp.diag, lcp.scale, impulses)
            assert ours == metrics.residual(problem, impulses)
            dense_order = lcp.residual_of(impulses, lcp.op @ impulses + lcp.b)
            bound = residual_rounding_bound(csc, lcp.b, lcp.scale, impulses)
            assert bound > 0.0 and abs(dense_order - ours) <= bound
            assert _loose_rounding_bound(csc, lcp.b, lcp.scale, impulses) >= bound


def test_pi_robust_falls_back_to_the_python_path_when_the_kernel_cannot_factor() -> None:
    """A block that Cholesky refuses (here: a kernel made to raise) sends the solve to the
    Python path, which still converges and says so."""
    from qpbench.solvers.pi_robust_kernel import call, entry

    problem = hard_problem("grid", 5, seed=0)
    entry.warm_up()  # its own call of the kernel comes before the patch
    kernel = call.call_pi_robust_into

    def refusing(*args: object, **kwargs: object) -> None:
        raise np.linalg.LinAlgError("Matrix is not positive definite")

    call.call_pi_robust_into = refusing
    try:
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    finally:
        call.call_pi_robust_into = kernel
    assert row["success"] and output.claimed_success
    assert output.info["compiled"] == "declined or not confirmed; Python path"


def test_pi_robust_returns_a_certified_answer_as_confirmed_would() -> None:
    """solve() returns the kernel's certified answer itself, without calling _confirmed: the
    output is the one _confirmed gives that answer (same l, status, count and info)."""
    from qpbench.solvers import pi_robust

    settings = pi_robust.settings_for(1e-8)
    for problem in [hard_problem("grid", 5, seed=0), generate("grid", 7, seed=0)[0]]:
        impulses, scalars = pi_robust.kernel_into(problem, settings, None)
        answer = (impulses, *scalars)
        assert answer[6], "the kernel certified its answer"
        confirmed = pi_robust._confirmed(problem, settings, answer[0], answer)
        returned = pi_robust.solve(problem, 1e-8)
        assert np.array_equal(returned.impulses, confirmed.impulses)
        assert (returned.status, returned.claimed_success, returned.iterations) == \
            (confirmed.status, confirmed.claimed_success, confirmed.iterations)
        assert returned.info == confirmed.info


def test_pi_robust_ends_on_lemkes_ray_without_the_python_path_when_there_is_no_solution(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A jammed wedge's relaxed LCP has no solution: the kernel's policy iteration and
    interior point fail in full, Lemke's method then ends on a ray, and the Python path (the
    same methods again) is skipped. The failure is claimed as such."""
    from qpbench.problem.friction_generate import generate as generate_frictional
    from qpbench.solvers import pi_robust

    problem = generate_frictional("wedge", 1)[0].relaxed()

    def python_path(*args: object, **kwargs: object) -> None:
        raise AssertionError("the Python path ran after Lemke's method had ended on a ray")

    monkeypatch.setattr(pi_robust, "pi_robust", python_path)
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert output.info["compiled"] is True and output.info["interior_iterations"] > 0
    assert output.info["path"] == "lemke fallback: ray termination"
    assert not output.claimed_success and not row["success"] and row["status_honest"]


def test_a_ray_certificate_is_a_non_negative_null_direction_of_q_with_b_t_y_below_zero() -> None:
    """Q and b of one body between two walls, both contacts asking it to leave at speed 1: no
    l >= 0 has Q l + b >= 0, and y = (1, 1) proves it (Q y = 0, b^T y = -2)."""
    from qpbench.solvers.lemke import no_solution_certified

    Q = np.array([[1.0, -1.0], [-1.0, 1.0]])
    b = np.array([-1.0, -1.0])
    assert no_solution_certified(Q, b, np.array([1.0, 1.0]))
    assert not no_solution_certified(Q, b, np.array([1.0, 0.0]))  # Q y != 0
    assert not no_solution_certified(Q, -b, np.array([1.0, 1.0]))  # b^T y > 0: solvable
    assert not no_solution_certified(Q, b, np.array([-1.0, -1.0]))  # y < 0
    assert not no_solution_certified(Q, b, np.zeros(2))


def test_lemke_ends_on_a_certified_ray_where_no_impulse_is_feasible() -> None:
    """One body between two walls, both contacts asking it to leave at speed 1 (n_rel = -1):
    impossible, and Lemke's ray proves it."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lemke import RAY_TERMINATION, lemke

    problem = ImpactProblem(name="opposed", G=sp.csc_matrix(np.array([[1.0, -1.0]])),
                            m_inv=np.array([1.0]), v_minus=np.array([0.0]),
                            restitution=np.zeros(2), n_rel=np.array([-1.0, -1.0]),
                            dofs_per_body=1)
    _, converged, status, _ = lemke(Lcp.of(problem), 1e-8, max_pivots=100)
    assert not converged and status == RAY_TERMINATION


def test_pi_robust_runs_the_python_path_after_a_ray_without_a_certificate(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The relaxed jammed wedge again, with the ray's certificate refused (as rounding in the
    pivots could refuse it): the ray proves nothing then, so the Python path runs after Lemke's
    method, and the answer still claims no success."""
    from qpbench.problem.friction_generate import generate as generate_frictional
    from qpbench.solvers import lemke

    monkeypatch.setattr(lemke, "no_solution_certified", lambda *args: False)
    problem = generate_frictional("wedge", 1)[0].relaxed()
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert output.info["compiled"] == "failed in full; Lemke's method, then the Python path"
    assert output.info["path"] == f"lemke fallback: {lemke.UNCERTIFIED_RAY}"
    assert not output.claimed_success and not row["success"] and row["status_honest"]


def test_pi_robust_runs_the_python_path_after_the_kernel_when_lemke_cannot_decide(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """When the kernel fails in full and Lemke's method ends above tolerance, the Python path
    runs, with Lemke's answer standing in for its own last step (Lemke runs once), and its
    answer is judged like any other. Both failures are forced here, so the test holds whatever
    arithmetic the CPU's kernel does."""
    from qpbench.solvers import lemke
    from qpbench.solvers.pi_robust_kernel import call
    from qpbench.solvers.pi_robust_kernel import entry as kernel

    def failed_in_full(*args: np.ndarray) -> tuple:
        args[4][:] = 0.0  # l, written into the caller's array
        return False, kernel.PATH_NONE, 0, 0, 0, False

    calls = []
    original = lemke.lemke

    def above_tolerance(*args: object, **kwargs: object) -> tuple:
        calls.append(args)
        impulses, _, _, pivots = original(*args, **kwargs)
        return impulses, False, "pivoting ended above tolerance", pivots

    monkeypatch.setattr(call, "call_pi_robust_into", failed_in_full)
    monkeypatch.setattr(lemke, "lemke", above_tolerance)
    problem = generate("grid", 4, seed=3)[0]
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert output.info["compiled"] == "failed in full; Lemke's method, then the Python path"
    assert len(calls) == 1
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8


@pytest.mark.parametrize("seed", [101, 102, 103])
def test_pi_robust_is_honest_on_masses_over_twelve_decades(seed: int) -> None:
    """Masses over 1e-6 .. 1e6: whichever of its paths answers (the CPU's rounding decides
    which), pi-robust claims success exactly when qpbench's residual meets the level."""
    problem = generate("mass-ratio", 10, seed=seed)[0]
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert np.all(np.isfinite(output.impulses))
    assert output.claimed_success == row["success"] and row["status_honest"]


def test_pi_robust_compiled_path_declines_a_too_wide_envelope(
        pi_robust_row: Callable[[str, object], None]) -> None:
    """With no envelope work allowed the kernel declines before any solve, and the sparse
    Python path answers (here a 1,000-ball box packing)."""
    problem = generate("box", 1000, seed=4)[0]
    pi_robust_row("compiled_work_limit", 0.0)
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success
    assert output.info["compiled"] == "declined or not confirmed; Python path"


def test_pi_robust_start_sweeps_run_before_the_envelope_is_measured(
        pi_robust_row: Callable[[str, object], None]) -> None:
    """The start sweeps come first, in the posed order: a problem they solve is answered by
    the compiled path even when no envelope work is allowed, with no ordering and no factor
    (here 100 contacts, above the ordering threshold of 64)."""
    pi_robust_row("compiled_work_limit", 0.0)
    row, output = solve_and_judge(get("pi-robust"), separate_pairs(100), 1e-8)
    assert row["success"] and output.claimed_success
    assert output.info["compiled"] is True and output.info["path"] == "start sweeps"
    assert output.info["factorizations"] == 0 and output.iterations == 0



def test_pi_robusts_row_does_not_depend_on_the_problems_scale() -> None:
    """pi-robust reads its row once per level (``settings_for``), which is right only while
    no entry of the row depends on the problem's scale."""
    from qpbench.solvers import accuracy

    for eps in (1e-2, 1e-8):
        assert accuracy.options_for("pi-robust", eps, 1.0) \
            == accuracy.options_for("pi-robust", eps, 1e6)


@pytest.mark.parametrize("compiled", [True, False])
def test_pi_robust_solves_a_dump_whose_prox_step_cycles_with_or_without_its_active_set_method(
        compiled: bool, pi_robust_row: Callable[[str, object], None]) -> None:
    """On this fork dump block pivoting cycles on the first prox step (``Q + 1e-5 D`` is nearly
    singular); with the primal active-set method to end that step, and without it (the
    interior point then takes over), pi-robust's answer passes qpbench's residual and its claim
    is honest, compiled or not. Which of its methods ends the solve depends on rounding, so it
    is not asserted."""
    problem = attach_reference(import_dump(CYCLING_DUMP))
    if not compiled:
        pi_robust_row("compiled_limit", 0)
    for active_set in (True, False):
        pi_robust_row("active_set", active_set)
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
        assert row["success"] and output.claimed_success and row["residual"] <= 1e-8, output.info
        assert row["status_honest"] and row["v_error"] <= 1e-6, row



@pytest.mark.parametrize("compiled", [True, False])
def test_pi_robust_follows_a_drifting_prox_step_instead_of_waiting_for_it(
        compiled: bool, pi_robust_row: Callable[[str, object], None]) -> None:
    """On this 7x7 grid (103 contacts, 98 degrees of freedom) prox steps on a wrong policy
    drift along Q_FF's null space; following the drift (``drift_steps``) ends policy iteration
    in fewer linear solves than waiting for rho to fall, compiled or not, and both answers
    pass qpbench's residual with an honest claim. The count is kept because following the drift
    saves several prox steps here, not one: a rounding difference that moves one stopping test
    by a step cannot reverse the comparison."""
    problem = hard_problem("grid", 7, seed=4)
    if not compiled:
        pi_robust_row("compiled_limit", 0)
    solves = {}
    for drift_steps in (0, 3):
        pi_robust_row("drift_steps", drift_steps)
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
        assert row["success"] and output.claimed_success and row["residual"] <= 1e-8, output.info
        solves[drift_steps] = row["iterations"]
    assert solves[3] < solves[0], solves



def box_pile_impact(bodies: int) -> ImpactProblem:
    """The first impact of ``qpbench scaling``'s dense pile of ``bodies`` unit boxes: about
    7.6 contacts per box against 3 degrees of freedom, Q singular."""
    from qpbench.inner_solvers import choose_by_name
    from qpbench.simulation.scaling import box_pile
    from qpbench.simulation.stepper import Simulator

    simulator = Simulator(box_pile(bodies), choose_by_name("pi-robust"))
    found = simulator.find_contacts(simulator.positions, simulator.positions)
    return simulator.impact_problem(found, simulator.dof_velocity())


def test_the_newton_matrix_over_the_degrees_of_freedom_solves_the_same_system() -> None:
    """(Q~ + diag(d)) x = r solved through L = M^-1/2 G (Woodbury): backward stable (the
    residual is rounding's, relative to |Q~ + diag(d)| |x|) for d from 1e-2..1e2 to
    1e-12..1e4 (the range an interior point's w / l sweeps), and on moderate d the same x as
    the solve over the contacts."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lcp_interior import FactoredNormalMatrix, NormalMatrix, jacobi_scaled

    problem = box_pile_impact(50)
    lcp = Lcp.of(problem)
    scaled, root = jacobi_scaled(lcp)
    factored = FactoredNormalMatrix.when_smaller(scaled, root, problem.L)
    assert factored is not None and factored.A.shape[0] == 150 < problem.n_contacts
    over_contacts = NormalMatrix(scaled, root)
    rng = np.random.default_rng(0)
    q_norm = float(np.max(np.abs(scaled.op).sum(axis=1)))
    for smallest, largest in [(-2, 2), (-8, 4), (-12, 4)]:
        diagonal = 10.0 ** rng.uniform(smallest, largest, problem.n_contacts)
        rhs = rng.normal(size=problem.n_contacts)
        factored.factorize(diagonal)
        over_contacts.factorize(diagonal)
        x = factored.solve(rhs)
        residual = scaled.op @ x + diagonal * x - rhs
        size = (q_norm + 10.0 ** largest) * np.max(np.abs(x)) + np.max(np.abs(rhs))
        assert np.max(np.abs(residual)) <= 1e-14 * size
        if smallest == -2:
            assert np.max(np.abs(x - over_contacts.solve(rhs))) <= 1e-10 * np.max(np.abs(x))


@pytest.mark.parametrize("correctors", [0, 1, 3])
def test_centrality_correctors_keep_the_newton_equations_and_only_lengthen_the_step(
        monkeypatch: pytest.MonkeyPatch, correctors: int) -> None:
    """Gondzio's correctors change Mehrotra's direction on a box pile only by solutions of
    the iteration's own Newton matrix: ``dw - (Q~ + prox I) dl`` stays what it was (the step
    still cuts the infeasibility by 1 - alpha), and a corrected direction is kept only when
    its step to the boundary is longer; with none, nothing changes."""
    from qpbench.problem.metrics import dot
    from qpbench.solvers import lcp_interior
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lcp_interior import _centrality_corrected, _longest_step
    from qpbench.solvers.pi_robust import _normal_matrix

    monkeypatch.setattr(lcp_interior, "CENTRALITY_CORRECTORS", correctors)
    lcp = Lcp.of(box_pile_impact(50))
    normal = _normal_matrix(lcp)
    scaled, prox = normal.lcp, 1e-10
    rng = np.random.default_rng(0)
    impulses, slack = 10.0 ** rng.uniform(-1, 0, (2, scaled.n))
    infeasibility = scaled.op @ impulses + prox * impulses + scaled.b - slack
    normal.factorize(slack / impulses + prox)
    dl = normal.solve(-slack - infeasibility)
    dw = scaled.op @ dl + prox * dl + infeasibility
    mu = dot(impulses, slack) / scaled.n
    affine = _longest_step(impulses, slack, dl, dw)
    target = (dot(impulses + affine * dl, slack + affine * dw) / scaled.n) ** 3 / mu ** 2
    dl = normal.solve(target / impulses - slack - infeasibility - dl * dw / impulses)
    dw = scaled.op @ dl + prox * dl + infeasibility
    step = _longest_step(impulses, slack, dl, dw)

    new_dl, new_dw, new_step = _centrality_corrected(
        impulses, slack, dl, dw, target, normal, lambda c: scaled.op @ c + prox * c)

    kept = new_dw - scaled.op @ new_dl - prox * new_dl
    assert np.max(np.abs(kept - infeasibility)) <= 1e-9 * np.max(np.abs(infeasibility))
    assert new_step == _longest_step(impulses, slack, new_dl, new_dw)
    if correctors == 0:
        assert new_step == step and np.array_equal(new_dl, dl)
    else:  # Mehrotra's step here is about half the way; the first corrector adds 0.1 or more
        assert new_step >= step + 0.1


def test_a_policy_block_over_the_degrees_of_freedom_is_refined_to_rounding() -> None:
    """A policy block ``Q_FF + rho D_F`` of a box pile solved through L's columns (Woodbury,
    149 degrees of freedom against 197 contacts): the subtraction loses digits as rho falls,
    and one step of iterative refinement wins them back (backward error, relative to
    |H| |x|, at rounding's level)."""
    from qpbench.solvers.lcp_interior import WoodburyFactor, moving_rows

    problem = box_pile_impact(50)
    Q = problem.Q.toarray()
    rng = np.random.default_rng(0)
    free = np.flatnonzero(rng.random(problem.n_contacts) < 0.6)
    rows = moving_rows(problem.L[:, free])
    assert rows.shape[0] == 149 < free.size == 197

    def backward_error(rho: float, refinements: int) -> float:
        shift = rho * np.diag(Q)[free]
        block = Q[np.ix_(free, free)] + np.diag(shift)
        rhs = np.random.default_rng(1).normal(size=free.size)
        x = WoodburyFactor(rows, shift, refinements).solve(rhs)
        size = np.max(np.abs(block).sum(axis=1)) * np.max(np.abs(x)) + np.max(np.abs(rhs))
        return float(np.max(np.abs(block @ x - rhs)) / size)

    for rho in (1e-5, 1e-8, 1e-11):
        assert backward_error(rho, 1) <= 1e-15
    assert backward_error(1e-11, 0) > 100.0 * backward_error(1e-11, 1)


def test_pi_robust_factors_sparse_policy_blocks_over_the_degrees_of_freedom(
        pi_robust_row: Callable[[str, object], None]) -> None:
    """On a pile of 200 boxes (1,504 contacts, 600 degrees of freedom), from a warm start
    (policy iteration first, on the Python path), the policy blocks are factored through L
    when fewer degrees of freedom than contacts move, and the answer is judged solved."""
    problem = box_pile_impact(200)
    pi_robust_row("compiled_limit", 0)
    cold, cold_output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert cold["success"]
    warm = 1.05 * cold_output.impulses
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8, warm_start=warm)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert 0 < output.info["factorizations_over_dofs"] <= output.info["factorizations"]


def test_pi_robust_puts_the_interior_point_first_on_sparse_problems(
        pi_robust_row: Callable[[str, object], None], pi_robust_methods: list[str]) -> None:
    """Above ``dense_limit`` contacts the Python path runs the interior point first, its
    Newton matrix over the 600 degrees of freedom of 200 boxes instead of the 1,504 contacts,
    and ends on qpbench's verdict. From a warm start, policy iteration goes first. The order is
    the rule's (the problem's size and the start decide it), so it is asserted; whether the
    first method alone ends the solve depends on rounding, so that is not."""
    problem = box_pile_impact(200)
    pi_robust_row("compiled_limit", 0)
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert pi_robust_methods[0] == "interior point", pi_robust_methods
    assert output.info["interior_newton_matrix"] == "degrees of freedom"
    warm = 1.01 * output.impulses
    pi_robust_methods.clear()
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8, warm_start=warm)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert pi_robust_methods[0] == "policy iteration", pi_robust_methods


def test_a_stalled_interior_point_hands_on_its_best_iterate_and_ends() -> None:
    """On a pile of 400 boxes complementarity outruns feasibility and the steps shrink to
    nothing near a residual of 1e-4; with ``end_on_stall`` the interior point hands its best
    iterate to the finish once five iterations have not cut the residual by 10%, and ends."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lcp_interior import interior_point
    from qpbench.solvers.pi_robust import _normal_matrix

    problem = box_pile_impact(400)
    lcp = Lcp.of(problem)
    normal = _normal_matrix(lcp)
    handed: list[float] = []

    def no_finish(impulses: np.ndarray, w: np.ndarray) -> None:
        handed.append(lcp.residual(impulses))

    impulses, converged, iterations, _ = interior_point(
        lcp, normal.lcp, normal.root, normal, 1e-8, 80, no_finish, 1e-3, end_on_stall=True)
    assert not converged and iterations < 80
    assert len(handed) == 2  # below finish_below, then the best iterate on the stall
    assert handed[-1] == lcp.residual(impulses) > 1e-8


def test_the_proximal_interior_point_comes_down_to_1e_8_where_the_plain_one_stalls() -> None:
    """The same 400-box pile has no strictly feasible point (no velocity separates every
    contact); the proximal LCP ``(Q~ + 1e-10 I) l~ + b~`` has one, and its iterates come down
    to about qpbench's 1e-8 on the pile's own LCP with no finishing policy iteration, where
    the plain ones stall above 1e-6. Its floor, ``1e-10 max(l~)``, is near 1e-8 here, so on
    which side of 1e-8 they end follows the rounding: ended short of it, the interior point
    hands its best iterate on, once."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lcp_interior import interior_point
    from qpbench.solvers.pi_robust import INTERIOR_PROX, _normal_matrix

    lcp = Lcp.of(box_pile_impact(400))

    def run(prox: float) -> tuple[tuple, list[float]]:
        normal = _normal_matrix(lcp)
        handed: list[float] = []
        answer = interior_point(
            lcp, normal.lcp, normal.root, normal, 1e-8, 80,
            lambda impulses, w: handed.append(lcp.residual(impulses)), 0.0,
            end_on_stall=True, prox=prox)
        return answer, handed

    (impulses, converged, iterations, _), handed = run(INTERIOR_PROX)
    assert iterations < 80 and lcp.residual(impulses) <= 3e-8
    assert handed == ([] if converged else [lcp.residual(impulses)])
    (impulses, converged, _, _), handed = run(0.0)
    assert not converged and lcp.residual(impulses) > 1e-6 and len(handed) == 1


def test_the_proximal_interior_point_hands_on_at_its_floor() -> None:
    """With a large weight (1e-6) the proximal solution misses the LCP by about 1e-6 max(l~)
    (scaled); once the LCP's residual stands 100 times above the proximal LCP's the iterate is
    handed on at once, near that floor."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.lcp_interior import interior_point
    from qpbench.solvers.pi_robust import _normal_matrix

    lcp = Lcp.of(box_pile_impact(400))
    normal = _normal_matrix(lcp)
    handed: list[float] = []
    impulses, converged, _, _ = interior_point(
        lcp, normal.lcp, normal.root, normal, 1e-8, 80,
        lambda impulses, w: handed.append(lcp.residual(impulses)), 0.0, end_on_stall=True,
        prox=1e-6)
    assert not converged and len(handed) == 1
    assert 1e-6 < handed[0] == lcp.residual(impulses) < 1e-4
