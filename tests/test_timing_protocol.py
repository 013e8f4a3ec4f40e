"""The timing protocol (docs/design.md section 7): no solver is timed on repeats of one problem
back to back. A fake solver records the order in which a worker's batch, the head-to-head
and the schedule itself make their solves; no test reads the clock."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_problems import collinear_balls, exact_impulses, write_tiny_problems

from qpbench.bench import repeats, schedule
from qpbench.bench.schedule import Schedule
from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.studies import head_to_head

PAIRS = ("test-first/lcp", "test-second/lcp")
LEVELS = (1e-4, 1e-8)


class RecordingWorker(CellSolver):
    """A CellSolver whose solvers (``PAIRS``) answer exactly and record every call as
    (problem, pair, accuracy, timed), timed being whether the worker announced it as a
    timed repeat (not its warm-up)."""

    def __init__(self) -> None:
        self.solves: list[tuple[str, str, float, bool]] = []
        self.announced_timed = False
        super().__init__(announce=self._heard)
        self.fakes = {key: SolverSpec(name=key.split("/")[0], formulation="lcp",
                                      backend="tests", solve=self._solver(key), version="0")
                      for key in PAIRS}

    def _heard(self, message: dict[str, Any]) -> None:
        if message["event"] == "begin":
            self.announced_timed = not message.get("warm_up")

    def _solver(self, key: str):  # noqa: ANN202
        def solve(problem: ImpactProblem, accuracy: float,
                  warm_start: np.ndarray | None = None) -> SolverOutput:
            self.solves.append((problem.name, key, accuracy, self.announced_timed))
            return SolverOutput(impulses=exact_impulses(problem), status="exact",
                                claimed_success=True)
        return solve

    def spec(self, key: str) -> SolverSpec:
        return self.fakes[key]


@pytest.fixture
def batch(tmp_path: Path) -> list[Cell]:
    """Two problems x two pairs x two levels, problem-major as the runner lists cells."""
    paths = write_tiny_problems(tmp_path, count=2)
    return [Cell(str(path), path.stem, *key.split("/"), level, "cold")
            for path in paths for key in PAIRS for level in LEVELS]


def unit(solve: tuple[str, str, float, bool]) -> tuple[str, str]:
    return solve[0], solve[1]


def test_no_two_consecutive_timed_calls_of_a_batch_share_a_problem_and_pair(
        batch: list[Cell]) -> None:
    worker = RecordingWorker()
    rows = dict(worker.solve_batch(batch, Limits(repeats=3)))
    timed = [solve for solve in worker.solves if solve[3]]
    assert all(unit(one) != unit(two) for one, two in zip(timed, timed[1:], strict=False))
    # every cell got its three repeats, and its row says so
    for cell in batch:
        assert sum(solve[:3] == (cell.problem, cell.solver_key, cell.accuracy)
                   for solve in timed) == 3
    assert sorted(rows) == list(range(len(batch)))
    assert all(row["repeats"] == 3 and row["status"] == "solved" for row in rows.values())


def test_each_pair_warms_up_once_per_problem_before_any_timed_call(batch: list[Cell]) -> None:
    worker = RecordingWorker()
    list(worker.solve_batch(batch, Limits(repeats=3)))
    warm_ups = [solve for solve in worker.solves if not solve[3]]
    # one per (problem, pair), at its first level, all before the first timed call: no
    # warm-up falls between timed repeats, where it would refresh one pair's caches alone
    assert sorted(unit(solve) for solve in warm_ups) == sorted(
        {(cell.problem, cell.solver_key) for cell in batch})
    assert all(solve[2] == LEVELS[0] for solve in warm_ups)
    assert worker.solves[:len(warm_ups)] == warm_ups
    # and no pair's first timed call follows its own warm-up directly
    first_timed = worker.solves[len(warm_ups)]
    assert unit(first_timed) != unit(warm_ups[-1])


def test_the_rounds_are_rotated(batch: list[Cell]) -> None:
    worker = RecordingWorker()
    list(worker.solve_batch(batch, Limits(repeats=3)))
    timed = [solve[:3] for solve in worker.solves if solve[3]]
    rounds = [timed[k * len(batch):(k + 1) * len(batch)] for k in range(3)]
    assert all(sorted(one) == sorted(batch_keys(batch)) for one in rounds)  # each cell once
    firsts = [unit((*one[0], True)) for one in rounds]
    assert len(set(firsts)) == 3  # each round starts with another (problem, pair)
    assert rounds[0] != rounds[1] != rounds[2]


def batch_keys(batch: list[Cell]) -> list[tuple[str, str, float]]:
    return [(cell.problem, cell.solver_key, cell.accuracy) for cell in batch]


def test_a_cell_past_its_repeat_budget_leaves_the_later_rounds(
        batch: list[Cell], monkeypatch: pytest.MonkeyPatch) -> None:
    """With a budget every timed call exhausts, each cell is timed once: the budget ends a
    cell's repeats, not the batch's."""
    worker = RecordingWorker()
    rows = dict(worker.solve_batch(batch, Limits(repeats=5, repeat_budget_s=1e-12)))
    assert sum(solve[3] for solve in worker.solves) == len(batch)
    assert all(row["repeats"] == 1 for row in rows.values())


def test_the_schedule_keeps_units_apart_across_round_boundaries() -> None:
    items = [(problem, pair, level) for problem in "PQR" for pair in "ab" for level in (1, 2, 3)]
    order = Schedule(items, 4, unit=lambda item: item[:2], warm_up=True)
    calls = list(order)
    assert all(one.item[:2] != two.item[:2] for one, two in zip(calls, calls[1:], strict=False))
    assert [call.round for call in calls] == sorted(call.round for call in calls)
    assert sum(not call.timed for call in calls) == 6  # one warm-up per unit
    assert all(sum(call.item == item and call.timed for call in calls) == 4 for item in items)


def test_a_schedule_of_one_unit_has_nothing_to_put_between_its_repeats() -> None:
    calls = list(Schedule(["only"], 3, unit=lambda item: "unit"))
    assert [(call.item, call.round) for call in calls] == [("only", 1), ("only", 2), ("only", 3)]


def test_the_cold_variant_flushes_the_caches_once_before_each_timed_call_outside_the_clock(
        monkeypatch: pytest.MonkeyPatch) -> None:
    events: list[str] = []
    in_call: list[bool] = [False]

    def call_solver(spec, problem, accuracy, warm_start=None) -> SolverOutput:  # noqa: ANN001
        in_call[0] = True  # the stopwatch runs inside call_solver
        events.append(f"solve {problem.name} {spec.key}")
        output = SolverOutput(impulses=exact_impulses(problem), status="exact",
                              claimed_success=True)
        output.time_s = 1e-6
        in_call[0] = False
        return output

    def flush() -> None:
        assert not in_call[0]
        events.append("flush")

    monkeypatch.setattr(repeats, "call_solver", call_solver)
    monkeypatch.setattr(schedule, "flush_caches", flush)
    monkeypatch.setattr(repeats, "flush_caches", flush)
    problems = [collinear_balls("row3", 3), collinear_balls("row4", 4)]
    specs = [SolverSpec(name=name, formulation="lcp", backend=backend, solve=lambda *a: None,
                        version="0") for name, backend in (("pi-robust", "qpbench"),
                                                           ("daqp", "qpsolvers"))]
    pairs = [(spec, problem) for problem in problems for spec in specs]
    rows = head_to_head.measure_batch(pairs, repeats=4, cold_repeats=2)
    warm_ups = len(pairs)
    timed = events[warm_ups:]
    assert "flush" not in events[:warm_ups]  # the untimed warm-ups flush nothing
    flushed = [timed[number + 1] for number, event in enumerate(timed) if event == "flush"]
    assert len(flushed) == 2 * len(pairs)  # one flush per cold timed call, each right before
    assert all(event.startswith("solve") for event in flushed)
    assert sum(event.startswith("solve") for event in timed) == (4 + 2) * len(pairs)
    for row in rows:
        assert row["time_s"] == row["time_cold_cache_s"] == 1e-6
    solves = [event for event in events if event.startswith("solve")][warm_ups:]
    assert all(one != two for one, two in zip(solves, solves[1:], strict=False))


def test_the_cold_figure_sits_beside_the_interleaved_one_in_a_sets_summary() -> None:
    rows = [{"problem": name, "set": "box packings", "solver": solver, "pass": 0,
             "own": solver == "pi-robust/lcp", "contacts": 10, "status": "solved",
             "success": True, "residual": 0.0, "iterations": 1, "outer_iterations": None,
             "time_s": warm, "time_cold_cache_s": cold}
            for name in ("a", "b")
            for solver, warm, cold in (("pi-robust/lcp", 1e-5, 4e-5), ("daqp/dual", 5e-5, 8e-5))]
    [entry] = head_to_head.summarize(rows)
    assert entry["speedup"] == pytest.approx(5.0)
    assert entry["cold_cache"]["speedup"] == pytest.approx(2.0)
    assert "| 2.00x |" in head_to_head.markdown([entry], 4, cold_repeats=2)
