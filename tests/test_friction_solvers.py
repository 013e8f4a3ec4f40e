"""The frictional solvers: nsgs, the ccp twins, staggered projections and Lemke on the
Stewart-Trinkle LCP, each judged by qpbench on problems with known answers."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from friction_cases import ball_on_floor, pair_on_floor

from qpbench.problem import friction_metrics as fm
from qpbench.problem import metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import registry
from qpbench.solvers.run import solve_and_judge


def hand_answer(u_normal: float, u_tangential: float, mu: float, restitution: float = 0.0,
                mass: float = 1.0) -> np.ndarray:
    """The ball sticks iff |u_T-| <= mu (1 + e) |u_N-|; else it slides with
    l_T = -mu l_N sign(u_T-)."""
    normal = mass * (1.0 + restitution) * -u_normal
    if abs(u_tangential) <= mu * normal / mass:
        return np.array([normal, -mass * u_tangential])
    return np.array([normal, -mu * normal * np.sign(u_tangential)])


def row_of(key: str, problem: FrictionalProblem, accuracy: float = 1e-10,
           warm_start: np.ndarray | None = None):
    spec = registry.get(key, "frictional")
    return solve_and_judge(spec, problem, accuracy, warm_start)


BALLS = [(-2.0, 0.6, 0.5), (-2.0, 1.5, 0.5), (-1.0, -3.0, 0.5), (-1.0, 0.0, 0.2)]


# --- nsgs ------------------------------------------------------------------------------
@pytest.mark.parametrize("u_normal, u_tangential, mu", BALLS)
def test_nsgs_finds_the_hand_answer_of_a_ball_on_the_floor(u_normal: float, u_tangential: float,
                                                           mu: float) -> None:
    problem = ball_on_floor(u_normal, u_tangential, mu, restitution=0.5, mass=2.0)
    row, output = row_of("nsgs/nsgs", problem)
    assert row["status"] == "solved" and row["status_honest"]
    np.testing.assert_allclose(output.impulses,
                               hand_answer(u_normal, u_tangential, mu, 0.5, 2.0), atol=1e-12)
    assert output.iterations == 1  # one contact: one exact local solve


def test_nsgs_on_three_coupled_contacts_reaches_1e_10() -> None:
    for seed in range(5):
        row, output = row_of("nsgs/nsgs", pair_on_floor(mu=0.6, seed=seed))
        assert row["status"] == "solved" and row["residual"] <= 1e-10
        assert output.info["outer_iterations"] == output.iterations


def test_nsgs_warm_started_from_its_answer_needs_at_most_one_sweep() -> None:
    problem = pair_on_floor(mu=0.6, seed=3)
    _, first = row_of("nsgs/nsgs", problem)
    row, again = row_of("nsgs/nsgs", problem, warm_start=first.impulses)
    assert row["status"] == "solved" and again.iterations <= 1


def test_nsgs_at_mu_zero_gives_the_frictionless_answer() -> None:
    problem = pair_on_floor(mu=0.0, seed=1)
    row, output = row_of("nsgs/nsgs", problem)
    normal, tangential = problem.split(output.impulses)
    assert np.all(tangential == 0.0)
    assert metrics.residual(problem.normal, normal) == fm.residual(problem, output.impulses)
    assert row["status"] == "solved"


# --- Lemke on the Stewart-Trinkle LCP ----------------------------------------------------
def test_one_lemke_spec_serves_both_problem_kinds() -> None:
    spec = registry.get("lemke/lcp", "frictional")
    assert set(spec.kinds) == {"impact", "frictional"}


@pytest.mark.parametrize("u_normal, u_tangential, mu", BALLS)
def test_lemke_finds_the_hand_answer_of_a_ball_on_the_floor(u_normal: float,
                                                            u_tangential: float,
                                                            mu: float) -> None:
    row, output = row_of("lemke/lcp", ball_on_floor(u_normal, u_tangential, mu))
    assert row["status"] == "solved" and row["status_honest"]
    np.testing.assert_allclose(output.impulses, hand_answer(u_normal, u_tangential, mu),
                               atol=1e-12)


def test_lemke_on_the_wedge_says_its_ray_proves_nothing() -> None:
    """The wedge has no solution, and Lemke ends on a ray of Stewart-Trinkle's LCP. A ray
    proves that no solution exists only for a copositive-plus matrix, which that one is not in
    general, so the status says it is no proof, instead of the plain ``ray termination``
    that is one on an impact LCP."""
    from qpbench.problem.friction_generate import generate
    from qpbench.solvers.lemke import RAY_TERMINATION, STEWART_TRINKLE_RAY

    row, output = row_of("lemke/lcp", generate("wedge", 1)[0])
    assert output.status == STEWART_TRINKLE_RAY != RAY_TERMINATION
    assert not output.claimed_success and row["status"] != "solved" and row["status_honest"]


def test_lemke_on_three_coupled_contacts_agrees_with_nsgs_on_the_residual() -> None:
    for seed in range(5):
        row, _ = row_of("lemke/lcp", pair_on_floor(mu=0.6, seed=seed))
        assert row["status"] == "solved" and row["residual"] <= 1e-10


# --- staggered projections -----------------------------------------------------------------
STAGGERED = ["osqp/staggered", "clarabel/staggered", "pi-robust/staggered", "pgs/staggered",
             "lemke/staggered"]


@pytest.mark.parametrize("key", STAGGERED)
def test_staggered_finds_the_hand_answer_of_a_ball_on_the_floor(key: str) -> None:
    for u_normal, u_tangential, mu in BALLS:
        row, output = row_of(key, ball_on_floor(u_normal, u_tangential, mu), accuracy=1e-8)
        assert row["status"] == "solved", (key, u_tangential, output.status)
        assert row["residual"] <= 1e-8 and row["status_honest"]
        np.testing.assert_allclose(output.impulses, hand_answer(u_normal, u_tangential, mu),
                                   atol=1e-6)
        assert row["outer_iterations"] == 1  # one contact: the two projections are exact


@pytest.mark.parametrize("key", STAGGERED)
def test_staggered_on_three_coupled_contacts_reports_its_rounds(key: str) -> None:
    row, output = row_of(key, pair_on_floor(mu=0.6, seed=2), accuracy=1e-8)
    assert row["status"] == "solved" and row["residual"] <= 1e-8
    assert row["outer_iterations"] == output.info["outer_iterations"] >= 1


def test_staggered_warm_started_from_an_answer_does_no_round() -> None:
    problem = pair_on_floor(mu=0.6, seed=2)
    _, answer = row_of("nsgs/nsgs", problem)
    row, output = row_of("pi-robust/staggered", problem, accuracy=1e-8,
                         warm_start=answer.impulses)
    assert row["status"] == "solved" and output.info["outer_iterations"] == 0
    assert output.info["compiled"] and output.info["returned"] == "warm start"


def test_staggered_with_empty_friction_boxes_is_the_frictionless_solve() -> None:
    """mu = 0: every box is [0, 0], so no backend sees a friction QP (quadprog would refuse
    it) and l_T stays exactly 0."""
    problem = pair_on_floor(mu=0.0, seed=1)
    row, output = row_of("quadprog/staggered", problem, accuracy=1e-8)
    assert row["status"] == "solved"
    assert np.all(problem.split(output.impulses)[1] == 0.0)


def _generated_frictional() -> list[FrictionalProblem]:
    from qpbench.problem.friction_generate import generate

    return [*generate("pyramid", 3), *generate("friction-mass-ratio", 4, seed=1),
            *generate("incline", 2), *generate("rough-box", 30), *generate("wedge", 1)]


def test_pi_robust_staggered_runs_its_loop_compiled_with_the_python_loops_answers(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled loop is the Python loop with pi-robust inside, round for round: the same
    impulses to the last bit, the same rounds, inner iterations and verdict; neither meets
    1e-8 in 200 rounds on the rough box, nor on the wedge, which has no solution."""
    from qpbench.solvers import friction_staggered

    problems = [pair_on_floor(mu=0.6, seed=seed) for seed in range(3)] + _generated_frictional()
    compiled = [row_of("pi-robust/staggered", problem, accuracy=1e-8) for problem in problems]
    monkeypatch.setattr(friction_staggered, "COMPILED_LOOPS", ())
    python = [row_of("pi-robust/staggered", problem, accuracy=1e-8) for problem in problems]
    for problem, (row, output), (python_row, python_output) in zip(problems, compiled, python,
                                                                   strict=True):
        assert output.info["compiled"] and "compiled" not in python_output.info, problem.name
        np.testing.assert_array_equal(output.impulses, python_output.impulses)
        for key in ("outer_iterations", "inner_solves", "returned", "residual"):
            assert output.info[key] == python_output.info[key], (problem.name, key)
        assert output.iterations == python_output.iterations
        assert (row["status"], row["claimed_success"]) == (python_row["status"],
                                                           python_row["claimed_success"])
        assert row["status_honest"]
    statuses = {problem.name: row["status"] for problem, (row, _) in zip(problems, compiled,
                                                                         strict=True)}
    assert statuses.pop("rough-box-30-s0") == "inaccurate"
    assert statuses.pop("wedge-1-s0") == "inaccurate"
    assert set(statuses.values()) == {"solved"}


