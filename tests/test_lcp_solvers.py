"""The LCP solvers written here (pi, pi-v2, pi-robust, pgs, lemke, penalty, apgd), judged by
qpbench's own metrics on the hard families and on known answers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge

if TYPE_CHECKING:  # (the kernel's module is imported inside each test that runs it)
    from qpbench.solvers.pi_robust_kernel.structures import Csc, OrderedLcp


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

# a dump of the research fork's 5x5 grid on which block pivoting cycles (problems/head_to_head)
CYCLING_DUMP = (Path(__file__).resolve().parents[1]
                / "problems/head_to_head/fork_5x5_grid/itr_15.xml.out")

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
    from qpbench.solvers.pi_robust import csc_arrays
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
    from qpbench.solvers.pi_robust_kernel import entry

    problem = hard_problem("grid", 5, seed=0)
    entry.warm_up()  # its own call of the kernel comes before the patch
    kernel = entry.envelope_pi_robust

    def refusing(*args: object, **kwargs: object) -> None:
        raise np.linalg.LinAlgError("Matrix is not positive definite")

    entry.envelope_pi_robust = refusing
    try:
        row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    finally:
        entry.envelope_pi_robust = kernel
    assert row["success"] and output.claimed_success
    assert output.info["compiled"] == "declined or not confirmed; Python path"


def test_pi_robust_returns_a_certified_answer_as_confirmed_would() -> None:
    """solve() returns the kernel's certified answer itself, without calling _confirmed: the
    output is the one _confirmed gives that answer (same l, status, count and info)."""
    from qpbench.solvers import pi_robust
    from qpbench.solvers.pi_robust_kernel.entry import envelope_pi_robust

    settings = pi_robust.settings_for(1e-8)
    for problem in [hard_problem("grid", 5, seed=0), generate("grid", 7, seed=0)[0]]:
        answer = pi_robust.kernel_call(envelope_pi_robust, problem, settings, None)
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
    from qpbench.solvers.pi_robust_kernel import entry as kernel

    def failed_in_full(*args: object) -> tuple:
        b = args[3]
        return np.zeros_like(b), False, kernel.PATH_NONE, 0, 0, 0, False

    calls = []
    original = lemke.lemke

    def above_tolerance(*args: object, **kwargs: object) -> tuple:
        calls.append(args)
        impulses, _, _, pivots = original(*args, **kwargs)
        return impulses, False, "pivoting ended above tolerance", pivots

    monkeypatch.setattr(kernel, "envelope_pi_robust", failed_in_full)
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


# run in a fresh process with an empty numba cache: numba loads a cached kernel whole, and
# only a compilation types (and so lists the signatures of) every function it calls
UNCOUNTED_RETURN_TYPES = """
import json
from numba.core import types
import importlib
import pkgutil
from qpbench.solvers import pi_robust_kernel
from qpbench.solvers.pi_robust_kernel import entry
entry.warm_up()
functions = {}
for module in pkgutil.iter_modules(pi_robust_kernel.__path__):
    kernel = importlib.import_module(f"{pi_robust_kernel.__name__}.{module.name}")
    functions.update(vars(kernel))
returned = {}
for name, function in functions.items():
    if getattr(function, "targetoptions", {}).get("_nrt") is False:
        returned[name] = []
        for signature in function.signatures:
            result = function.overloads[signature].signature.return_type
            parts = result.types if isinstance(result, types.BaseTuple) else (result,)
            returned[name] += [isinstance(part, types.Array) for part in parts]
