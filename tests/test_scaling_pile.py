"""The dense piles of ``qpbench scaling``: most bodies in contact, parts that add up."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from qpbench.cli import main
from qpbench.inner_solvers import choose_by_name
from qpbench.problem.impact import ImpactProblem
from qpbench.simulation import scaling as scaling_module
from qpbench.simulation.scaling import (
    FACTORIZATION_TARGET,
    PARTS,
    SOLVE_GROWTH_TARGET,
    box_pile,
    circle_pile,
    final_block_fields,
    pile_markdown,
    pile_scaling,
)
from qpbench.studies.factorization import active_block_factorization

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
    for entry in piles.values():  # the command sets every pile against one factorization
        assert all(row["factorization_s"] > 0 for row in entry["rows"])
    assert "inner solves per step / factorization" in report["markdown"]


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


def test_passes_keep_each_sizes_least_disturbed_run_and_show_every_pass() -> None:
    """Each pass simulates every size (in reverse order every other pass); a size keeps the
    pass whose inner solves per body per step took least, the table says so, and the kind's
    line gives the growth of each pass alone."""
    told: list[str | None] = []
    report = pile_scaling(CLARABEL, {"boxes": (20, 40)}, steps=1, passes=3,
                          progress=lambda count, note: told.append(note))
    assert report["passes"] == 3
    assert told == ["boxes pile warm-up, 20 bodies"] + [
        f"boxes pile, {bodies} bodies, pass {turn} of 3"
        for turn, order in ((1, (20, 40)), (2, (40, 20)), (3, (20, 40))) for bodies in order]
    entry = report["kinds"]["boxes"]
    small, large = entry["rows"]
    for row in entry["rows"]:
        assert row["passes"] == 3 and len(row["solve_per_body_step_us_by_pass"]) == 3
        assert row["solve_per_body_step_us"] == min(row["solve_per_body_step_us_by_pass"])
    assert entry["solve_ratio_by_pass"] == pytest.approx(
        [b / a for a, b in zip(small["solve_per_body_step_us_by_pass"],
                               large["solve_per_body_step_us_by_pass"], strict=True)])
    text = pile_markdown(report, "clarabel/dual")
    assert "every pile simulated in 3 passes" in text
    ratios = entry["solve_ratio_by_pass"]
    assert f", pass by pass {min(ratios):.2f}-{max(ratios):.2f}x." in text
    single = pile_scaling(CLARABEL, {"boxes": (20, 40)}, steps=1)
    assert single["passes"] == 1 and len(single["kinds"]["boxes"]["solve_ratio_by_pass"]) == 1
    assert "passes" not in pile_markdown(single, None)


def test_a_pass_whose_solver_failed_is_kept_over_faster_ones(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Passes pick the least disturbed run, but never hide a failure: a size with a failed pass
    keeps it, however fast the others were."""
    runs = iter([(True, 5.0), (False, 9.0), (True, 4.0)])

    def timed(*_: object) -> tuple[dict[str, Any], None]:
        success, seconds = next(runs)
        return {"success": success, "solve_per_body_step_us": seconds}, None

    monkeypatch.setattr(scaling_module, "measure_pile", timed)
    [(row, _)] = scaling_module._fastest_passes("boxes", (20,), 1, CLARABEL, 1.0, 3,
                                                lambda count, note: None)
    assert not row["success"] and row["solve_per_body_step_us"] == 9.0
    assert row["solve_per_body_step_us_by_pass"] == [5.0, 9.0, 4.0] and row["passes"] == 3