def test_the_compiled_coulomb_residual_is_qpbenchs_to_the_last_bit() -> None:
    from qpbench.solvers.pi_robust_call import csc_arrays
    from qpbench.solvers.staggered_compiled import coulomb_residual

    rng = np.random.default_rng(7)
    for problem in [pair_on_floor(mu=0.6, seed=1), *_generated_frictional()]:
        n = problem.n_contacts
        for impulses in (np.zeros(2 * n), rng.standard_normal(2 * n),
                         np.concatenate([np.abs(rng.standard_normal(n)), np.zeros(n)])):
            assert coulomb_residual(csc_arrays(problem.W), problem.q, problem.diag_N,
                                    problem.mu, problem.scale, impulses) == \
                fm.residual(problem, impulses)


def test_the_compiled_loop_reads_ws_blocks_as_scipys_slices_store_them() -> None:
    """The blocks the compiled loop takes from W's own arrays are, array for array, the CSR
    arrays of the problem's W_NT, W_TN and W_TT (so its products sum in SciPy's order)."""
    from qpbench.solvers.pi_robust_call import csc_arrays
    from qpbench.solvers.staggered_compiled import _block

    for problem in [pair_on_floor(mu=0.6, seed=1), *_generated_frictional()]:
        n = problem.n_contacts
        W = csc_arrays(problem.W)
        W_TT = problem.W_TT.tocsr()
        for block, (first_row, end_row, first_column) in (
                (problem.W_NT, (0, n, n)), (problem.W_TN, (n, 2 * n, 0)),
                (W_TT, (n, 2 * n, n))):
            for got, stored in zip(_block(W, first_row, end_row, first_column),
                                   (block.indptr, block.indices, block.data), strict=True):
                np.testing.assert_array_equal(got, stored, err_msg=problem.name)


