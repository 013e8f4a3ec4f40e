"""``qpbench solvers`` lists every backend and formulation, its version, and why not."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from qpbench.cli import main
from qpbench.solvers import accuracy


def listing(capsys: pytest.CaptureFixture[str]) -> list[dict]:
    assert main(["solvers", "--json"]) == 0
    return json.loads(capsys.readouterr().out)["solvers"]


def test_at_least_twenty_usable_backend_pairs_with_versions(
        capsys: pytest.CaptureFixture[str]) -> None:
    rows = listing(capsys)
    assert all(set(row) == {"name", "formulation", "backend", "version", "usable", "reason",
                            "kinds"} for row in rows)
    backends = [row for row in rows if row["backend"] in ("qpsolvers", "cvxpy", "cyipopt")]
    usable = [row for row in backends if row["usable"]]
    assert len(usable) >= 20
    assert {"ipopt/dual", "ipopt/primal", "cvxpy-ipopt/dual"} <= {
        f"{row['name']}/{row['formulation']}" for row in usable}
    assert all(row["version"] for row in usable)
    assert all(row["reason"] for row in backends if not row["usable"])


def test_regularization_is_a_named_variant_not_a_silent_option() -> None:
    regularized = {name for name, row in accuracy.OPTIONS.items() if "regularization" in row}
    assert regularized == {"quadprog-reg", "ecos-reg"}


def test_c_level_output_is_silenced_and_stdout_restored(
        capfd: pytest.CaptureFixture[str]) -> None:
    import os

    from qpbench.solvers.quiet import c_stdout_silenced

    with c_stdout_silenced(), c_stdout_silenced():
        os.write(1, b"from C\n")
    os.write(1, b"after\n")
    assert capfd.readouterr().out == "after\n"


MISSING_QPSOLVERS = """
import json, sys
sys.modules["qpsolvers"] = None  # as if the package were not installed
from qpbench.solvers.registry import all_solvers
print(json.dumps({s.key: [s.usable, s.reason] for s in all_solvers()}))
"""


def test_a_missing_backend_package_drops_out_alone_and_says_why() -> None:
    """Without qpsolvers, its solvers (the -reg variants too) are listed as unusable with
    the import error, and every other family, IPOPT and cvxpy included, still runs."""
    listed = json.loads(subprocess.run([sys.executable, "-c", MISSING_QPSOLVERS], check=True,
                                       capture_output=True, text=True).stdout)
    for key in ("osqp/dual", "daqp/primal", "quadprog-reg/dual", "ecos-reg/dual"):
        usable, reason = listed[key]
        assert not usable and reason.startswith("import failed"), key
    for key in ("ipopt/dual", "ipopt/primal", "cvxpy-clarabel/dual", "pi-robust/lcp"):
        assert listed[key] == [True, ""], key
