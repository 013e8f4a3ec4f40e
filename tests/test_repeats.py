"""The fastest of a few repeats, as the head-to-head and the sequence mode time a solve. The
stopwatch is replaced by given times here: no test depends on the clock."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from qpbench.bench import repeats
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
    fastest = repeats.fastest_solve(None, None, 1e-8, repeats=3, warm_start=start)
    assert fastest.time_s == 0.005
    assert len(warm_starts) == 3 and all(warm is start for warm in warm_starts)


def test_a_solve_slower_than_the_repeat_budget_is_not_repeated(
        monkeypatch: pytest.MonkeyPatch) -> None:
    warm_starts = given_times(monkeypatch, [2 * repeats.REPEAT_BUDGET_S, 0.001])
    assert repeats.fastest_solve(None, None, 1e-8, repeats=5).time_s == \
        2 * repeats.REPEAT_BUDGET_S
    assert len(warm_starts) == 1