def test_the_compiled_loop_reads_the_staggered_row_once_per_level_and_state() -> None:
    """``staggered_compiled.loop_settings`` serves every problem from one reading of the row,
    which holds only while none of its entries depends on the problem's scale, and reads it
    again while a measurement overrides it."""
    from qpbench.solvers import accuracy, staggered_compiled

    for eps in (1e-2, 1e-8, 1e-10):
        assert accuracy.options_for(staggered_compiled.ROW, eps, 1.0) == \
            accuracy.options_for(staggered_compiled.ROW, eps, 3.7e4)
    settings = staggered_compiled.loop_settings(1e-8)
    assert settings.inner_eps == pytest.approx(1e-9)
    cap = accuracy.options_for(staggered_compiled.ROW, 1e-8)["max_outer"]
    assert settings.max_outer == cap
    assert staggered_compiled.loop_settings(1e-8) is settings
    with accuracy.overridden(staggered_compiled.ROW, max_outer=cap + 7):
        overridden = staggered_compiled.loop_settings(1e-8)
        assert overridden.max_outer == cap + 7
        assert overridden.packed[staggered_compiled.OPTION_MAX_OUTER] == cap + 7
    assert staggered_compiled.loop_settings(1e-8).max_outer == cap


def test_a_declined_compiled_loop_leaves_the_answer_to_the_python_loop(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """When a normal solve inside the compiled loop is not certified, the loop ends with
    FALLBACK and the Python loop answers (its time counts too)."""
    from qpbench.solvers import staggered_compiled

    declined = []

    def declining(*args: object) -> tuple:
        declined.append(True)
        return np.zeros(0), np.inf, staggered_compiled.FALLBACK, 1, 0, 0, 0

    monkeypatch.setattr(staggered_compiled, "staggered_pi_robust", declining)
    row, output = row_of("pi-robust/staggered", pair_on_floor(mu=0.6, seed=2), accuracy=1e-8)
    assert declined and "compiled" not in output.info
    assert row["status"] == "solved" and row["status_honest"]


def test_the_box_gauss_seidel_reaches_the_box_qp_optimum() -> None:
    from qpbench.solvers.friction_staggered import BoxQP, box_gauss_seidel, box_residual

    P = np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]])
    box = BoxQP(P=sp.csc_matrix(P), c=np.array([-4.0, 1.0, 3.0]),
                lower=np.full(3, -1.0), upper=np.full(3, 1.0))
    answer = box_gauss_seidel(box, 1e-12, 10_000, 5, np.zeros(3))
    assert answer.claimed_success and box_residual(box, answer.x) <= 1e-12
    # x_0 at its upper bound (g_0 = -2.5 < 0), x_2 at its lower (g_2 = 0.5 > 0), x_1 inside
    # with g_1 = 1 + 2 x_1 - 1 + 1 = 0
    np.testing.assert_allclose(answer.x, [1.0, -0.5, -1.0], atol=1e-11)


