"""The breakdown of pi-robust's time: its parts are what they say they are."""

from __future__ import annotations

from qpbench.problem.generate import generate
from qpbench.studies import breakdown


def test_the_compiled_calls_time_is_measured_inside_the_instrumented_solve() -> None:
    """On a problem the compiled kernel solves, the kernel's part is the time of its call as
    pi-robust makes it: positive, within the instrumented solve's own time, and no Python path
    ran."""
    problem = generate("grid", 5, seed=0)[0]
    trivial = generate("cradle", 2, seed=0)[0]
    row = breakdown.measure(problem, trivial, repeats=2)
    assert row["success"] and row["compiled"]
    assert 0.0 < row["kernel_s"] <= row["instrumented_total_s"]
    assert row["python_path_s"] == 0.0
    assert row["kernel_back_to_back_s"] > 0.0
