"""The commands' text output speaks in words and plain numbers, never in Python reprs."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from qpbench.cli import main
from qpbench.cli.output import plain

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes" / "scisim"
CRADLE = SCENES / "newtons_cradle.xml"
# what a Python repr looks like in text output
REPRS = re.compile(r"\bNone\b|\bTrue\b|\bFalse\b|\bnan\b|[\[\]{}]|np\.|array\(")


def test_plain_values() -> None:
    assert plain(None) == "none" and plain(math.nan, "not measured") == "not measured"
    assert plain(True) == "yes" and plain(np.bool_(False)) == "no"
    assert plain(0.031095824) == "0.0311" and plain(np.float64(2.0)) == "2"
    assert plain(3.1e-5, seconds=True) == "31 us" and plain(0.0123, seconds=True) == "12.3 ms"
    assert plain(["ipopt/dual", "pgs/lcp"]) == "ipopt/dual, pgs/lcp" and plain([]) == "none"
    assert plain({"step": 3, "reason": "diverged"}) == "step 3; reason diverged"


def test_simulate_prints_no_python_reprs(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", str(CRADLE), "--steps", "2000", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "solvers: ipopt/dual" in text and "success: yes" in text
    assert not REPRS.search(text), text


def test_solve_says_in_one_line_why_it_exits_1(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """Projected Gauss-Seidel cannot reach 1e-10 on masses over twelve decades in its
    iterations: exit 1, and stderr says which pair missed which level, by what residual."""
    assert main(["generate", "mass-ratio", "--size", "10", "--seed", "101", "--no-reference",
                 "-o", str(tmp_path)]) == 0
    (problem,) = tmp_path.glob("*.npz")
    capsys.readouterr()
    assert main(["solve", str(problem), "--solver", "pgs", "--accuracy", "1e-10"]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1
    assert error.startswith(f"qpbench solve: {problem}: pgs/lcp missed the accuracy asked "
                            "(1e-10): status ")
    assert not REPRS.search(error.split("residual")[-1])


@pytest.mark.parametrize("solver", ["highs/dual", "cvxpy-highs/dual", "highs-native/dual"])
def test_solve_json_is_json_through_every_route_to_highs(solver: str, tmp_path: Path) -> None:
    """A process's first HiGHS object prints a banner on standard output; each pair that
    reaches HiGHS makes that object silenced in its set-up, so --json stays one JSON object."""
    assert main(["generate", "k3", "--no-reference", "-o", str(tmp_path)]) == 0
    (problem,) = tmp_path.glob("*.npz")
    done = subprocess.run([sys.executable, "-m", "qpbench.cli", "solve", str(problem),
                           "--solver", solver, "--json"], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["solver"] == solver
