"""Shifted geometric means, the time-scale shift, charged failures and performance profiles."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from qpbench.bench import stats


def _frame(rows: list[tuple[str, str, float, bool]], limit: float = 60.0) -> pd.DataFrame:
    """(problem, solver, time_s, success) rows of one formulation at one level; the solver
    named ``ours`` has qpbench's own backend."""
    return pd.DataFrame([
        {"problem": problem, "solver": solver, "formulation": "dual", "accuracy": 1e-8,
         "backend": stats.OWN_BACKEND if solver == "ours" else "external",
         "time_s": time_s, "success": success, "time_limit_s": limit, "status":
         "solved" if success else "inaccurate", "residual": 1e-9 if success else 1e-3,
         "v_error": 1e-9 if success else 1e-3, "claimed_success": True}
        for problem, solver, time_s, success in rows
    ])


def test_shifted_geometric_mean_formula() -> None:
    assert stats.shifted_geometric_mean([2.0, 8.0], shift=0.0) == pytest.approx(4.0)
    # exp(mean(log(t + s))) - s with t = (1e-6, 1e-2), s = 1e-3
    expected = math.sqrt((1e-6 + 1e-3) * (1e-2 + 1e-3)) - 1e-3
    assert stats.shifted_geometric_mean([1e-6, 1e-2], shift=1e-3) == pytest.approx(expected)
    assert math.isnan(stats.shifted_geometric_mean([], shift=1.0))


def test_shift_is_ten_times_the_median_fastest_time_and_failures_are_charged_the_limit() -> None:
    frame = _frame([("p1", "a", 1e-5, True), ("p1", "b", 4e-5, True),
                    ("p2", "a", 3e-5, True), ("p2", "b", 2e-5, False),
                    ("p3", "a", 5e-5, True), ("p3", "b", 9e-5, True)], limit=2.0)
    # fastest successful per problem: 1e-5, 3e-5, 5e-5 -> median 3e-5
    assert stats.time_scale_shift(frame) == pytest.approx(3e-4)
    charged = stats.charged_times(frame)
    assert list(charged) == [1e-5, 4e-5, 3e-5, 2.0, 5e-5, 9e-5]


def test_performance_profile_counts_problems_within_tau_of_the_fastest() -> None:
    frame = _frame([("p1", "a", 1.0, True), ("p1", "b", 2.0, True),
                    ("p2", "a", 5.0, False), ("p2", "b", 1.0, True),
                    ("p3", "a", 1.0, False), ("p3", "b", 1.0, False)])  # p3: nobody, dropped
    ratios = stats.performance_ratios(frame)
    assert list(ratios.index) == ["p1", "p2"]
    assert ratios.loc["p1", "a/dual"] == 1.0 and ratios.loc["p1", "b/dual"] == 2.0
    assert np.isinf(ratios.loc["p2", "a/dual"]) and ratios.loc["p2", "b/dual"] == 1.0
    profile = stats.performance_profile(frame, taus=np.array([1.0, 1.5, 2.0, 1e6]))
    assert list(profile["a/dual"]) == [0.5, 0.5, 0.5, 0.5]
    assert list(profile["b/dual"]) == [0.5, 0.5, 1.0, 1.0]


def test_cost_of_accuracy_is_the_ratio_of_consecutive_levels() -> None:
    loose = _frame([("p1", "a", 1.0, True), ("p2", "a", 1.0, True)]).assign(accuracy=1e-4)
    tight = _frame([("p1", "a", 4.0, True), ("p2", "a", 4.0, True)]).assign(accuracy=1e-8)
    table = stats.cost_of_accuracy(pd.concat([loose, tight], ignore_index=True), shift=0.0)
    assert table.loc["a/dual", "SGM @ 1e-04"] == pytest.approx(1.0)
    assert table.loc["a/dual", "1e-04 -> 1e-08"] == pytest.approx(4.0)


def test_paired_cost_of_accuracy_ignores_problems_failed_at_either_level() -> None:
    loose = _frame([("p1", "a", 1.0, True), ("p2", "a", 1.0, False),
                    ("p3", "a", 2.0, True)]).assign(accuracy=1e-4)
    tight = _frame([("p1", "a", 3.0, True), ("p2", "a", 9.0, True),
                    ("p3", "a", 10.0, True)]).assign(accuracy=1e-8)
    table = stats.paired_cost_of_accuracy(pd.concat([loose, tight], ignore_index=True))
    # p2 failed at 1e-4, so only p1 (ratio 3) and p3 (ratio 5) count: median 4
    assert table.loc["a/dual", "1e-04 -> 1e-08"] == pytest.approx(4.0)


def test_honesty_counts_claims_that_disagree_with_the_verdict() -> None:
    frame = _frame([("p1", "a", 1.0, True), ("p2", "a", 1.0, False),  # both claim success
                    ("p1", "ours", 1.0, True)])
    table = stats.honesty(frame).set_index("solver")
    assert table.loc["a/dual", "honesty_rate"] == 0.5
    assert table.loc["a/dual", "false_success_claims"] == 1
    # a solver written here stops on qpbench's residual: marked, its 100% is by construction
    assert table.loc["ours/dual", "ours"] == "ours" and table.loc["a/dual", "ours"] == ""