def test_a_fixed_coordinate_stays_at_its_bound_and_the_rest_solve_the_restricted_box() -> None:
    """lower == upper fixes a coordinate (an empty friction box): the compiled sweeps leave
    it there, and the others reach the optimum of the box QP restricted to them, which is
    also what a backend gets through on_free_coordinates."""
    from qpbench.solvers.friction_staggered import (
        BoxAnswer,
        BoxQP,
        box_gauss_seidel,
        box_residual,
        on_free_coordinates,
    )

    P = np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]])
    box = BoxQP(P=sp.csc_matrix(P), c=np.array([-4.0, 1.0, 3.0]),
                lower=np.array([-1.0, 0.0, -1.0]), upper=np.array([1.0, 0.0, 1.0]))
    answer = box_gauss_seidel(box, 1e-12, 10_000, 5, np.full(3, 0.5))
    assert answer.claimed_success and box_residual(box, answer.x) <= 1e-12
    assert answer.x[1] == 0.0
    # x_1 = 0 decouples x_0 (g_0 = 2 x_0 - 4 < 0 on [-1, 1]: upper) and x_2 (g_2 = 2 x_2 + 3 > 0:
    # lower)
    np.testing.assert_allclose(answer.x, [1.0, 0.0, -1.0], atol=1e-12)
    seen: list[BoxQP] = []

    def recording(restricted: BoxQP, eps: float, scale: float,
                  start: np.ndarray) -> BoxAnswer:
        seen.append(restricted)
        return box_gauss_seidel(restricted, 1e-12, 10_000, 5, start)

    through = on_free_coordinates(recording)(box, 1e-12, 1.0, np.zeros(3))
    assert seen[0].n == 2 and np.array_equal(seen[0].P.toarray(), P[np.ix_([0, 2], [0, 2])])
    np.testing.assert_allclose(through.x, answer.x, atol=1e-12)


# --- Anitescu's relaxation ------------------------------------------------------------------
CCP = ["pi-robust/ccp", "clarabel/ccp", "osqp/ccp", "lemke/ccp", "pgs/ccp"]


@pytest.mark.parametrize("key", CCP)
def test_ccp_twins_solve_the_relaxation_and_are_judged_on_it(key: str) -> None:
    row, _ = row_of(key, pair_on_floor(mu=0.6, seed=0))
    assert row["model"] == "ccp" and row["residual"] <= 1e-8


@pytest.mark.parametrize("key", CCP)
def test_ccp_on_a_sliding_ball_separates_which_is_model_error(key: str) -> None:
    """A sliding ball: the relaxation lifts it off (u_N = mu |u_T| > 0), so its ccp residual is
    zero and its Coulomb residual, the model error, is not."""
    problem = ball_on_floor(u_normal=-1.0, u_tangential=3.0, mu=0.5)
    row, output = row_of(key, problem)
    assert row["status"] == "solved" and row["residual"] <= 1e-8
    assert row["model_error"] > 1e-3
    u_normal = problem.split(problem.u(output.impulses))[0]
    assert u_normal[0] > 0.1


def test_pi_robust_ccp_in_one_compiled_call_solves_what_the_general_twin_solves() -> None:
    """pi-robust's twin maps the warm start in, sweeps each contact's pair (z+, z-) as one
    block, solves and maps the answer back in one compiled call: qpbench's ccp verdict
    wherever the general twin (pi-robust's own solve on the relaxed problem, mapped in Python)
    succeeds, with the same velocities, cold and warm-started; started from the general
    twin's answer it stops at the start."""
    from qpbench.problem import friction_metrics
    from qpbench.problem.formulations import pose
    from qpbench.solvers import friction_ccp, pi_robust

    general = friction_ccp.make_solve(pi_robust.solve)
    twin = registry.get("pi-robust/ccp", "frictional")
    problems = [pair_on_floor(mu=0.6, seed=seed) for seed in range(3)] + _generated_frictional()
    rng = np.random.default_rng(3)
    for problem in problems:
        pose(problem, "ccp")
        n = problem.n_contacts
        for warm_start in (None, rng.standard_normal(2 * n)):
            fast, slow = twin.solve(problem, 1e-8, warm_start), general(problem, 1e-8, warm_start)
            if problem.name == "wedge-1-s0":  # no solution: both end on Lemke's ray
                np.testing.assert_array_equal(fast.impulses, slow.impulses)
                assert fast.info["path"] == slow.info["path"] == "lemke fallback: ray termination"
                assert not fast.claimed_success and fast.info["relaxed_contacts"] == 2 * n
                continue
            assert fast.info["compiled"] is True and fast.info["relaxed_contacts"] == 2 * n
            for output in (fast, slow):
                assert friction_metrics.residual(problem, output.impulses, "ccp") <= 1e-8
            np.testing.assert_allclose(problem.v_plus(fast.impulses),
                                       problem.v_plus(slow.impulses), rtol=0, atol=1e-6 * max(
                                           np.abs(problem.v_minus).max(), 1.0))
        if problem.name != "wedge-1-s0":
            again = twin.solve(problem, 1e-8, slow.impulses)
            assert again.iterations == 0 and again.info["path"] == "start"


