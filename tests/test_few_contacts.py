"""The head-to-head's verdict on problems of a few contacts: pi-robust's pair the fastest of
all pairs on every one, problem by problem, each solve's fastest pass counting."""

from __future__ import annotations

from typing import Any

from qpbench.studies.few_contacts import (
    FEW_CONTACTS,
    few_contacts_markdown,
    few_contacts_summary,
)
from qpbench.studies.head_to_head import UNDECIDED


def row(problem: str, solver: str, time_s: float, contacts: int = 3, success: bool = True,
        status: str = "solved", set_name: str = "k3", pass_number: int = 0) -> dict[str, Any]:
    """One head-to-head row (the fields the summary reads)."""
    return {"problem": problem, "set": set_name, "solver": solver, "pass": pass_number,
            "own": solver.startswith("pi-robust"), "contacts": contacts, "status": status,
            "success": success, "time_s": time_s}


def test_pi_robust_fastest_on_every_small_problem_meets_the_target() -> None:
    rows = [row("a", "pi-robust/lcp", 2e-5), row("a", "daqp-native/dual", 4e-5),
            row("b", "pi-robust/lcp", 3e-5), row("b", "siconos-pgs/lcp", 3.3e-5)]
    summary = few_contacts_summary(rows, UNDECIDED)
    assert summary["lowest"] == 2 and summary["target_met"]
    closest = min(summary["problems"], key=lambda entry: entry["ratio"])
    assert closest["problem"] == "b" and closest["external"] == "siconos-pgs/lcp"
    assert abs(closest["ratio"] - 1.1) < 1e-12
    text = few_contacts_markdown(summary)
    assert "2 of 2" in text and "**met**" in text and "`siconos-pgs/lcp` took 1.10x" in text


def test_one_faster_external_pair_fails_the_target_and_is_named() -> None:
    rows = [row("a", "pi-robust/lcp", 2e-5), row("a", "daqp-native/dual", 4e-5),
            row("b", "pi-robust/lcp", 5e-5), row("b", "siconos-pgs/lcp", 2.5e-5)]
    summary = few_contacts_summary(rows, UNDECIDED)
    assert summary["lowest"] == 1 and not summary["target_met"]
    text = few_contacts_markdown(summary)
    assert "1 of 2" in text and "**not met**" in text and "0.50x" in text


def test_each_solve_counts_with_its_fastest_pass() -> None:
    rows = [row("a", "pi-robust/lcp", 5e-5, pass_number=0),
            row("a", "pi-robust/lcp", 2e-5, pass_number=1),
            row("a", "daqp-native/dual", 3e-5, pass_number=0),
            row("a", "daqp-native/dual", 4e-5, pass_number=1)]
    summary = few_contacts_summary(rows, UNDECIDED)
    assert summary["problems"][0]["own_s"] == 2e-5 and summary["target_met"]


def test_a_problem_pi_robust_fails_counts_against_it_and_one_nobody_else_solves_for_it() -> None:
    rows = [row("a", "pi-robust/lcp", 1e-5, success=False, status="failed"),
            row("a", "daqp-native/dual", 4e-5),
            row("b", "pi-robust/lcp", 3e-5),
            row("b", "daqp-native/dual", 1e-5, success=False, status="failed")]
    problems = {entry["problem"]: entry for entry in
                few_contacts_summary(rows, UNDECIDED)["problems"]}
    assert problems["a"]["ratio"] == 0.0 and not problems["a"]["lowest"]
    assert problems["b"]["external"] is None and problems["b"]["lowest"]


def test_larger_problems_unsolved_ones_and_ones_without_a_verdict_are_left_out() -> None:
    rows = [row("big", "pi-robust/lcp", 9e-5, contacts=FEW_CONTACTS + 1),
            row("big", "daqp-native/dual", 1e-5, contacts=FEW_CONTACTS + 1),
            row("ray", "pi-robust/lcp", 9e-5, status=UNDECIDED[0]),
            row("ray", "daqp-native/dual", 1e-5, status=UNDECIDED[0]),
            row("hard", "pi-robust/lcp", 9e-5, success=False, status="failed"),
            row("hard", "daqp-native/dual", 1e-5, success=False, status="failed")]
    assert few_contacts_summary(rows, UNDECIDED) == {}
    assert few_contacts_markdown({}) == ""


def test_a_frictional_problem_counts_once_in_each_formulations_set() -> None:
    rows = [row("f", "pi-robust/ccp", 2e-5, set_name="frictional (ccp)"),
            row("f", "daqp/ccp", 9e-5, set_name="frictional (ccp)"),
            row("f", "pi-robust/staggered", 8e-5, set_name="frictional (coulomb)"),
            row("f", "daqp/staggered", 4e-5, set_name="frictional (coulomb)")]
    summary = few_contacts_summary(rows, UNDECIDED)
    assert [(entry["set"], entry["lowest"]) for entry in summary["problems"]] == [
        ("frictional (ccp)", True), ("frictional (coulomb)", False)]
