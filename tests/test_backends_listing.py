"""``qpbench solvers`` lists every backend and formulation, its version, and why not."""

from __future__ import annotations

import json

import pytest

from qpbench.cli import main
from qpbench.solvers import accuracy


def listing(capsys: pytest.CaptureFixture[str]) -> list[dict]:
    assert main(["solvers", "--json"]) == 0
    return json.loads(capsys.readouterr().out)["solvers"]


def test_at_least_twenty_usable_backend_pairs_with_versions(
        capsys: pytest.CaptureFixture[str]) -> None:
    rows = listing(capsys)
    assert all(set(row) == {"name", "formulation", "backend", "version", "usable", "reason"}
               for row in rows)
    backends = [row for row in rows if row["backend"] in ("qpsolvers", "cvxpy", "cyipopt")]
    usable = [row for row in backends if row["usable"]]
    assert len(usable) >= 20
    assert {"ipopt/dual", "ipopt/primal", "cvxpy-ipopt/dual"} <= {
        f"{row['name']}/{row['formulation']}" for row in usable}
    assert all(row["version"] for row in usable)
    assert all(row["reason"] for row in backends if not row["usable"])


def test_every_usable_backend_has_a_row_in_the_accuracy_table(
        capsys: pytest.CaptureFixture[str]) -> None:
    names = {row["name"] for row in listing(capsys)
             if row["usable"] and row["backend"] in ("qpsolvers", "cvxpy", "cyipopt")}
    assert names <= set(accuracy.OPTIONS)
    for name in names:  # every level maps to options without error
        for level in accuracy.LEVELS:
            accuracy.options_for(name, level, scale=3.0)


def test_regularization_is_a_named_variant_not_a_silent_option() -> None:
    regularized = {name for name, row in accuracy.OPTIONS.items() if "regularization" in row}
    assert regularized == {"quadprog-reg", "ecos-reg"}


def test_c_level_output_is_silenced_and_stdout_restored(
        capfd: pytest.CaptureFixture[str]) -> None:
    import os

    from qpbench.solvers.qpsolvers_ import c_stdout_silenced

    with c_stdout_silenced(), c_stdout_silenced():
        os.write(1, b"from C\n")
    os.write(1, b"after\n")
    assert capfd.readouterr().out == "after\n"
