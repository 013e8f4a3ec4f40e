"""The commands' text output speaks in words and plain numbers, never in Python reprs."""

from __future__ import annotations

import math
import re
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
