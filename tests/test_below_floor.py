"""Below a problem's double-precision residual floor no solver is judged: verdict ``below-floor``.

A reference certified in exact arithmetic records in the problem's metadata the least residual
any double vector is known to reach on it (``reference_residual_floor``). At a level below it
``judge`` says ``below-floor`` (``success`` False, every metric kept), at a level above it the
answer is judged on merit, and the statistics and reports leave the cell out, naming it.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bench_problems import collinear_balls, exact_impulses

from qpbench.bench import below_floor, stats
from qpbench.bench.report import write_report
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import STATUSES, TIMEOUT, VERDICTS
from qpbench.problem import files, metrics
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.run import BELOW_FLOOR, FLOOR_KEY, judge, residual_floor
from qpbench.studies import sequence

SPEC = SolverSpec(name="any", formulation="lcp", backend="tests", solve=None)
FLOOR = 1e-6  # set by hand on the tiny problem


def answer(impulses: np.ndarray | None, claimed: bool) -> SolverOutput:
    return SolverOutput(impulses=impulses, status="claimed", claimed_success=claimed)


def tiny_with_floor() -> ImpactProblem:
    problem = collinear_balls("row", 3)
    problem.metadata[FLOOR_KEY] = FLOOR
    return problem


@cache
def mass_ratio_10_s2() -> ImpactProblem:
    """A real floor: the exact solution of mass-ratio-10-s2, rounded to double, leaves 7.1e-7."""
    return attach_reference(generate("mass-ratio", 10, seed=2)[0])


# --- the verdict ---------------------------------------------------------------------------
def test_below_floor_is_a_verdict_every_status_list_knows() -> None:
    assert BELOW_FLOOR in VERDICTS and BELOW_FLOOR in STATUSES


def test_a_level_below_the_floor_is_below_floor_whatever_the_answer() -> None:
    problem = tiny_with_floor()
    exact = exact_impulses(problem)
    for impulses, claimed in ((exact, True), (np.full(problem.n_contacts, 0.1), True),
                              (None, False)):
        row = judge(SPEC, problem, answer(impulses, claimed), 1e-8)
        assert row["status"] == BELOW_FLOOR and row["success"] is False
        assert row["claimed_success"] is claimed  # the solver's claim, as it gave it
    # the answer stays visible: its residual is kept, and honesty compares the claim with it
    row = judge(SPEC, problem, answer(exact, True), 1e-8)
    assert row["residual"] == metrics.residual(problem, exact) <= 1e-8
    assert row["status_honest"] is True
    row = judge(SPEC, problem, answer(np.full(problem.n_contacts, 0.1), True), 1e-8)
    assert row["residual"] > 1e-8 and row["status_honest"] is False


def test_a_level_above_the_floor_is_judged_on_merit() -> None:
    problem = tiny_with_floor()
    exact = exact_impulses(problem)
    assert judge(SPEC, problem, answer(exact, True), 1e-4)["status"] == "solved"
    wrong = judge(SPEC, problem, answer(np.full(problem.n_contacts, 0.1), True), 1e-4)
    assert wrong["status"] == "inaccurate" and wrong["success"] is False
    assert judge(SPEC, problem, answer(None, False), 1e-4)["status"] == "failed"


@pytest.mark.parametrize("value", [None, "1e-6", True, math.nan, -1.0, 0.0])
def test_a_missing_or_unusable_floor_is_no_floor(value: object) -> None:
    problem = collinear_balls("row", 3)
    if value is not None:
        problem.metadata[FLOOR_KEY] = value
    assert residual_floor(problem) == 0.0
    row = judge(SPEC, problem, answer(exact_impulses(problem), True), 1e-8)
    assert row["status"] == "solved"


def test_a_certified_floor_survives_the_problem_file_and_decides_the_verdict(
        tmp_path: Path) -> None:
    """mass-ratio-10-s2: its reference (the exact solution rounded) is judged ``below-floor``
    at 1e-8 and ``solved`` at 1e-6; an answer of zeros is ``inaccurate`` at 1e-6."""
    problem = files.load(files.save(mass_ratio_10_s2(), tmp_path / "mass-ratio-10-s2"))
    floor = residual_floor(problem)
    assert 1e-8 < floor < 1e-6
    reference = problem.reference.impulses
    tight = judge(SPEC, problem, answer(reference, False), 1e-8)
    assert tight["status"] == BELOW_FLOOR and tight["success"] is False
    assert tight["residual"] == pytest.approx(floor)
    assert judge(SPEC, problem, answer(reference, True), 1e-6)["status"] == "solved"
    zeros = judge(SPEC, problem, answer(np.zeros(problem.n_contacts), False), 1e-6)
    assert zeros["status"] == "inaccurate"


# --- the statistics and the reports ------------------------------------------------------
def rows_with_a_floor() -> list[dict]:
    """Two pairs on two problems at 1e-4 and 1e-8, cold; problem ``m`` has a floor between the
    levels: at 1e-8 pair ``a`` is below-floor and pair ``b`` timed out."""
    rows = []
    for problem in ("k", "m"):
        for solver, time_s in (("a", 1e-4), ("b", 2e-4)):
            for accuracy in (1e-4, 1e-8):
                status = "solved"
                if problem == "m" and accuracy == 1e-8:
                    status = BELOW_FLOOR if solver == "a" else TIMEOUT
                rows.append({
                    "problem": problem, "family": "mass-ratio", "solver": solver,
                    "formulation": "lcp", "backend": "tests", "accuracy": accuracy,
                    "mode": "cold", "status": status, "success": status == "solved",
                    "claimed_success": status != TIMEOUT,
                    "residual": 5e-7 if status == BELOW_FLOOR else accuracy / 10,
                    "v_error": 1e-9, "time_s": time_s, "time_limit_s": 1.0, "contacts": 3})
    return rows


def test_the_stats_leave_out_every_row_of_a_cell_below_the_floor() -> None:
    frame = pd.DataFrame(rows_with_a_floor())
    cells = stats.below_floor_cells(frame)
    assert cells.to_dict("records") == [{"problem": "m", "accuracy": 1e-8, "rows": 2}]
    kept = stats.without_below_floor(frame)
    assert len(kept) == len(frame) - 2  # the timeout in that cell goes too
    assert set(kept.loc[kept["problem"] == "m", "accuracy"]) == {1e-4}  # its other level stays
    summary = stats.level_summary(kept, stats.time_scale_shift(kept))
    assert list(summary["success_rate"]) == [1.0] * 4
    tight = summary[summary["accuracy"] == 1e-8].set_index("solver")
    assert tight.loc["b/lcp", "timeout"] == 0 and tight.loc["b/lcp", "solves"] == 1
    ratios = stats.performance_ratios(kept[kept["accuracy"] == 1e-8])
    assert list(ratios.index) == ["k"]
    assert stats.without_below_floor(kept).equals(kept)


def test_the_note_names_the_problems_and_levels_below_the_floor() -> None:
    text = below_floor.note(pd.DataFrame(rows_with_a_floor()))
    assert text.startswith("1 cell (problem, level) of 2 solves lies below")
    assert text.endswith(": m at 1e-08.")
    assert below_floor.note(pd.DataFrame(rows_with_a_floor()[:4])) == ""
    many = pd.DataFrame([{"problem": f"p{index:02d}", "accuracy": accuracy, "status": BELOW_FLOOR}
                         for index in range(12) for accuracy in (1e-8, 1e-10)])
    text = below_floor.note(many)
    assert text.startswith("24 cells (problem, level) of 24 solves lie below")
    assert "p00 at 1e-08, 1e-10; " in text and text.endswith("; and 2 more problems.")


def test_the_reports_say_which_cells_were_below_the_floor_and_leave_them_out(
        tmp_path: Path) -> None:
    store = ResultStore(tmp_path / "bench.parquet")
    store.write_part(rows_with_a_floor())
    store.compact()
    text = write_report(store.path, tmp_path / "out").read_text()
    assert f"{BELOW_FLOOR} 1" in text.split("Statuses: ", 1)[1].split("\n", 1)[0]
    assert "1 cell (problem, level) of 2 solves lies below" in text and ": m at 1e-08." in text
    tight = text.split("### Accuracy 1e-08\n", 2)[2].split("\n#", 1)[0]  # the per-level table
    assert "| b/lcp |  | 1 | 100.0% |" in tight and "| a/lcp |  | 1 | 100.0% |" in tight
    page = (tmp_path / "out" / "index.html").read_text()
    assert "lies below the problem&#x27;s double-precision residual floor" in page


def test_the_sequence_summary_leaves_out_a_step_below_the_floor() -> None:
    def step(index: int, status: str, time_s: float) -> dict:
        figures = {"status": status, "success": status == "solved", "residual": 0.0,
                   "iterations": 1, "solver_status": "ok", "time_s": time_s}
        return {"scene": "s", "problem": f"p{index}", "index": index, "solver": "x/lcp",
                "warm_startable": True, "warm_start_given": index > 0,
                **{f"{mode}_{name}": value for mode in ("cold", "sequence")
                   for name, value in figures.items()}}

    summary = sequence.summarize([step(0, "solved", 1e-4), step(1, BELOW_FLOOR, 5e-4)])
    assert summary[0]["solves"] == 1 and summary[0]["cold_success_rate"] == 1.0
    assert summary[0]["cold_median_s"] == 1e-4
