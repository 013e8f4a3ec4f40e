"""Warm mode: the warm start is what a simulator carried into the step, never the reference;
and only the solver call is timed. The capture of a SCISim scene reads ../shared beside the
repository (marked ``shared``, skipped when it is missing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bench_problems import collinear_balls

from qpbench.bench.worker import timer_overhead_s, warm_start_for
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem
from qpbench.studies import sequence

# SCISim's ball2d test scenes in ../shared beside the repository
SHARED = Path(__file__).resolve().parents[2] / "shared/scisim/assets/ball2d/tests_st"


def test_warm_start_prefers_the_previous_impulses_stored_with_the_problem() -> None:
    problem = collinear_balls("row4", 4)
    previous = np.full(problem.n_contacts, 0.25)
    problem.data["warm_start"] = previous
    warm_start, source = warm_start_for(problem)
    assert source == "previous" and np.array_equal(warm_start, previous)


def test_the_reference_is_never_a_warm_start() -> None:
    """A problem with a verified reference but no carried impulses is solved cold: a solver
    never sees anything derived from the answer it is judged against."""
    problem = collinear_balls("row4", 4)
    assert problem.reference is not None and problem.reference.verified
    assert warm_start_for(problem) == (None, "none")


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason=f"needs ../shared beside the repository: {SHARED}")
def test_a_capture_from_shared_of_a_scene_that_caches_impulses_carries_them_into_warm_mode(
        tmp_path: Path) -> None:
    """Balls settling in a rough wedge (SCISim's ``cache_impulses="normal_and_friction"``):
    every captured problem carries the impulses (l_N, l_T) the simulator carried into its
    step, zero for contacts that are new, and warm mode starts from exactly those."""
    paths = sequence.capture(SHARED / "balls_in_wedge.xml", tmp_path, 8)
    problems = [files.load(path) for path in paths]
    assert len(problems) == 8 and all(isinstance(p, FrictionalProblem) for p in problems)
    starts = []
    for problem in problems:
        warm_start, source = warm_start_for(problem)
        assert source == "previous" and warm_start.shape == (2 * problem.n_contacts,)
        np.testing.assert_array_equal(warm_start, problem.data["warm_start"])
        assert problem.blind_copy().data == {}  # the solver itself never sees stored data
        starts.append(warm_start)
    assert any(start[0] > 0 for start in starts)  # a ball in contact one step before


def test_timer_overhead_is_positive_and_far_below_a_millisecond() -> None:
    overhead = timer_overhead_s(samples=200)
    assert 0 < overhead < 1e-4