def test_pi_robust_ccps_contact_block_sweeps_solve_a_lone_contact_without_a_factorization(
        ) -> None:
    """One ball sliding, one sticking: each contact's 2x2 block LCP is the whole problem, so
    the sweeps answer it exactly (path "start sweeps", no linear solve)."""
    for u_tangential in (3.0, 0.6):
        problem = ball_on_floor(u_normal=-2.0, u_tangential=u_tangential, mu=0.5)
        row, output = row_of("pi-robust/ccp", problem, accuracy=1e-10)
        assert row["status"] == "solved"
        assert output.info["path"] == "start sweeps" and output.iterations == 0


def test_ccp_on_a_sticking_ball_is_the_coulomb_answer() -> None:
    problem = ball_on_floor(u_normal=-2.0, u_tangential=0.6, mu=0.5)
    row, output = row_of("pi-robust/ccp", problem)
    assert row["status"] == "solved" and row["model_error"] <= 1e-10
    np.testing.assert_allclose(output.impulses, hand_answer(-2.0, 0.6, 0.5), atol=1e-12)


# --- the listing ------------------------------------------------------------------------
def test_every_frictionless_dual_or_lcp_solver_has_its_ccp_and_staggered_twins() -> None:
    """... but for the untwinned backends (native pairs, whose qpsolvers twins are twinned, and
    Siconos, which has its own fc2d solvers)."""
    from qpbench.solvers.friction_ccp import UNTWINNED_BACKENDS

    listed = {spec.key: spec for spec in registry.all_solvers()}
    inner = {spec.name: spec for spec in listed.values()
             if "impact" in spec.kinds and spec.formulation in ("dual", "lcp")}
    assert {"pi-robust", "pgs", "lemke", "apgd", "penalty", "pi", "pi-v2", "daqp",
            "daqp-native"} <= set(inner)
    for name, spec in inner.items():
        for formulation in ("ccp", "staggered"):
            twin = listed.get(f"{name}/{formulation}")
            if spec.backend in UNTWINNED_BACKENDS:
                assert twin is None
                continue
            assert twin is not None and twin.kinds == ("frictional",)
            assert twin.usable == spec.usable and twin.reason == spec.reason
    assert listed["nsgs/nsgs"].kinds == ("frictional",)


REGISTERED_KEYS = """
import importlib.util, json, pathlib, sys
import qpbench
path = pathlib.Path(qpbench.__file__).parent / "solvers" / "__init__.py"
source = path.read_text()
loop = "for _module in FAMILIES:"
assert loop in source
if sys.argv[1] == "reversed":  # the package's own code, its families imported last to first
    source = source.replace(loop, "for _module in reversed(FAMILIES):")
spec = importlib.util.spec_from_file_location("qpbench.solvers", path,
                                              submodule_search_locations=[str(path.parent)])
package = importlib.util.module_from_spec(spec)
sys.modules["qpbench.solvers"] = package
exec(compile(source, str(path), "exec"), package.__dict__)
from qpbench.solvers import registry
print(json.dumps([spec.key for spec in registry.all_solvers()]))
"""


def test_the_registered_pairs_do_not_depend_on_the_order_families_are_imported() -> None:
    """The families imported last to first, every twin family before the families it twins,
    give the same pairs as the usual order."""
    import json
    import subprocess
    import sys

    def keys(order: str) -> list[str]:
        result = subprocess.run([sys.executable, "-c", REGISTERED_KEYS, order],
                                capture_output=True, text=True, check=True)
        return json.loads(result.stdout)

    usual = keys("usual")
    assert {"pgs/ccp", "pgs/staggered", "pi-robust/ccp", "daqp/staggered"} <= set(usual)
    assert keys("reversed") == usual
