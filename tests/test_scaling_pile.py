"""The dense piles of ``qpbench scaling``: most bodies in contact, parts that add up."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from qpbench.cli import main
from qpbench.inner_solvers import choose_by_name
from qpbench.simulation.scaling import PARTS, box_pile, circle_pile, pile_markdown, pile_scaling

CLARABEL = choose_by_name("clarabel/dual")


def test_the_piles_rest_on_the_floor_inside_their_walls() -> None:
    for scene in (circle_pile(400), box_pile(400)):
        bodies = scene.bodies
        assert bodies.count == 400 and scene.gravity is not None and scene.gravity[1] < 0
        assert np.all(bodies.velocities[:, 1] < 0)
        width = scene.plane_points[2, 0]
        reach = 0.5
        assert np.all(bodies.positions[:, 0] - reach <= width)
        assert np.all(bodies.positions[:, 0] >= reach - 1e-2)
        assert np.min(bodies.positions[:, 1]) <= reach  # the bottom row touches the floor
    assert box_pile(4).bodies.has_boxes and not circle_pile(4).bodies.rotates


def test_a_pile_keeps_most_bodies_in_contact_and_its_parts_add_up() -> None:
    report = pile_scaling(CLARABEL, {"circles": (100, 400), "boxes": (100, 400)}, steps=2)
    for kind, entry in report["kinds"].items():
        assert [row["bodies"] for row in entry["rows"]] == [100, 400]
        assert entry["own_ratio"] > 0 and entry["solve_ratio"] > 0
        for row in entry["rows"]:
            assert row["success"] and row["steps"] == 2
            assert all(row[part] >= 0 for part in PARTS)
            assert sum(row[part] for part in PARTS) == pytest.approx(row["wall_s"], rel=1e-9)
            assert row["own_s"] == pytest.approx(
                row["contacts_s"] + row["assembly_s"] + row["integration_s"])
            own = row["contacts_per_body_step_us"] + row["assembly_per_body_step_us"] \
                + row["integration_per_body_step_us"]
            assert row["own_per_body_step_us"] == pytest.approx(own)
            assert row["contacts_per_body"] >= (1.5 if kind == "circles" else 1.0)


def test_a_pile_counts_the_inner_solves_that_miss_the_accuracy_asked() -> None:
    """Every inner solve of a pile is judged by qpbench's residual: answers scaled by 1 + 1e-5
    (usable, far above 1e-8) are counted inaccurate, with their largest residual, and the
    table says so; pi-robust's own answers count none (clarabel/dual's miss 1e-8 on this
    pile)."""
    from qpbench.inner_solvers import chosen
    from qpbench.problem.impact import ImpactProblem
    from qpbench.simulation.operators import ChosenSolve, SolvedImpulses
    from qpbench.solvers.registry import get

    exact = chosen(get("pi-robust/lcp"))

    def nudged(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None
               ) -> SolvedImpulses:
        answer = exact.solve(problem, accuracy, warm_start)
        return SolvedImpulses((1.0 + 1e-5) * answer.impulses, answer.time_s, answer.status)

    def choose_nudged(operator: object) -> ChosenSolve:
        return ChosenSolve("nudged pi-robust/lcp", nudged)

    sizes = {"boxes": (20,)}
    row = pile_scaling(choose_nudged, sizes, steps=2)["kinds"]["boxes"]["rows"][0]
    assert row["success"] and row["inner_solves"] == 2 == row["inaccurate_solves"]
    assert 1e-8 < row["max_residual"] < 1e-3 and row["accuracy"] == 1e-8
    table = pile_markdown(pile_scaling(choose_nudged, sizes, steps=1), "nudged")
    assert "| 1 of 1 |" in table and "the accuracy the simulator asks of it (1e-08)" in table
    row = pile_scaling(choose_by_name("pi-robust/lcp"), sizes, steps=2)["kinds"]["boxes"]["rows"][0]
    assert row["inner_solves"] == 2 and row["inaccurate_solves"] == 0
    assert row["max_residual"] <= 1e-8


def test_scaling_writes_the_piles_beside_the_sparse_boxes(tmp_path: Path) -> None:
    output = tmp_path / "scaling.json"
    assert main(["scaling", "--sizes", "50,200", "--steps", "2", "--pile-steps", "1",
                 "--box-pile-sizes", "20,60", "-o", str(output)]) == 0
    report = json.loads(output.read_text())
    assert [row["balls"] for row in report["rows"]] == [50, 200]  # the existing fields stay
    assert {"ratio", "ratio_without_solves", "meets_target"} <= set(report)
    piles = report["piles"]["kinds"]
    assert piles["circles"]["sizes"] == [50, 200] and piles["boxes"]["sizes"] == [20, 60]
    assert "### Dense piles" in report["markdown"] and "own cost" in report["markdown"]


def test_a_pile_past_its_solve_budget_stops_after_one_step_and_says_so() -> None:
    report = pile_scaling(CLARABEL, {"boxes": (20, 60)}, steps=3, solve_budget_s=1e-9)
    assert report["solve_budget_s"] == 1e-9 and report["warmup_bodies"] == 20
    for row in report["kinds"]["boxes"]["rows"]:
        assert row["success"] and row["steps"] == 1 and row["steps_asked"] == 3
        assert row["stopped_by_solve_budget"] and row["solve_s"] > 0
    text = pile_markdown(report, "clarabel/dual")
    assert "boxes, 60 bodies: 1 of 3 timed steps" in text and "1e-09 s budget" in text
    unlimited = pile_scaling(CLARABEL, {"boxes": (20, 60)}, steps=2)
    assert all(row["steps"] == 2 and not row["stopped_by_solve_budget"]
               for row in unlimited["kinds"]["boxes"]["rows"])
    assert "timed steps; the inner solves took" not in pile_markdown(unlimited, None)


def test_scaling_refuses_a_solve_budget_that_is_not_positive(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture
                                                             ) -> None:
    output = tmp_path / "scaling.json"
    assert main(["scaling", "--sizes", "20,40", "--pile-solve-budget", "0",
                 "-o", str(output)]) == 2
    assert "--pile-solve-budget" in capsys.readouterr().err and not output.exists()
