"""The fastest of a few repeats, as the head-to-head and the sequence mode time a solve, and the
main table's repeats within a budget. The stopwatch is replaced by given times here: no test
depends on the clock."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from bench_problems import collinear_balls

from qpbench.bench import repeats, worker
from qpbench.bench.settings import Cell, Limits
from qpbench.errors import QpbenchError
from qpbench.problem import files
from qpbench.solvers.base import SolverOutput


def given_times(monkeypatch: pytest.MonkeyPatch, times: list[float]) -> list[object]:
    """Every call_solver of the repeats module returns the next of ``times``; the warm starts
    it was given are recorded."""
    upcoming: Iterator[float] = iter(times)
    warm_starts: list[object] = []

    def call_solver(spec, problem, accuracy, warm_start=None) -> SolverOutput:
        warm_starts.append(warm_start)
        output = SolverOutput(impulses=np.zeros(1), status="given", claimed_success=True)
        output.time_s = next(upcoming)
        return output

    monkeypatch.setattr(repeats, "call_solver", call_solver)
    return warm_starts


def test_the_fastest_of_the_repeats_is_kept_each_from_the_same_warm_start(
        monkeypatch: pytest.MonkeyPatch) -> None:
    warm_starts = given_times(monkeypatch, [0.02, 0.005, 0.01])
    start = np.ones(1)
    [outputs] = repeats.time_interleaved([repeats.Timing(None, None, start, unit="one")],
                                         repeats=3, warm_up=False)
    assert repeats.fastest_output(outputs).time_s == 0.005
    assert len(warm_starts) == 3 and all(warm is start for warm in warm_starts)


def test_a_solve_slower_than_the_repeat_budget_is_not_repeated(
        monkeypatch: pytest.MonkeyPatch) -> None:
    warm_starts = given_times(monkeypatch, [2 * repeats.REPEAT_BUDGET_S, 0.001])
    [outputs] = repeats.time_interleaved([repeats.Timing(None, None, unit="one")], repeats=5,
                                         warm_up=False)
    assert repeats.fastest_output(outputs).time_s == 2 * repeats.REPEAT_BUDGET_S
    assert len(warm_starts) == 1


def test_a_unit_whose_warm_up_passed_the_cap_is_timed_no_further(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The slow unit's warm-up (12 s against a cap of 10 s) stands for its interleaved timing,
    and its cold timing gets no call; the fast unit is timed as without a cap."""
    warm_starts = given_times(monkeypatch, [12.0, 0.001, *[0.002] * 6])
    slow = [repeats.Timing(None, None, unit="slow"),
            repeats.Timing(None, None, cold=True, unit="slow")]
    fast = [repeats.Timing(None, None, unit="fast"),
            repeats.Timing(None, None, cold=True, unit="fast")]
    slow_warm, fast_warm, slow_cold, fast_cold = repeats.time_interleaved(
        [slow[0], fast[0], slow[1], fast[1]], repeats=3, flush=lambda: None, cap_s=10.0)
    assert [output.time_s for output in slow_warm] == [12.0] and slow_cold == []
    assert len(fast_warm) == len(fast_cold) == 3
    assert len(warm_starts) == 2 + 6  # two warm-ups, then the fast unit's six timed calls


def test_without_a_cap_a_slow_warm_up_is_discarded_and_timed_calls_follow(
        monkeypatch: pytest.MonkeyPatch) -> None:
    given_times(monkeypatch, [12.0, 3.0])
    [outputs] = repeats.time_interleaved([repeats.Timing(None, None, unit="slow")], repeats=3)
    assert [output.time_s for output in outputs] == [3.0]  # (past the repeat budget)


# --- the main table's repeats (qpbench run --repeats K --repeat-budget S) ------------------
def repeats_of_a_cell(monkeypatch: pytest.MonkeyPatch, tmp_path, times: list[float],
                      limits: Limits) -> dict:
    """The worker's row of one cell whose timed solves take ``times`` in turn (a real solve of
    a tiny problem, its stopwatch replaced; the untimed warm-up before them takes 1 s)."""
    upcoming: Iterator[float] = iter([1.0, *times])
    real_call_solver = worker.call_solver

    def call_solver(spec, problem, accuracy, warm_start=None) -> SolverOutput:
        output = real_call_solver(spec, problem, accuracy, warm_start)
        output.time_s = next(upcoming)
        return output

    monkeypatch.setattr(worker, "call_solver", call_solver)
    path = files.save(collinear_balls("three-in-a-row", 3), tmp_path / "three.npz")
    cell = Cell(problem_file=str(path), problem="three-in-a-row", solver="pi-robust",
                formulation="lcp", accuracy=1e-8, mode="cold")
    return worker.CellSolver().solve(cell, limits)


def test_a_cell_is_repeated_until_its_repeats_have_taken_the_budget(
        monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    row = repeats_of_a_cell(monkeypatch, tmp_path, [0.004, 0.005, 0.003, 0.001, 0.001],
                            Limits(timeout_s=10.0, repeats=5, repeat_budget_s=0.01))
    assert row["repeats"] == 3  # 0.004 + 0.005 + 0.003 >= 0.01: the fourth never runs
    assert row["time_s"] == 0.003 and row["time_max_s"] == 0.005
    assert row["success"] is True


def test_without_a_budget_a_cell_gets_every_repeat(monkeypatch: pytest.MonkeyPatch,
                                                   tmp_path) -> None:
    row = repeats_of_a_cell(monkeypatch, tmp_path, [0.004, 0.005, 0.003, 0.001, 0.002],
                            Limits(timeout_s=10.0, repeats=5))
    assert row["repeats"] == 5 and row["time_s"] == 0.001


def test_a_repeat_budget_must_be_positive() -> None:
    with pytest.raises(QpbenchError, match="--repeat-budget must be positive"):
        Limits(repeat_budget_s=0.0)