print(json.dumps(returned))
"""


@pytest.mark.slow
def test_the_kernels_functions_without_reference_counts_return_no_array(tmp_path: Path) -> None:
    """A function compiled without numba's reference counting may take arrays but not return
    one: nothing would own it, and the caller would free it while it is in use. Every such
    function of the kernel, as compiled for a solve, returns scalars and flags only."""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    printed = subprocess.run([sys.executable, "-c", UNCOUNTED_RETURN_TYPES], env=environment,
                             capture_output=True, text=True, check=True).stdout
    returned = json.loads(printed)
    assert {"_block_solve", "_inner_lcp", "_prox_policy_iteration"} <= set(returned)
    for name, array_parts in returned.items():
        assert array_parts and not any(array_parts), name


def test_a_blocks_envelope_factor_from_the_upper_triangle_is_the_dense_blocks() -> None:
    """For a free set I, the rows of the factor of Q_II + rho D_I start at each row's first
    nonzero of Q_II, L L^T is Q_II + rho D_I, and the forward substitution made row by row
    with it is L's: all read from Q's upper triangle alone (a copy, or Q's own sorted columns'
    leading entries), from a first row on as well (the rows before it kept from an earlier
    factor)."""
    from qpbench.solvers.pi_robust_kernel.factor import _backward_substitution, _factor_rows
    from qpbench.solvers.pi_robust_kernel.ordering import _leading_upper, _upper

    Q = generate("grid", 10, seed=0)[0].Q
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    upper = _upper(csc)
    # Q's own arrays, rows sorted in each column, serve as the upper triangle: same entries
    ends = np.empty(Q.shape[0], dtype=np.int64)
    assert _leading_upper(csc, ends)
    for column in range(Q.shape[0]):
        copied = slice(upper[0][column], upper[1][column])
        leading = slice(Q.indptr[column], ends[column])
        assert np.array_equal(upper[2][copied], Q.indices[leading])
        assert np.array_equal(upper[3][copied], Q.data[leading])
    unsorted = (csc[0], csc[1].copy(), csc[2])
    unsorted[1][[0, 1]] = unsorted[1][[1, 0]]  # the first column's first two rows swapped
    assert not _leading_upper(unsorted, ends)
    diag, rho = Q.diagonal(), 1e-3
    rng = np.random.default_rng(3)
    for _ in range(5):
        free = np.flatnonzero(rng.uniform(size=Q.shape[0]) < 0.6)
        position = np.full(Q.shape[0], -1, dtype=np.int64)
        position[free] = np.arange(free.size)
        block = Q[free][:, free].toarray() + rho * np.diag(diag[free])
        offsets = np.zeros(free.size + 1, dtype=np.int64)
        values = np.empty(Q.nnz + free.size ** 2)
        _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, 0,
                     np.empty(0))
        for a in range(free.size):
            assert a + 1 - (offsets[a + 1] - offsets[a]) == np.flatnonzero(block[a])[0]
        lower = dense_factor(values, offsets, free.size)
        assert np.allclose(lower @ lower.T, block, rtol=1e-12, atol=1e-12 * diag.max())
        # refactored from a middle row on (the rows before it kept), with a right side
        kept = free.size // 2
        rhs = rng.normal(size=free.size)
        solution = rhs.copy()
        values[offsets[kept]:] = np.nan  # must be written before being read
        _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, kept,
                     solution)
        _backward_substitution(values, offsets, free.size, solution)
        assert np.allclose(block @ solution, rhs, rtol=1e-10, atol=1e-10)


def test_an_envelope_factor_of_random_patterns_is_numpys_cholesky() -> None:
    """Rows whose envelopes start anywhere (at the row itself, one or two columns before it,
    or far back) and of every parity of width: the envelope factor's entries, formed two at a
    time with each row's newest entries subtracted last, are those of numpy's Cholesky factor."""
    import scipy.sparse as sp

    from qpbench.solvers.pi_robust_kernel.factor import _factor_rows
    from qpbench.solvers.pi_robust_kernel.ordering import _upper

    rng = np.random.default_rng(11)
    for size, density in ((1, 1.0), (2, 1.0), (7, 0.3), (30, 0.1), (61, 0.05), (61, 0.5)):
        pattern = sp.random(size, size, density=density, random_state=rng, format="csc")
        symmetric = (pattern + pattern.T).tocsc()
        matrix = symmetric + sp.diags(abs(symmetric).sum(axis=1).A1 + 1.0)
        Q = sp.csc_matrix(matrix)
        Q.sort_indices()
        upper = _upper((Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data))
        everything = np.arange(size)
        offsets = np.zeros(size + 1, dtype=np.int64)
        values = np.full(size * size, np.nan)
        _factor_rows(upper, everything, everything, np.empty(0), 0.0, np.zeros(size), values,
                     offsets, 0, np.empty(0))
        expected = np.linalg.cholesky(Q.toarray())
        for row in range(size):
            first = row + 1 - (offsets[row + 1] - offsets[row])
            stored = values[offsets[row]:offsets[row + 1]].copy()
            stored[-1] = 1.0 / stored[-1]  # the diagonal is kept as its reciprocal
            assert np.allclose(stored, expected[row, first:row + 1], rtol=1e-12, atol=1e-12)
            assert not expected[row, :first].any()


def test_a_block_factor_counts_its_dependent_contacts() -> None:
    """Two contacts with the same column of G make Q_FF singular: the second one's pivot is
    only its share of rho D (L_ii^2 < DEPENDENT_PIVOT rho D_i), so the factor counts one
    dependent contact, which block pivoting reads (a nearly singular block goes to the
    active-set method); independent contacts count none, and a solve from the kept factor
    reports its count again."""
    import scipy.sparse as sp

    from qpbench.solvers.pi_robust_kernel.factor import _block_solve
    from qpbench.solvers.pi_robust_kernel.ordering import _upper
    from qpbench.solvers.pi_robust_kernel.structures import _work

    G = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 1.0]])  # contacts 1 and 2 are one contact twice
    for Q, expected in ((G.T @ G, 1), (np.diag([2.0, 1.0, 3.0]), 0)):
        csc = sp.csc_matrix(Q)
        csc.sort_indices()
        A = (csc.indptr.astype(np.int64), csc.indices.astype(np.int64), csc.data)
        work = _work(3, 6)[0]
        policy = np.ones(3, dtype=np.bool_)
        for _ in range(2):  # factored, then solved from the kept factor
            _block_solve(_upper(A), Q.diagonal().copy(), policy, np.arange(3), 1e-5,
                         np.ones(3), work.cache)
            assert work.cache.counters[2] == expected
        assert work.cache.counters[0] == 1


def dense_factor(values: np.ndarray, offsets: np.ndarray, size: int) -> np.ndarray:
    """The dense L of an envelope factor stored as the kernel stores it (row i in
    ``values[offsets[i]:offsets[i + 1]]``, its diagonal last, kept as its reciprocal)."""
    lower = np.zeros((size, size))
    for row in range(size):
        first = row + 1 - (offsets[row + 1] - offsets[row])
        lower[row, first:row + 1] = values[offsets[row]:offsets[row + 1]]
        lower[row, row] = 1.0 / lower[row, row]
    return lower


def test_deleting_a_contacts_row_from_a_factor_gives_the_factor_of_the_smaller_block() -> None:
    """A free set of a reverse Cuthill-McKee-ordered grid, factored: deleting the row and
    column of its first, a middle or its last contact in place (without a right side, or with
    one, to the same numbers and the forward substitution ``L' y = x`` made as the rows are
    formed) leaves a lower-triangular L' with positive diagonal and ``L' L'^T = H`` without
    that row and column (H = Q_II + rho D_I); deleting a second contact from that, the same
    for H without both."""
    from qpbench.solvers.pi_robust_kernel.factor import _delete_contact, _factor_rows

    Q, _, order, _, _, (starts, rows, data) = ordered_grid(7, 0)
    upper = (starts, starts[1:], rows, data)
    n = starts.size - 1
    dense = Q[order][:, order].toarray()
    diag, rho = dense.diagonal().copy(), 1e-5
    rng = np.random.default_rng(7)
    free = np.flatnonzero(rng.uniform(size=n) < 0.5)
    block = dense[np.ix_(free, free)] + rho * np.diag(diag[free])
    position = np.full(n, -1, dtype=np.int64)
    position[free] = np.arange(free.size)
    values = np.full(data.size + n * n, np.nan)
    offsets = np.zeros(free.size + 1, dtype=np.int64)
    _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, 0, np.empty(0))
    cosines, sines = np.empty(free.size), np.empty(free.size)

    def check(factor: np.ndarray, factor_offsets: np.ndarray, kept: np.ndarray) -> None:
        lower = dense_factor(factor, factor_offsets, kept.size)
        assert np.array_equal(lower, np.tril(lower)) and np.all(np.diag(lower) > 0.0)
        assert np.allclose(lower @ lower.T, block[np.ix_(kept, kept)], rtol=1e-12,
                           atol=1e-12 * diag.max())

    everything = np.arange(free.size)
    for place in (0, free.size // 2, free.size - 1):
        target, target_offsets = values.copy(), offsets.copy()
        _delete_contact(target, target_offsets, free.size, place, cosines, sines, np.empty(0))
        kept = np.delete(everything, place)
        check(target, target_offsets, kept)
        # with a right side: the same numbers, and L' y = x solved as the rows are formed
        with_right, with_right_offsets = values.copy(), offsets.copy()
        right = rng.normal(size=free.size - 1)
        forward = right.copy()
        _delete_contact(with_right, with_right_offsets, free.size, place, cosines, sines,
                        forward)
        assert np.array_equal(with_right_offsets[:free.size], target_offsets[:free.size])
        used = target_offsets[free.size - 1]
        assert np.array_equal(with_right[:used], target[:used])
        lower = dense_factor(target, target_offsets, free.size - 1)
        assert np.allclose(lower @ forward, right, rtol=1e-12, atol=1e-12)
        second = place // 2
        _delete_contact(target, target_offsets, free.size - 1, second, cosines, sines,
                        np.empty(0))
        check(target, target_offsets, np.delete(kept, second))


def posed_order_lcp(Q: sp.csc_matrix, b: np.ndarray) -> tuple[OrderedLcp, Csc, np.ndarray]:
    """(the kernel's OrderedLcp of LCP(Q, b) in the posed order (no ordering, scale 1), Q's
    CSC arrays with 64-bit indices, diag(Q)); Q's row indices are sorted in place first."""
    from qpbench.solvers.pi_robust_kernel.ordering import _upper
    from qpbench.solvers.pi_robust_kernel.structures import OrderedLcp, Posed

    Q.sort_indices()
    A = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    diag = Q.diagonal()
    posed = Posed(A, b, diag, np.empty(0, dtype=np.int64))
    return OrderedLcp(A, _upper(A), posed, b, diag, diag, 1.0), A, diag


