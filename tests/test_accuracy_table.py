"""The one accuracy-options table: every solver that can run has its row, so none runs on
defaults nobody chose, and registering one without a row is refused."""

from __future__ import annotations

import pytest

from qpbench.errors import QpbenchError
from qpbench.solvers import accuracy, registry
from qpbench.solvers.base import SolverSpec


@pytest.mark.parametrize("spec", registry.usable_solvers(), ids=lambda spec: spec.key)
def test_every_registered_solver_has_its_row_at_every_level(spec: SolverSpec) -> None:
    assert spec.name in accuracy.OPTIONS
    for level in accuracy.LEVELS:
        options = accuracy.options_for(spec.name, level, scale=2.0)
        assert all(not callable(value) for value in options.values())


def test_a_solver_without_a_row_is_refused_at_registration() -> None:
    def solve(*args: object) -> None:
        raise AssertionError("never called")

    spec = SolverSpec(name="no-row-solver", formulation="lcp", backend="tests", solve=solve)
    with pytest.raises(QpbenchError, match="no row in the accuracy-options table"):
        registry.register(spec)
    assert spec.key not in {s.key for s in registry.all_solvers()}


def test_an_unusable_solver_needs_no_row() -> None:
    registry.register_unusable("absent-solver", ("dual",), "tests", "not installed here")
    try:
        listed = {s.key: s for s in registry.all_solvers()}
        assert listed["absent-solver/dual"].reason == "not installed here"
    finally:
        del registry._SOLVERS["absent-solver/dual"]


def test_options_follow_the_level_as_the_table_says() -> None:
    osqp = accuracy.options_for("osqp", 1e-6, scale=3.0)
    assert osqp["eps_abs"] == pytest.approx(3e-6) and osqp["eps_rel"] == pytest.approx(1e-6)
    assert accuracy.options_for("quadprog", 1e-6) == {}


def test_a_row_overridden_for_one_measurement_is_restored_after() -> None:
    cap = accuracy.OPTIONS["staggered"]["max_outer"]
    with accuracy.overridden("staggered", max_outer=cap + 1):
        assert accuracy.options_for("staggered", 1e-8)["max_outer"] == cap + 1
    assert accuracy.options_for("staggered", 1e-8)["max_outer"] == cap
    with pytest.raises(KeyError, match="no option max_rounds"), \
            accuracy.overridden("staggered", max_rounds=1):
        pass
