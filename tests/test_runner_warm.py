"""Warm mode: where the warm start comes from, and that only the solver call is timed."""

from __future__ import annotations

import numpy as np
from bench_problems import collinear_balls

from qpbench.bench.worker import timer_overhead_s, warm_start_for


def test_warm_start_prefers_the_previous_impulses_stored_with_the_problem() -> None:
    problem = collinear_balls("row4", 4)
    previous = np.full(problem.n_contacts, 0.25)
    problem.data["warm_start"] = previous
    warm_start, source = warm_start_for(problem)
    assert source == "previous" and np.array_equal(warm_start, previous)


def test_otherwise_the_reference_perturbed_by_one_percent_seeded_by_the_name() -> None:
    problem = collinear_balls("row4", 4)
    warm_start, source = warm_start_for(problem)
    reference = problem.reference.impulses
    assert source == "perturbed-reference"
    assert np.all(warm_start >= 0)
    assert np.allclose(warm_start, reference, rtol=0.1, atol=0)  # ~1% noise, a few sigma
    assert not np.array_equal(warm_start, reference)
    again, _ = warm_start_for(collinear_balls("row4", 4))
    assert np.array_equal(again, warm_start)  # deterministic


def test_without_either_the_warm_cell_is_a_cold_start() -> None:
    problem = collinear_balls("row3", 3)
    problem.reference = None
    assert warm_start_for(problem) == (None, "none")


def test_timer_overhead_is_positive_and_far_below_a_millisecond() -> None:
    overhead = timer_overhead_s(samples=200)
    assert 0 < overhead < 1e-4