def test_a_policy_that_fixes_contacts_of_the_last_one_is_solved_by_deleting_their_rows() -> None:
    """After a policy's block is factored and solved, the policy with two of its contacts
    fixed is solved from that factor with their rows deleted, with no factorization: x_F
    solves ``(Q_FF + rho D_F) x_F = -q_F`` and is zero off F; the updated factor is kept for
    that policy, so solving it again takes it from the cache, to the same x."""
    from qpbench.solvers.pi_robust_kernel.factor import _policy_solve
    from qpbench.solvers.pi_robust_kernel.structures import _work

    Q = generate("grid", 7, seed=1)[0].Q.tocsc()
    n, rho = Q.shape[0], 1e-5
    lcp, _, diag = posed_order_lcp(Q, np.zeros(n))
    rng = np.random.default_rng(2)
    q = rng.normal(size=n)
    policy = rng.uniform(size=n) < 0.5
    capacity = n * (n + 1) // 2
    work = _work(n, capacity)[0]
    refactor = np.empty(0, dtype=np.int64)  # no places of fixed contacts: factor or cache
    size = _policy_solve(lcp, policy, rho, q, work, refactor)
    free = np.flatnonzero(policy)
    assert size == free.size and work.cache.counters[0] == 1
    places = np.array([3, free.size - 5], dtype=np.int64)
    policy[free[places]] = False
    assert _policy_solve(lcp, policy, rho, q, work, places) == free.size - 2
    assert work.cache.counters[0] == 1  # no factorization
    kept = np.flatnonzero(policy)
    H = Q[kept][:, kept].toarray() + rho * np.diag(diag[kept])
    expected = np.zeros(n)
    expected[kept] = np.linalg.solve(H, -q[kept])
    assert np.allclose(work.x, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    updated = work.x.copy()
    _policy_solve(lcp, policy, rho, q, work, refactor)
    assert work.cache.counters[0] == 1  # the updated factor, from the cache
    assert np.array_equal(work.x, updated)


def test_block_pivoting_hands_a_nearly_singular_block_to_the_active_set_method() -> None:
    """On the first prox step of this fork dump (from the start sweeps' policy) the first
    block solved has dependent contacts and leaves mostly negative free contacts: block
    pivoting hands over to the active-set method right after that solve, so that with no solve
    left x is the method's feasible start max(x, 0), where block pivoting alone (no
    active-set method) would exchange them next and stops at its x, with negative entries.
    Given the solves it needs, the active-set method solves the prox LCP."""
    from qpbench.solvers.pi_robust_kernel.entry import _gauss_seidel
    from qpbench.solvers.pi_robust_kernel.pivoting import _inner_lcp
    from qpbench.solvers.pi_robust_kernel.structures import Prox, _work

    problem = import_dump(CYCLING_DUMP)
    Q = problem.Q.tocsc()
    n, rho, b = Q.shape[0], 1e-5, problem.b
    lcp, A, diag = posed_order_lcp(Q, b)
    tol_w = 1e-9 * np.abs(b).max()
    tol_l = tol_w / diag
    centre = np.zeros(n)
    _gauss_seidel(A, b, diag, centre, np.empty(n), 5)
    q = b - rho * diag * centre

    def inner(active_set: bool, budget: int) -> tuple[np.ndarray, np.ndarray, bool]:
        work = _work(n, n * (n + 1) // 2)[0]
        policy = Q @ centre + b <= diag * centre
        _, solved = _inner_lcp(lcp, policy, rho, q, tol_l, tol_w,
                               Prox(1e-14, 0.01, 0.5, 3, 0, active_set, 0), budget, work)
        return work.x.copy(), policy, solved

    handed_over, _, _ = inner(True, 1)
    pivoted, _, _ = inner(False, 1)
    assert np.all(handed_over >= 0.0) and np.any(pivoted < 0.0)
    x, free, solved = inner(True, 10 * n)
    w = Q @ x + rho * diag * x + q
    assert solved and np.all(x >= 0.0) and np.all(x[~free] == 0.0)
    assert np.all(w[~free] >= -tol_w) and np.all(np.abs(w[free]) <= 1e-6 * np.abs(b).max())


def test_the_diagonal_spread_that_gates_row_updates_ignores_contacts_that_move_nothing() -> None:
    """max D_i / min D_i over D_i > 0: a contact with D_i = 0 moves nothing and does not count;
    with none left the spread is 1."""
    from qpbench.solvers.pi_robust_kernel.active_set import _diagonal_spread

    assert _diagonal_spread(np.array([0.0, 2.0, 1e-7, 5.0])) == pytest.approx(5e7)
    assert _diagonal_spread(np.array([3.0, 3.0])) == 1.0
    assert _diagonal_spread(np.zeros(2)) == 1.0


def test_the_active_set_methods_objective_without_products_is_the_objective() -> None:
    """At s minimizing f(x) = x^T H x / 2 + q^T x (H = Q + rho D) on a free set F, zero off F:
    f(s) = q^T s / 2, f(max(s, 0)) = f(s) + d^T H d / 2 with d = max(-s, 0), and for x zero
    off F, f(x + t (s - x)) = f(s) + (1 - t)^2 (f(x) - f(s)): the values the active-set
    method uses instead of products with Q."""
    from qpbench.solvers.pi_robust_kernel.active_set import _clipped_curvature, _objective

    problem = generate("grid", 7, seed=0)[0]
    Q = problem.Q.tocsc()
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    diag, rho = Q.diagonal(), 1e-3
    H = Q.toarray() + rho * np.diag(diag)
    rng = np.random.default_rng(5)
    product = np.empty(problem.n_contacts)
    q = np.empty(problem.n_contacts)

    def f(x: np.ndarray) -> float:
        return _objective(csc, rho, diag, q, x, product)

    for _ in range(5):
        free = np.flatnonzero(rng.uniform(size=problem.n_contacts) < 0.5)
        q[:] = rng.normal(size=problem.n_contacts) * diag
        s = np.zeros(problem.n_contacts)
        s[free] = np.linalg.solve(H[np.ix_(free, free)], -q[free])
        at_minimum = 0.5 * q @ s
        assert (s < 0).any() and (s > 0).any()

        scale = abs(f(np.maximum(s, 0.0))) + abs(at_minimum)
        assert abs(at_minimum - f(s)) <= 1e-9 * scale
        assert abs(at_minimum + _clipped_curvature(csc, rho, diag, s, np.flatnonzero(s < 0))
                   - f(np.maximum(s, 0.0))) <= 1e-9 * scale
        x = np.zeros(problem.n_contacts)
        x[free] = rng.uniform(size=free.size)
        for t in (0.25, 0.8):
            assert abs(at_minimum + (1 - t) ** 2 * (f(x) - at_minimum) - f(x + t * (s - x))) \
                <= 1e-9 * (abs(f(x)) + scale)


@pytest.mark.parametrize("all_of_them, freed", [(True, [1, 2]), (False, [1])])
def test_the_active_set_method_frees_violators_not_coupled_to_one_freed_before(
        all_of_them: bool, freed: list[int]) -> None:
    """Contacts 0, 1 and 2 violate (slacks -2, -3, -1; contact 3's is +1). Contact 1, the
    most negative, is freed first; contact 0 is coupled to it (Q_01 = 0.5 sqrt(D_0 D_1),
    above COUPLED), so freeing 1 raises 0's slack and 0 waits; contact 2 is coupled to 0 only
    (and weakly): freed. When f has not fallen since the last freeing, only contact 1 is.
    The kernel and the Python path free the same contacts."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.pi_robust import _violators_to_free
    from qpbench.solvers.pi_robust_kernel.active_set import _free_violators

    Q = sp.csc_matrix(np.array([[1.0, 0.5, 0.01, 0.0], [0.5, 1.0, 0.0, 0.0],
                                [0.01, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]))
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    slack = np.array([-2.0, -3.0, -1.0, 1.0])
    diag = Q.diagonal()
    policy = np.zeros(4, dtype=bool)
    assert _free_violators(csc, diag, policy, np.zeros(4), slack, 1e-12, all_of_them,
                           np.zeros(4, dtype=np.int64), np.zeros(4))
    assert np.flatnonzero(policy).tolist() == freed

    lcp = Lcp(Q=Q.tocsr(), b=slack, diag=diag, scale=1.0)
    chosen = _violators_to_free(lcp, slack < 0.0, slack, all_of_them=all_of_them)
    assert np.flatnonzero(chosen).tolist() == freed


def test_the_active_set_method_frees_nothing_without_a_violator() -> None:
    """No fixed contact's slack below -tol_w: nothing is freed, and the method is told the
    point is the solution."""
    from qpbench.solvers.pi_robust_kernel.active_set import _free_violators

    Q = sp.identity(3, format="csc")
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    policy = np.array([True, False, False])
    assert not _free_violators(csc, np.ones(3), policy, np.zeros(3), np.array([-5.0, 0.0, -1e-13]),
                               1e-12, True, np.zeros(3, dtype=np.int64), np.zeros(3))
    assert policy.tolist() == [True, False, False]


def empty_upper(n: int, entries: int) -> Csc:
    """Zeroed arrays for an upper triangle of n columns: (starts, rows, values), room for
    ``entries`` entries."""
    return np.zeros(n + 1, dtype=np.int64), np.zeros(entries, dtype=np.int64), np.zeros(entries)


def ordered_grid(size: int, seed: int) -> tuple[sp.csc_matrix, Csc, np.ndarray, Csc,
                                                np.ndarray, Csc]:
    """A generated grid's Q, its 64-bit CSC arrays, its reverse Cuthill-McKee order, and
    _permuted's arrays for that order: (Q, (indptr, indices, data), order, permuted CSC,
    envelope offsets, upper triangle)."""
    from qpbench.solvers.pi_robust_kernel.ordering import _permuted, reverse_cuthill_mckee

    Q = generate("grid", size, seed=seed)[0].Q
    n = Q.shape[0]
    posed = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    order = reverse_cuthill_mckee(posed[0], posed[1], n)
    widths = np.zeros(n + 1, dtype=np.int64)
    upper = empty_upper(n, Q.nnz)
    permuted = _permuted(*posed, order, widths, upper)
    return Q, posed, order, permuted, widths, upper


def test_reverse_cuthill_mckee_is_a_permutation_that_narrows_a_grid() -> None:
    from qpbench.solvers.pi_robust_kernel.ordering import _envelope_widths

    Q, posed, order, _, ordered, _ = ordered_grid(10, seed=0)
    assert sorted(order) == list(range(Q.shape[0]))
    natural = np.zeros(Q.shape[0] + 1, dtype=np.int64)
    _envelope_widths(posed, natural)
    assert ordered[-1] < natural[-1]


def test_the_permutation_copies_its_upper_triangle_and_envelope_in_the_same_pass() -> None:
    """_permuted fills the permuted matrix's upper triangle and envelope offsets as
    _upper_into and _envelope_widths would from its CSC arrays."""
    from qpbench.solvers.pi_robust_kernel.ordering import _envelope_widths, _upper_into

    Q, _, order, permuted, widths, upper = ordered_grid(7, seed=1)
    n = Q.shape[0]
    new_indptr, new_indices, new_data = permuted
    np.testing.assert_array_equal(
        sp.csc_matrix((new_data, new_indices, new_indptr), shape=(n, n)).toarray(),
        Q.toarray()[np.ix_(order, order)])
    expected_widths = np.zeros(n + 1, dtype=np.int64)
    _envelope_widths(permuted, expected_widths)
    np.testing.assert_array_equal(widths, expected_widths)
    expected = empty_upper(n, Q.nnz)
    _upper_into(permuted, expected)
    entries = int(expected[0][-1])
    assert 0 < entries < Q.nnz
    np.testing.assert_array_equal(upper[0], expected[0])
    np.testing.assert_array_equal(upper[1][:entries], expected[1][:entries])
    np.testing.assert_array_equal(upper[2][:entries], expected[2][:entries])


def test_the_kernels_packed_options_unpack_to_the_accuracy_table_row() -> None:
    """Options travel to the compiled kernel as one array; unpacked they are the row's."""
    from qpbench.solvers import accuracy
    from qpbench.solvers.pi_robust_kernel.structures import options_of, unpacked

    row = accuracy.options_for("pi-robust", 1e-6)
    options = unpacked(options_of(row))
    flat = {**options._asdict(), **options.prox._asdict()}
    assert {name: flat[name] for name in flat if name != "prox"} == {
        name: row[name] for name in flat if name != "prox"}


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
def test_a_prox_steps_drift_is_followed_to_the_first_free_contact_at_zero(compiled: bool) -> None:
    """A settled prox step's change d of l, as long as the step before's (a drift along Q_FF's
    null space), moves the centre z to where the first free contact falling along d reaches
    zero; fixed contacts stay. A d that shrinks by 1% a step (a slow contraction) moves
    nothing, nor does a drift along which no free contact falls. Compiled and Python alike."""
    from qpbench.solvers import pi_robust
    from qpbench.solvers.pi_robust_kernel import prox

    def moved(centre: list[float], drift: list[float], previous: list[float],
              policy: list[bool]) -> np.ndarray | None:
        z, d, d_before, free = (np.array(centre), np.array(drift), np.array(previous),
                                np.array(policy))
        if not compiled:
            return pi_robust._drifted(z, d, d_before, free)
        return z if prox._extrapolate_drift(z, d, d_before, free) else None

    free = [True, True, True, False]
    drift = [-0.5, 1.0, -1.0, -6.0]
    # contacts 0 and 2 fall; 2 reaches zero first (after 0.5 of the step), 3 is fixed
    np.testing.assert_array_equal(moved([1.0, 2.0, 0.5, 3.0], drift, drift, free),
                                  [0.75, 2.5, 0.0, 3.0])
    assert moved([1.0, 2.0, 0.5, 3.0], drift, [value / 0.99 for value in drift], free) is None
    assert moved([1.0, 2.0, 0.5, 3.0], [0.5, 1.0, 1.0, -6.0], [0.5, 1.0, 1.0, -6.0],
                 free) is None
    # g = 0.9995: the geometric series ends after 1999 steps, before any contact reaches zero
    slow = [-1e-4, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(moved([1.0, 2.0, 0.5, 0.0], slow,
                                     [value / 0.9995 for value in slow], free),
                               [1.0 - 0.1999, 2.0, 0.5, 0.0], rtol=1e-9)


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


@settings(max_examples=30, deadline=None)
@given(family=st.sampled_from(["grid", "k4", "mass-ratio", "near-duplicate", "cradle"]),
       size=st.integers(3, 7), seed=st.integers(0, 10_000),
       rho=st.sampled_from([1e-6, 1e-3, 1.0]))
def test_primal_active_set_solves_the_prox_lcp_from_zero(family: str, size: int, seed: int,
                                                         rho: float) -> None:
    """From l = 0 (every contact fixed) the active-set method solves LCP(Q + rho D, b):
    x >= 0; ``w = (Q + rho D) x + b >= -tol`` where x = 0 and ``w = 0`` (up to the block
    solve's rounding) where x is free; and its objective ``x^T (Q + rho D) x / 2 + b^T x`` is
    at most the start's, 0."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.pi_robust import BlockSolver, _primal_active_set

    problem = generate(family, size, seed=seed)[0]
    lcp = Lcp.of(problem, dense_limit=300)
    n = lcp.n
    tol_w = 1e-10 * lcp.scale
    tol_l = tol_w / lcp.safe_diag
    x, free, _, solved = _primal_active_set(lcp, BlockSolver(lcp), rho, lcp.b, np.zeros(n),
                                            tol_l, tol_w, budget=10 * n + 10)
    assert solved
    w = lcp.op @ x + rho * lcp.safe_diag * x + lcp.b
    assert np.all(x >= 0.0) and np.all(x[~free] == 0.0)
    assert np.all(w[~free] >= -tol_w)
    assert np.all(np.abs(w[free]) <= 1e-6 * lcp.scale)
    assert 0.5 * x @ (w + lcp.b) <= 0.0


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


def test_the_proximal_interior_point_converges_where_the_plain_one_stalls() -> None:
    """The same 400-box pile has no strictly feasible point (no velocity separates every
    contact); the proximal LCP ``(Q~ + 1e-10 I) l~ + b~`` has one, and its iterates reach
    qpbench's 1e-8 on the pile's own LCP, with no finishing policy iteration."""
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
    assert converged and iterations < 80 and lcp.residual(impulses) <= 1e-8 and not handed
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
