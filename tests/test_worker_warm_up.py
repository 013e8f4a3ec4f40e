"""No level is charged a cold start: before the first timed solve of a (problem, solver,
formulation) a worker solves that problem once untimed, and throws the answer away."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from bench_problems import exact_impulses, write_tiny_problems

from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec


class RecordingCellSolver(CellSolver):
    """A CellSolver whose only solver is ``test-recorder/lcp``, which writes every call into
    ``log`` beside the worker's own begin/end announcements. Its first answer is all zeros
    (wrong on any problem with an approaching contact), every later one exact."""

    def __init__(self) -> None:
        self.log: list[tuple[Any, ...]] = []
        super().__init__(announce=self._heard)
        self.recorder = SolverSpec(name="test-recorder", formulation="lcp", backend="tests",
                                   solve=self._solve, version="0")

    def _heard(self, message: dict[str, Any]) -> None:
        if message["event"] == "load":  # setting a cell up, no solver call
            return
        which = "warm-up" if message.get("warm_up") else message.get("repeat")
        self.log.append((message["event"], which))

    def _solve(self, problem: ImpactProblem, accuracy: float,
               warm_start: np.ndarray | None = None) -> SolverOutput:
        first = not any(entry[0] == "solve" for entry in self.log)
        self.log.append(("solve", accuracy))
        if first:
            return SolverOutput(impulses=np.zeros(problem.n_contacts), status="zeros",
                                claimed_success=True, iterations=99)
        return SolverOutput(impulses=exact_impulses(problem), status="exact",
                            claimed_success=True, iterations=1)

    def spec(self, key: str) -> SolverSpec:
        return self.recorder


def test_a_worker_warms_up_once_per_problem_and_solver_before_the_timed_levels(
        tmp_path: Path) -> None:
    row3, row4 = write_tiny_problems(tmp_path, count=2)
    worker = RecordingCellSolver()
    limits = Limits(repeats=2)
    rows = [worker.solve(Cell(str(path), path.stem, "test-recorder", "lcp", level, "cold"),
                         limits)
            for path in (row3, row4) for level in (1e-4, 1e-8)]

    def timed(level: float) -> list[tuple[Any, ...]]:
        return [("begin", 0), ("solve", level), ("end", 0),
                ("begin", 1), ("solve", level), ("end", 1)]

    warm_up = [("begin", "warm-up"), ("solve", 1e-4), ("end", "warm-up")]
    assert worker.log == [*warm_up, *timed(1e-4), *timed(1e-8),  # row3
                          *warm_up, *timed(1e-4), *timed(1e-8)]  # row4: a new problem

    # the warm-up's answer (zeros, 99 iterations) is in no row: each row judges its own
    # first timed answer and counts only the timed repeats
    for row in rows:
        assert row["status"] == "solved" and row["solver_status"] == "exact"
        assert row["iterations"] == 1 and row["repeats"] == 2


def test_a_batch_warms_each_problem_and_solver_up_once_before_any_timed_solve(
        tmp_path: Path) -> None:
    """The same four cells as one batch: both warm-ups (each at its problem's first level)
    come first, then the timed solves, interleaved (tests/test_timing_protocol.py checks
    their order in full)."""
    row3, row4 = write_tiny_problems(tmp_path, count=2)
    worker = RecordingCellSolver()
    cells = [Cell(str(path), path.stem, "test-recorder", "lcp", level, "cold")
             for path in (row3, row4) for level in (1e-4, 1e-8)]
    rows = dict(worker.solve_batch(cells, Limits(repeats=2)))
    warm_up = [("begin", "warm-up"), ("solve", 1e-4), ("end", "warm-up")]
    assert worker.log[:6] == [*warm_up, *warm_up]
    assert ("begin", "warm-up") not in worker.log[6:]
    assert sum(entry == ("begin", 0) for entry in worker.log) == 4  # every cell's first
    assert sum(entry == ("begin", 1) for entry in worker.log) == 4  # and second repeat
    for row in rows.values():
        assert row["status"] == "solved" and row["solver_status"] == "exact"
        assert row["iterations"] == 1 and row["repeats"] == 2
