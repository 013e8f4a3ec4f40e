"""What a test does with a failure that qpbench/solvers/defects.toml describes: it checks the
failure is the one the row says, then marks the test an expected failure (never a silent
pass, never a skip)."""

from __future__ import annotations

from typing import Any, NoReturn

import pytest

from qpbench.solvers.defects import Defect


def expect_described(defect: Defect, row: dict[str, Any], status: str) -> NoReturn:
    """Asserts that the judged ``row`` fails as ``defect`` says (a wrong claim of success, no
    claim, or an inaccurate answer; ``status`` is the solver's own words, for the message),
    then ends the test as an expected failure naming the defect."""
    as_described = {
        "wrong-claim": row["claimed_success"] is True and row["status_honest"] is False,
        "fails": row["claimed_success"] is False,
        "inaccurate": True,
    }[defect.effect]
    assert as_described, f"{row['solver']}/{row['formulation']} goes wrong otherwise than the " \
        f"defects table says ({defect.effect}): {status}"
    pytest.xfail(f"known defect of {defect.package} {defect.versions}: {defect.what}")