def test_scaling_refuses_a_pass_count_below_one(tmp_path: Path,
                                               capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "scaling.json"
    assert main(["scaling", "--sizes", "20,40", "--pile-passes", "0", "-o", str(output)]) == 2
    assert "--pile-passes" in capsys.readouterr().err and not output.exists()


def test_scaling_refuses_a_solve_budget_that_is_not_positive(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture
                                                             ) -> None:
    output = tmp_path / "scaling.json"
    assert main(["scaling", "--sizes", "20,40", "--pile-solve-budget", "0",
                 "-o", str(output)]) == 2
    assert "--pile-solve-budget" in capsys.readouterr().err and not output.exists()


def test_a_pile_sets_its_inner_solves_against_one_factorization_of_its_final_active_block(
        ) -> None:
    """Each row times one sparse factorization of the last step's active block (CHOLMOD and
    SuperLU, the faster named) and divides the inner solves per step by it; per kind the
    largest ratio is held against 3x, and the table and the kind's line show the figures."""
    pi_robust = choose_by_name("pi-robust")
    report = pile_scaling(pi_robust, {"circles": (30, 60), "boxes": (20, 40)}, steps=2,
                          factor_block=active_block_factorization)
    assert report["factorization_target"] == FACTORIZATION_TARGET == 3.0
    text = pile_markdown(report, "pi-robust")
    for entry in report["kinds"].values():
        for row in entry["rows"]:
            assert row["success"] and row["steps"] == 2
            # a pressed pile keeps contacts active; the block stores its whole diagonal
            assert 0 < row["active_contacts"] <= row["active_nonzeros"]
            by_method = row["factorization_s_by_method"]
            assert set(by_method) >= {"SuperLU/MMD_AT_PLUS_A"}
            assert row["factorization_s"] == min(by_method.values()) > 0
            assert by_method[row["factorization_method"]] == row["factorization_s"]
            assert row["factorization_library"] == row["factorization_method"].split("/")[0]
            assert row["solve_per_step_s"] == pytest.approx(row["solve_s"] / row["steps"])
            assert row["solve_to_factorization"] == pytest.approx(
                row["solve_per_step_s"] / row["factorization_s"])
            assert (f"| {row['active_contacts']} | {1e3 * row['factorization_s']:.2f} "
                    f"({row['factorization_library']}) "
                    f"| {row['solve_to_factorization']:.2f}x |") in text
        largest = max(row["solve_to_factorization"] for row in entry["rows"])
        assert entry["max_solve_to_factorization"] == largest
        assert entry["meets_factorization_target"] == (largest <= 3.0)
        verdict = "meets" if entry["meets_factorization_target"] else "misses"
        small, large = entry["rows"]
        assert (f"{small['solve_to_factorization']:.2f}x at {small['bodies']}, "
                f"{large['solve_to_factorization']:.2f}x at {large['bodies']} bodies** "
                f"({verdict} the target <= 3x)") in text
        growth = ((large["factorization_s"] / large["bodies"])
                  / (small["factorization_s"] / small["bodies"]))
        assert (f"One factorization itself, per body, grows {growth:.2f}x from "
                f"{small['bodies']} to {large['bodies']} bodies.") in text
    assert "final active block (the contacts F with l > 0" in text


def test_a_kinds_inner_solves_growth_is_held_against_2x() -> None:
    """The inner solves per body per step, largest pile over the smallest, against the
    near-linear target; a report kept before that target was measured shows no verdict."""
    report = pile_scaling(CLARABEL, {"boxes": (20, 40)}, steps=1)
    assert report["solve_growth_target"] == SOLVE_GROWTH_TARGET == 2.0
    entry = report["kinds"]["boxes"]
    assert entry["meets_solve_growth_target"] == (entry["solve_ratio"] <= 2.0)
    verdict = "meets" if entry["meets_solve_growth_target"] else "misses"
    assert (f"inner solves **{entry['solve_ratio']:.2f}x** ({verdict} the target <= 2x)."
            in pile_markdown(report, "clarabel/dual"))
    for kind_entry in report["kinds"].values():  # as an older scaling.json holds it
        del kind_entry["meets_solve_growth_target"]
    del report["solve_growth_target"]
    assert f"inner solves **{entry['solve_ratio']:.2f}x**." in pile_markdown(report, None)


def test_a_pile_without_a_factorization_shows_dashes_and_no_verdict() -> None:
    report = pile_scaling(CLARABEL, {"boxes": (20, 40)}, steps=1)
    assert "factorization_target" not in report
    row = report["kinds"]["boxes"]["rows"][0]
    assert "factorization_s" not in row and "solve_to_factorization" not in row
    text = pile_markdown(report, "clarabel/dual")
    assert "| - | - | - |" in text and "against one factorization" not in text


def test_an_empty_final_active_block_has_no_factorization_and_no_ratio() -> None:
    """A last answer with l = 0 everywhere leaves F empty: no factorization time, no ratio,
    and the kind misses the target; a pile with no step done has no factorization either."""
    def nothing_active(problem: ImpactProblem, impulses: np.ndarray) -> dict[str, Any]:
        return active_block_factorization(problem, np.zeros_like(impulses))

    report = pile_scaling(choose_by_name("pi-robust"), {"boxes": (20,)}, steps=1,
                          factor_block=nothing_active)
    entry = report["kinds"]["boxes"]
    row = entry["rows"][0]
    assert row["active_contacts"] == 0 and row["factorization_s"] is None
    assert row["factorization_library"] is None and row["solve_to_factorization"] is None
    assert set(row["factorization_s_by_method"].values()) == {None}
    assert entry["max_solve_to_factorization"] is None
    assert not entry["meets_factorization_target"]
    text = pile_markdown(report, "pi-robust")
    assert "| 0 | - | - |" in text and "**none at 20 bodies** (misses" in text
    fields = final_block_fields(None, 0.5, active_block_factorization)
    assert fields["factorization_s"] is None and fields["solve_to_factorization"] is None
