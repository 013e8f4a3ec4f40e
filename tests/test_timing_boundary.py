"""One timing boundary for every solver (docs/design.md section 7): ``time_s`` is measured by
the harness around the whole solve, from the formulation's matrices to l; a backend's own
split and cvxpy's compile time are extra columns that fit inside it."""

from __future__ import annotations

import gc
import math

from bench_problems import collinear_balls

from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec, Stopwatch
from qpbench.solvers.registry import get, resolve
from qpbench.solvers.run import call_solver, solve_and_judge


def test_time_s_holds_osqps_own_set_up_and_solve_on_a_1000_ball_box() -> None:
    """OSQP's set-up (KKT factorization) dominates on a box packing: qpsolvers' solve_time
    leaves it out, qpbench's time_s may not."""
    problem = generate("box", 1000, seed=0)[0]
    output = call_solver(get("osqp/dual"), problem, 1e-6)
    setup, solve = (output.backend_times["backend_setup_time_s"],
                    output.backend_times["backend_solve_time_s"])
    assert setup > 0.0 and solve > 0.0
    assert output.time_s >= setup + solve
    assert output.formulation_time_s > 0.0


def test_cvxpy_compile_time_is_inside_time_s_and_stored_alone() -> None:
    row, output = solve_and_judge(get("cvxpy-clarabel/dual"), collinear_balls("row", 4), 1e-6)
    assert output.backend_times["compile_time_s"] > 0.0
    assert row["time_s"] >= row["compile_time_s"] + row["backend_solve_time_s"]


def test_our_solvers_are_timed_by_the_same_stopwatch() -> None:
    """A solve function never times itself; the harness fills time_s for ours as for theirs."""
    for spec in [s for s in resolve(["pi-robust", "pgs", "lemke"]) if "impact" in s.kinds]:
        output = call_solver(spec, collinear_balls("row", 5), 1e-8)
        assert math.isfinite(output.time_s) and output.time_s > 0.0
        assert output.backend_times == {}


def test_a_slow_solve_is_charged_in_full() -> None:
    import bench_solvers

    with bench_solvers.registered():
        output = call_solver(resolve(["test-slow/lcp"])[0], collinear_balls("row", 3), 1e-8)
    assert output.time_s >= 0.3  # the solver sleeps 0.3 s inside its solve function


def test_a_solver_that_raises_is_an_error_status_with_its_time() -> None:
    def raising(problem: ImpactProblem, accuracy: float, warm_start: object = None) -> None:
        raise ArithmeticError("pivot is zero")

    spec = SolverSpec(name="raises", formulation="lcp", backend="tests", solve=raising)
    output = call_solver(spec, collinear_balls("row", 3), 1e-8)
    assert output.impulses is None and output.claimed_success is False
    assert output.status.startswith("error: ArithmeticError: pivot is zero at ")
    assert math.isfinite(output.time_s) and output.time_s >= 0.0


def test_the_stopwatch_pauses_the_garbage_collector_inside_and_restores_it() -> None:
    """A solve runs with the cyclic collector off (as under timeit), whatever state it was in."""
    seen: list[bool] = []

    def watching(problem: ImpactProblem, accuracy: float, warm_start: object = None
                 ) -> SolverOutput:
        seen.append(gc.isenabled())
        return SolverOutput(impulses=None, status="watched", claimed_success=False)

    spec = SolverSpec(name="watches", formulation="lcp", backend="tests", solve=watching)
    assert gc.isenabled()
    call_solver(spec, collinear_balls("row", 3), 1e-8)
    assert seen == [False] and gc.isenabled()
    gc.disable()
    try:
        with Stopwatch() as clock:
            assert not gc.isenabled()
        assert not gc.isenabled() and clock.elapsed >= 0.0
    finally:
        gc.enable()
