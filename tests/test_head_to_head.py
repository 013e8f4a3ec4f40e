"""``qpbench head-to-head``: the external pairs come from the main table's measurements, and
each set's speedup is the fastest external SGM over pi-robust's. Correctness only."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from qpbench.bench import repeats as repeats_module
from qpbench.bench.problem_sets import read_set
from qpbench.cli import main
from qpbench.problem import files
from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.problem.reduced import ReducedFrictionalProblem
from qpbench.scenes.builders import scene_xml
from qpbench.simulation.scaling import box_pile, circle_pile
from qpbench.solvers.registry import get
from qpbench.studies import head_to_head, head_to_head_pairs, head_to_head_sets

ROOT = Path(__file__).resolve().parents[1]


def bench_rows(solver: str, backend: str, family: str, times: list[float],
               kind: str = "", formulation: str = "dual") -> list[dict]:
    return [{"problem": f"p{i}", "family": family, "solver": solver, "formulation": formulation,
             "backend": backend, "accuracy": 1e-8, "success": True, "time_s": time,
             "time_limit_s": 10.0, "kind": kind} for i, time in enumerate(times)]


def test_the_candidates_are_the_fastest_external_pairs_of_the_main_table() -> None:
    frame = pd.DataFrame(
        bench_rows("slow", "x", "grid", [3e-3, 4e-3])
        + bench_rows("fast", "y", "grid", [1e-4, 2e-4])
        + bench_rows("pi-robust", "qpbench", "grid", [1e-5, 1e-5])  # ours: never a candidate
        + bench_rows("other", "z", "k3", [1e-6, 1e-6])  # not a candidate family
        + bench_rows("fric", "y", "incline", [1e-3], kind="frictional", formulation="ccp"))
    chosen = head_to_head_pairs.fastest_external(frame, candidates=2, accuracy=1e-8)
    assert chosen["impact"] == ["fast/dual", "slow/dual"]
    assert chosen["frictional"] == ["fric/ccp"]


def test_a_reduced_frictional_problems_pairs_are_frictional_candidates() -> None:
    """Siconos' flows reduced to their contacts are of kind ``frictional-reduced`` in the
    table: their pairs are chosen per law as the other frictional problems', never as impact
    pairs."""
    frame = pd.DataFrame(
        bench_rows("fast", "y", "grid", [1e-4])
        + bench_rows("osqp", "qpsolvers", "siconos", [2e-3], kind="frictional-reduced",
                     formulation="staggered")
        + bench_rows("osqp", "qpsolvers", "siconos", [1e-3], kind="frictional-reduced",
                     formulation="ccp"))
    chosen = head_to_head_pairs.fastest_external(frame, candidates=3, accuracy=1e-8)
    assert chosen["frictional"] == ["osqp/staggered", "osqp/ccp"]
    assert chosen["impact"] == ["fast/dual"]


def test_each_candidate_familys_fastest_pair_is_a_candidate_too() -> None:
    frame = pd.DataFrame(
        bench_rows("fast", "x", "grid", [1e-4, 1e-4]) + bench_rows("fast", "x", "dump", [2e-4])
        + bench_rows("second", "y", "grid", [2e-4, 2e-4]) + bench_rows("second", "y", "dump",
                                                                        [3e-4])
        # slowest over both families, yet the fastest on the dumps
        + bench_rows("dumps", "z", "grid", [9e-3, 9e-3]) + bench_rows("dumps", "z", "dump",
                                                                       [1e-4]))
    chosen = head_to_head_pairs.fastest_external(frame, candidates=1, accuracy=1e-8)
    # the fastest overall first, then each family's FAMILY_CANDIDATES fastest not chosen yet
    assert chosen["impact"][0] == "fast/dual"
    assert set(chosen["impact"]) == {"fast/dual", "second/dual", "dumps/dual"}
    assert head_to_head_pairs.FAMILY_CANDIDATES == 3


def test_the_frictional_candidates_are_the_fastest_of_each_model_and_formulation() -> None:
    """Siconos' fc2d solvers, NSGS and the LCP solve Coulomb's law as staggered projections do:
    the fastest of them all is a candidate, then each formulation's fastest; ccp pairs are
    ranked apart (Anitescu's relaxation is another law)."""
    def frictional(solver: str, formulation: str, time: float) -> list[dict]:
        return bench_rows(solver, "x", "incline", [time, time], kind="frictional",
                          formulation=formulation)

    frame = pd.DataFrame(
        frictional("siconos-cpg", "fc2d", 1e-4) + frictional("siconos-nsgs", "fc2d", 2e-4)
        + frictional("daqp", "staggered", 9e-4) + frictional("piqp", "staggered", 5e-4)
        + frictional("daqp", "ccp", 3e-4) + frictional("osqp", "ccp", 4e-3))
    chosen = head_to_head_pairs.fastest_external(frame, candidates=3, accuracy=1e-8)
    # coulomb: the fastest over fc2d and staggered, then staggered's fastest; then ccp's
    assert chosen["frictional"] == ["siconos-cpg/fc2d", "piqp/staggered", "daqp/ccp"]


def row(solver: str, own: bool, problem: str, time: float, success: bool = True) -> dict:
    return {"problem": problem, "set": "box packings 1k-4k", "solver": solver, "own": own,
            "contacts": 10, "status": "solved" if success else "failed", "success": success,
            "residual": 0.0, "time_s": time}


def test_a_sets_speedup_is_the_fastest_external_sgm_over_pi_robusts() -> None:
    rows = [row("pi-robust/lcp", True, "a", 1e-4), row("pi-robust/lcp", True, "b", 1e-4),
            row("daqp/dual", False, "a", 4e-4), row("daqp/dual", False, "b", 4e-4),
            row("osqp/dual", False, "a", 1e-5, False), row("osqp/dual", False, "b", 5e-4, False)]
    [entry] = head_to_head.summarize(rows)
    # osqp fails quickly, but failures are charged the set's largest time (5e-4): daqp is the
    # fastest external pair
    assert entry["external"]["solver"] == "daqp/dual"
    assert entry["speedup"] == pytest.approx(4.0)
    assert entry["target_met"]
    assert "| box packings 1k-4k | 2 |" in head_to_head.markdown([entry], 5)


def test_the_report_names_options_tuned_on_a_sets_own_problems() -> None:
    rows = [row("pi-robust/lcp", True, "a", 1e-4), row("daqp/dual", False, "a", 4e-4)]
    [entry] = head_to_head.summarize(rows)
    assert "chosen while looking" not in head_to_head.markdown([entry], 5)  # box packings
    [entry] = head_to_head.summarize([{**one, "set": "fork 5x5 grid dumps"} for one in rows])
    assert "rho, start_sweeps, backup_steps and pi_budget were swept on these dumps" in \
        head_to_head.markdown([entry], 5)


def test_the_per_problem_column_shows_the_median_and_the_least_lead() -> None:
    """Over two problems the median is their mean; the least per-problem ratio shows the
    problem where pi-robust's lead is smallest (here none at all)."""
    rows = [row("pi-robust/lcp", True, "even", 1e-3), row("daqp/dual", False, "even", 1e-3),
            row("pi-robust/lcp", True, "far", 1e-4), row("daqp/dual", False, "far", 1.9e-3)]
    [entry] = head_to_head.summarize(rows)
    assert entry["median_problem_speedup"] == pytest.approx(10.0)  # (1 + 19) / 2
    assert entry["least_problem_speedup"] == pytest.approx(1.0)
    assert "| 10.00x (1.00x) |" in head_to_head.markdown([entry], 5)


def test_the_target_needs_every_problem_the_external_pair_solves() -> None:
    """A problem neither pair solves is charged to both and named; one that only the external
    pair solves keeps the target from holding, however fast pi-robust is elsewhere."""
    easy = [f"a{i}" for i in range(4)]
    rows = [row("pi-robust/lcp", True, name, 1e-5) for name in easy] \
        + [row("daqp/dual", False, name, 1e-3) for name in easy] \
        + [row("pi-robust/lcp", True, "b", 2e-3, False), row("daqp/dual", False, "b", 2e-3, False)]
    [entry] = head_to_head.summarize(rows)
    assert entry["speedup"] > 3 and entry["target_met"] and entry["unsolved_by_both"] == ["b"]
    assert entry["median_problem_speedup"] == pytest.approx(100.0)  # a0-a3: 1e-3 / 1e-5
    assert entry["least_problem_speedup"] == pytest.approx(100.0)
    assert "solved by neither `pi-robust/lcp` nor `daqp/dual`" in head_to_head.markdown(
        [entry], 5)
    rows[-1] = row("daqp/dual", False, "b", 1.9e-3)
    [entry] = head_to_head.summarize(rows)
    assert entry["speedup"] > 3 and not entry["target_met"] and entry["unsolved_by_both"] == []


def lifted_by_failures() -> list[dict]:
    """pi-robust as fast as daqp on three problems; daqp fails a fourth, charged the set's
    largest time (1), which alone lifts the speedup over 3x."""
    rows = [row(solver, own, name, 1e-3) for name in ("a", "b", "c")
            for solver, own in (("pi-robust/lcp", True), ("daqp/dual", False))]
    return rows + [row("pi-robust/lcp", True, "d", 1e-3), row("daqp/dual", False, "d", 1.0,
                                                                False)]


def test_a_speedup_lifted_over_the_target_by_the_peers_failures_is_not_met() -> None:
    [entry] = head_to_head.summarize(lifted_by_failures())
    assert entry["speedup"] > 3 and entry["common_speedup"] == pytest.approx(1.0)
    assert entry["met_by_failures"] and not entry["target_met"]
    text = head_to_head.markdown([entry], 5)
    assert "| not met (peer failures) |" in text
    assert "only because `daqp/dual` failed 25% of the problems" in text
    assert "it is 1.00x" in text


def test_a_peer_that_solves_nothing_meets_no_target_for_pi_robust() -> None:
    rows = [row("pi-robust/lcp", True, name, 1e-3) for name in "ab"] \
        + [row("daqp/dual", False, name, 1.0, False) for name in "ab"]
    [entry] = head_to_head.summarize(rows)
    assert entry["speedup"] > 3 and math.isnan(entry["common_speedup"])
    assert entry["met_by_failures"] and not entry["target_met"]
    assert "no problem did both solve" in head_to_head.markdown([entry], 5)


def test_an_earlier_runs_rows_are_summarized_again_without_timing(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A run's JSON whose summary an older rule wrote (target met) is summarized again from
    its rows; nothing is solved, and the pairs that had left a set stay out of it."""
    rows = lifted_by_failures() + [row("osqp/dual", False, "a", 1e-2)]
    earlier = {"repeats": 5, "rows": rows, "markdown": "old", "summary": [
        {"set": "box packings 1k-4k", "target_met": True, "out_of_running": [
            {"solver": "osqp/dual", "problems": 1, "slower": 10.0, "than": "daqp/dual"}]}]}
    path = tmp_path / "h2h.json"
    path.write_text(json.dumps(earlier))
    assert main(["head-to-head", "--summarize-again", str(path), "-o", str(path)]) == 0
    [entry] = json.loads(path.read_text())["summary"]
    assert entry["met_by_failures"] and not entry["target_met"]
    assert [pair["solver"] for pair in entry["pairs"]] == ["pi-robust/lcp", "daqp/dual"]
    assert "not met (peer failures)" in capsys.readouterr().out


@pytest.mark.parametrize("text", ["{", "[]", '{"rows": [], "summary": [], "repeats": 5}'])
def test_a_file_that_is_no_head_to_head_run_is_one_line(tmp_path: Path, text: str,
                                                       capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "h2h.json"
    path.write_text(text)
    code = main(["head-to-head", "--summarize-again", str(path), "-o", str(tmp_path / "o.json")])
    err = capsys.readouterr().err
    assert code != 0 and str(path) in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o.json").exists()


def test_timing_needs_a_folder_and_a_table(tmp_path: Path, capsys: pytest.CaptureFixture
                                           ) -> None:
    code = main(["head-to-head", "-o", str(tmp_path / "o.json")])
    assert code != 0 and "--results are needed" in capsys.readouterr().err


def test_a_frictional_problems_set_is_the_law_its_pairs_formulation_solves() -> None:
    from friction_cases import pair_on_floor

    problem = pair_on_floor(mu=0.5)
    for formulation in ("staggered", "fc2d", "nsgs", "lcp"):
        assert head_to_head.set_of(problem, formulation) == "frictional (coulomb)"
    assert head_to_head.set_of(problem, "ccp") == "frictional (ccp)"
    problem.normal.family, problem.normal.name = "siconos", "gfc2d_granularflowonwall_00069_00350"
    assert head_to_head.set_of(problem, "fc2d") == "Siconos granular (coulomb)"
    assert head_to_head.set_of(problem, "ccp") == "Siconos granular (ccp)"


def test_a_siconos_flow_given_reduced_to_its_contacts_has_sets_of_its_own() -> None:
    W = np.array([[2.0, 0.5], [0.5, 1.0]])
    flow = ReducedFrictionalProblem.from_local("fc2d_granularflowonwall_00667_00000", W,
                                               np.array([-1.0, 0.2]), np.array([0.5]),
                                               family="siconos")
    assert head_to_head.set_of(flow, "staggered") == "Siconos granular, reduced (coulomb)"
    assert head_to_head.set_of(flow, "ccp") == "Siconos granular, reduced (ccp)"
    assert {"Siconos granular, reduced (coulomb)",
            "Siconos granular, reduced (ccp)"} <= set(head_to_head.SETS)


def test_a_capture_of_any_7x7_grid_scene_is_in_the_7x7_set() -> None:
    problem = generate("k3", None, seed=0)[0]
    for scene in ("grid7_itr_0", "grid7_itr_31"):
        problem.family = f"scene:{scene}"
        assert head_to_head.set_of(problem) == "fork 7x7 grid scenes"
    problem.family = "scene:grid5_itr_0"
    assert head_to_head.set_of(problem) == "grid scene captures"


def test_a_dump_is_in_the_grid_dump_set_a_k3_in_the_k3_set_and_a_k4_scene_in_none() -> None:
    assert head_to_head.set_of(import_dump(ROOT / "problems/dumps/grid5_itr_0.out")) \
        == "fork 5x5 grid dumps"
    problem = generate("k3", None, seed=0)[0]
    assert head_to_head.set_of(problem) == "k3"
    problem.family = "scene:K4"
    assert head_to_head.set_of(problem) is None


def test_a_grid_or_box_packings_set_is_its_size_bucket() -> None:
    """Grids and box packings are compared per size bucket; a size in no bucket is a set of its
    own, named by its size."""
    assert head_to_head.set_of(generate("grid", 4, seed=3)[0]) == "grids 4-9"
    assert head_to_head.set_of(generate("grid", 12, seed=3)[0]) == "grids 10-14"
    assert head_to_head.set_of(generate("grid", 25, seed=3)[0]) == "grids 25"
    assert head_to_head_sets.size_bucket("box", 1_000) == "box packings 1k-4k"
    assert head_to_head_sets.size_bucket("box", 16_000) == "box packings 8k-16k"
    assert head_to_head_sets.size_bucket("box", 100) == "box packings 100"
    assert head_to_head_sets.larger_buckets("grids 10-14") == ["grids 16-20", "grids 30-40"]
    assert head_to_head_sets.larger_buckets("box packings 8k-16k") == []


def test_the_head_to_heads_piles_are_the_scaling_studys_piles() -> None:
    """The head-to-head's piles are the scaling study's piles of 1,000 bodies
    (``problems/head_to_head.toml``) and of 10,000 (``head_to_head_large.toml``, `make
    bench-large`), each captured with pi-robust as inner solver; the 1,000-body ones are
    committed as scene files too, written as the generator makes them."""
    for scene in (circle_pile(1000), box_pile(1000)):
        committed = ROOT / "problems/scenes/piles" / scene.path
        assert committed.read_text(encoding="utf-8") == scene_xml(scene)
    for set_file, bodies in (("head_to_head.toml", 1000), ("head_to_head_large.toml", 10000)):
        piles = read_set(ROOT / "problems" / set_file)["piles"]
        assert [(pile["kind"], pile["bodies"], pile["solver"]) for pile in piles] == [
            ("circles", bodies, "pi-robust"), ("boxes", bodies, "pi-robust")]


def test_the_impacts_of_a_dense_pile_are_in_the_set_of_its_bodies() -> None:
    """A pile scene's impacts (family ``scene:circle_pile_N`` or ``scene:box_pile_N``) are
    compared per bucket of bodies, circles and boxes together; the resting pile of the
    sequence mode is no set of the table's buckets, and a scene merely named like a pile
    ends elsewhere."""
    problem = generate("k3", None, seed=0)[0]
    for family, expected in (("scene:circle_pile_1000", "dense piles 1k"),
                             ("scene:box_pile_1000", "dense piles 1k"),
                             ("scene:box_pile_10000", "dense piles 10k"),
                             ("scene:circle_pile_30", "dense piles 30"),
                             ("scene:circle_pile_1000_x", None),
                             ("scene:ball_pile_1000", None)):
        problem.family = family
        assert head_to_head.set_of(problem) == expected, family
    assert head_to_head_sets.larger_buckets("dense piles 1k") == ["dense piles 10k"]
    piles = [name for name in head_to_head_sets.SETS if name.startswith("dense piles")]
    assert piles == ["dense piles 1k", "dense piles 10k"]
    assert head_to_head_sets.SETS.index("box packings 8k-16k") + 1 \
        == head_to_head_sets.SETS.index("dense piles 1k")


def test_the_command_measures_a_folder_against_the_named_table(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture
                                                               ) -> None:
    folder = tmp_path / "problems"
    folder.mkdir()
    files.save(import_dump(ROOT / "problems/dumps/grid5_itr_0.out"), folder / "grid5.npz")
    table = tmp_path / "bench.parquet"
    pd.DataFrame(bench_rows("daqp", "daqp", "dump", [1e-4])).to_parquet(table)
    out = tmp_path / "h2h.json"
    assert main(["head-to-head", str(folder), "--results", str(table), "--repeats", "1",
                 "--passes", "2", "-o", str(out)]) == 0
    assert "fork 5x5 grid dumps" in capsys.readouterr().out
    rows = json.loads(out.read_text())["rows"]
    assert sorted((row["solver"], row["pass"]) for row in rows) == [
        ("daqp/dual", 0), ("daqp/dual", 1), ("pi-robust/lcp", 0), ("pi-robust/lcp", 1)]


def test_a_solve_past_the_memory_cap_fails_alone_and_the_run_goes_on(tmp_path: Path) -> None:
    """Under ``--memory-limit`` (headroom above the loaded process), a dense backend's solve
    that needs more (Q of 10,051 contacts as a dense array: 808 MB) fails with MemoryError;
    pi-robust's sparse solve of the same problem goes on, and so does the run."""
    folder = tmp_path / "problems"
    folder.mkdir()
    files.save(generate("box", 10_000, seed=0)[0], folder / "box-10000-s0.npz")
    table = tmp_path / "bench.parquet"
    pd.DataFrame(bench_rows("daqp-native", "daqp", "box", [1e-3])).to_parquet(table)
    out = tmp_path / "h2h.json"
    done = subprocess.run(
        [sys.executable, "-m", "qpbench.cli", "head-to-head", str(folder), "--results",
         str(table), "--repeats", "1", "--passes", "1", "--cold-repeats", "0",
         "--memory-limit", "400", "-o", str(out)],
        capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    rows = {row["solver"]: row for row in json.loads(out.read_text())["rows"]}
    assert rows["pi-robust/lcp"]["success"]
    refused = rows["daqp-native/dual"]
    assert refused["status"] == "failed" and refused["residual"] is None  # no answer at all


def test_a_missing_folder_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = main(["head-to-head", str(tmp_path / "nothing"), "--results", "x.parquet",
                 "-o", str(tmp_path / "h.json")])
    assert code != 0 and "no such problem folder" in capsys.readouterr().err
    assert not (tmp_path / "h.json").exists()


@pytest.mark.parametrize("limit", ["0.5", "nan"])
def test_an_out_of_running_limit_below_one_is_one_line(tmp_path: Path, limit: str,
                                                       capsys: pytest.CaptureFixture) -> None:
    code = main(["head-to-head", str(tmp_path), "--results", "x.parquet",
                 "--out-of-running", limit, "-o", str(tmp_path / "h.json")])
    err = capsys.readouterr().err
    assert code != 0 and "--out-of-running must be at least 1" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "h.json").exists()


def test_a_table_without_times_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture
                                           ) -> None:
    folder = tmp_path / "problems"
    folder.mkdir()
    table = tmp_path / "bench.parquet"
    pd.DataFrame(bench_rows("daqp", "daqp", "dump", [1e-4])).drop(columns="time_s").to_parquet(
        table)
    code = main(["head-to-head", str(folder), "--results", str(table),
                 "-o", str(tmp_path / "h.json")])
    assert code != 0 and "no column time_s" in capsys.readouterr().err
    assert not (tmp_path / "h.json").exists()


def test_staggered_pairs_run_to_the_head_to_heads_round_cap(tmp_path: Path) -> None:
    """rough-box-30 needs about 1,700 staggered rounds at 1e-8, more than the accuracy table's
    cap: in the head-to-head every staggered pair may run STAGGERED_MAX_OUTER rounds, and the
    table is itself again afterwards."""
    from qpbench.problem.friction_generate import generate as generate_frictional
    from qpbench.solvers import accuracy

    table_cap = accuracy.OPTIONS["staggered"]["max_outer"]
    assert table_cap < 1_700 <= head_to_head.STAGGERED_MAX_OUTER
    folder = tmp_path / "problems"
    folder.mkdir()
    files.save(generate_frictional("rough-box", seed=0)[0], folder / "rough-box.npz")
    bench = pd.DataFrame(bench_rows("daqp", "daqp", "dump", [1e-4]))  # no frictional pair
    result = head_to_head.head_to_head(folder, bench, repeats=1, passes=1)
    [staggered] = [row for row in result["rows"] if row["solver"] == "pi-robust/staggered"]
    assert staggered["success"] and staggered["outer_iterations"] > table_cap
    assert accuracy.OPTIONS["staggered"]["max_outer"] == table_cap
    assert f"up to {head_to_head.STAGGERED_MAX_OUTER} rounds" in result["markdown"]


def test_the_target_sentence_names_what_holds_and_what_does_not() -> None:
    sentence = head_to_head.target_sentence
    assert sentence(3, ["a", "b"], [], "scene") == "The 3x target holds on every scene: a, b."
    assert sentence(3, [], ["a"], "set") == "The 3x target holds on no set; it does not hold on: a."
    assert sentence(3, ["a"], ["b"], "set") == \
        "The 3x target holds on: a; it does not hold on: b."


def test_a_set_without_a_verdict_is_never_counted_as_holding() -> None:
    """A set where one side was not measured (no external pair ran there) has no verdict:
    with no verdict anywhere the sentence says so, and "every" means every set."""
    sentence = head_to_head.target_sentence
    assert sentence(3, [], [], "set", ["c"]) == \
        "No set has a verdict on the 3x target; no verdict (one side not measured) on: c."
    assert sentence(3, ["a"], [], "set", ["c"]) == (
        "The 3x target holds on every set with a verdict: a; no verdict (one side not "
        "measured) on: c.")
    assert "every" not in sentence(3, [], [], "set")


def test_the_table_keeps_each_problems_fastest_pass_and_every_pass_must_meet_the_target(
        ) -> None:
    """Two passes: pi-robust ran in a slow stretch in the second. The table (each problem's
    fastest over the passes) shows 4x, but the second pass alone gives 2.5x, and the target
    needs every pass."""
    rows = []
    for number, (own_time, daqp_time) in enumerate(((1e-4, 4e-4), (2e-4, 5e-4))):
        rows += [{**row("pi-robust/lcp", True, name, own_time), "pass": number} for name in "ab"]
        rows += [{**row("daqp/dual", False, name, daqp_time), "pass": number} for name in "ab"]
    [entry] = head_to_head.summarize(rows)
    assert entry["speedup"] == pytest.approx(4.0)
    assert entry["pass_speedups"] == pytest.approx([4.0, 2.5])
    assert not entry["target_met"]
    text = head_to_head.markdown([entry], 5, passes=2)
    assert "in each of 2 passes" in text and "| 4.00x | 2.50-4.00x |" in text
    [first_pass] = head_to_head.summarize([one for one in rows if one["pass"] == 0])
    assert "pass_speedups" not in first_pass and first_pass["target_met"]
    # a pass without the external pair gives no speedup (NaN), and the target fails with it
    [entry] = head_to_head.summarize([one for one in rows if one["pass"] == 0 or one["own"]])
    assert entry["speedup"] == pytest.approx(4.0) and not entry["target_met"]


def test_a_pair_far_slower_than_the_fastest_external_one_leaves_the_set() -> None:
    """After two problems daqp has taken 31x osqp's time: it is measured no further on the set,
    and the set's figures compare the pairs that ran on all of it."""
    running = head_to_head.Running(limit=30.0)
    rows = [row("pi-robust/lcp", True, "a", 1e-5), row("osqp/dual", False, "a", 1e-3),
            row("daqp/dual", False, "a", 2e-2)]
    running.update(rows, "box packings 1k-4k")
    assert running.running("box packings 1k-4k", "daqp/dual")  # 20x: still in the running
    rows += [row("pi-robust/lcp", True, "b", 1e-5), row("osqp/dual", False, "b", 1e-3),
             row("daqp/dual", False, "b", 4.2e-2)]
    running.update(rows, "box packings 1k-4k")
    assert not running.running("box packings 1k-4k", "daqp/dual")
    assert running.running("box packings 1k-4k", "osqp/dual")
    assert running.running("fork 5x5 grid dumps", "daqp/dual")  # another set: still in it
    assert running.out["box packings 1k-4k"]["daqp/dual"] == {
        "problems": 2, "slower": pytest.approx(31.0), "than": "osqp/dual"}
    [entry] = head_to_head.summarize(rows, running.out)
    assert [pair["solver"] for pair in entry["pairs"]] == ["pi-robust/lcp", "osqp/dual"]
    assert entry["out_of_running"] == [{"solver": "daqp/dual", "problems": 2,
                                        "slower": pytest.approx(31.0), "than": "osqp/dual"}]
    text = head_to_head.markdown([entry], 5)
    assert "`daqp/dual` measured no further after 2 problems (31.0x `osqp/dual`'s time there)" \
        in text
    assert "more than 30 times those of the fastest external pair that solved every problem" \
        in text


def test_a_pair_with_a_solve_past_the_cap_leaves_once_another_solved_within_it() -> None:
    """daqp's dense factorization took 15 s on the first pile (17x piqp's 0.87 s: within the
    running limit); past the cap of 10 s it leaves the set and the larger bucket, and the
    report says why. A pair past the cap sets no pace."""
    def pile(solver: str, own: bool, time: float, over_cap: bool = False) -> dict:
        return {**row(solver, own, "pile", time), "set": "dense piles 1k", "over_cap": over_cap}

    running = head_to_head.Running(limit=30.0, cap_s=10.0)
    rows = [pile("pi-robust/lcp", True, 0.05), pile("piqp-native/dual", False, 0.87),
            pile("daqp-native/dual", False, 15.0, over_cap=True)]
    running.update(rows, "dense piles 1k")
    left = {"problems": 1, "slower": pytest.approx(15.0 / 0.87), "than": "piqp-native/dual",
            "longest_s": 15.0, "cap_s": 10.0}
    assert running.out["dense piles 1k"] == {"daqp-native/dual": left}
    assert running.out["dense piles 10k"] == {"daqp-native/dual": {
        **left, "measured_on": "dense piles 1k"}}
    [entry] = head_to_head.summarize(rows, running.out)
    text = head_to_head.markdown([entry], 5, solve_cap_s=10.0)
    assert ("`daqp-native/dual` measured no further after 1 problem (a solve took 15.0 s, past "
            "the cap of 10 s; 17.2x `piqp-native/dual`'s time there)") in text
    assert "untimed warm-up took more than 10 s (the main table's time limit)" in text
    assert "untimed warm-up took more than" not in head_to_head.markdown([entry], 5)
    # every external pair past the cap: none is the pace, so none leaves
    alone = head_to_head.Running(limit=30.0, cap_s=10.0)
    alone.update([pile("piqp-native/dual", False, 11.0, over_cap=True),
                  pile("daqp-native/dual", False, 15.0, over_cap=True)], "dense piles 1k")
    assert alone.out == {}


def test_a_solve_past_the_cap_is_timed_once_and_its_row_says_so(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """measure_batch on a pile-sized problem: the pair whose warm-up passed the cap keeps that
    one solve (judged as any other) and no cold time; the other pair is timed in full."""
    problem = generate("k3", None, seed=0)[0]
    slow, fast = get("lemke/lcp"), get("pi-robust/lcp")
    real_call_solver = repeats_module.call_solver

    def call_solver(spec, solved, accuracy, warm_start=None):
        output = real_call_solver(spec, solved, accuracy, warm_start)
        if spec is slow:
            output.time_s = 12.0
        return output

    monkeypatch.setattr(repeats_module, "call_solver", call_solver)
    slow_row, fast_row = head_to_head.measure_batch([(slow, problem), (fast, problem)],
                                                    repeats=3, cold_repeats=2, cap_s=10.0)
    assert slow_row["over_cap"] and slow_row["time_s"] == 12.0 and slow_row["success"]
    assert math.isnan(slow_row["time_cold_cache_s"])
    assert not fast_row["over_cap"] and fast_row["success"]
    assert fast_row["time_cold_cache_s"] >= 0


def test_no_pair_leaves_while_no_external_pair_has_solved_every_problem() -> None:
    """A pair that fails fast sets no pace: daqp stays however slow it is against it; once
    daqp is the only one to have solved every problem, the failing pair is measured against
    daqp instead (and is not slower)."""
    running = head_to_head.Running(limit=30.0)
    rows = [row("osqp/dual", False, "a", 1e-5, success=False), row("daqp/dual", False, "a", 1e-5,
                                                                   success=False)]
    running.update(rows, "box packings 1k-4k")
    rows += [row("osqp/dual", False, "b", 1e-5, success=False), row("daqp/dual", False, "b", 1.0)]
    running.update(rows, "box packings 1k-4k")
    assert running.out == {}
    # a problem without a solution is solved by no pair and counts for none
    frictional = [{**row("daqp/ccp", False, name, 1e-5), "set": "frictional (ccp)"}
                  for name in "ab"] + [{**row("piqp/ccp", False, name, 1e-3),
                                        "set": "frictional (ccp)"} for name in "ab"]
    for one in frictional[::2]:
        one.update(status=head_to_head.NO_SOLUTION, success=False)
    running.update(frictional, "frictional (ccp)")
    assert running.out["frictional (ccp)"]["piqp/ccp"]["problems"] == 1
    # so does a problem whose residual floor is above the level: below-floor decides nothing
    for one in frictional[::2]:
        one.update(status=head_to_head.BELOW_FLOOR)
    below = head_to_head.Running(limit=30.0)
    below.update(frictional, "frictional (ccp)")
    assert below.out["frictional (ccp)"]["piqp/ccp"]["problems"] == 1


def test_a_pair_far_slower_than_one_that_solved_all_it_solved_leaves_though_none_solved_all(
        ) -> None:
    """No pair solves problem c; quadprog solves a and b fast, proxqp only a and slowly: it
    leaves against quadprog. daqp solved b, which proxqp did not: proxqp is no pace for it,
    but quadprog is (and daqp is not 30x slower)."""
    running = head_to_head.Running(limit=30.0)
    rows = [row("quadprog/primal", False, "a", 1e-3), row("quadprog/primal", False, "b", 1e-3),
            row("quadprog/primal", False, "c", 1e-3, False),
            row("proxqp/dual", False, "a", 0.1), row("proxqp/dual", False, "b", 0.1, False),
            row("proxqp/dual", False, "c", 0.1, False),
            row("daqp/dual", False, "a", 1e-2, False), row("daqp/dual", False, "b", 1e-2),
            row("daqp/dual", False, "c", 1e-2, False)]
    running.update(rows, "box packings 1k-4k")
    assert running.out["box packings 1k-4k"] == {"proxqp/dual": {
        "problems": 3, "slower": pytest.approx(100.0), "than": "quadprog/primal"}}


def test_a_solve_past_the_cap_on_a_problem_without_a_solution_takes_its_pair_out() -> None:
    """A solve over the cap counts on a problem that no pair can be judged on (below its
    residual floor) as anywhere: time is time."""
    running = head_to_head.Running(limit=30.0, cap_s=10.0)
    rows = [row("quadprog/primal", False, "a", 1e-3), row("proxqp/dual", False, "a", 1e-3),
            {**row("quadprog/primal", False, "floor", 1e-3, False),
             "status": head_to_head.BELOW_FLOOR},
            {**row("proxqp/dual", False, "floor", 25.0, False), "status": head_to_head.BELOW_FLOOR,
             "over_cap": True}]
    running.update(rows, "box packings 1k-4k")
    left = running.out["box packings 1k-4k"]["proxqp/dual"]
    assert left["longest_s"] == 25.0 and left["than"] == "quadprog/primal"
    assert running.running("box packings 1k-4k", "quadprog/primal")


def three_dumps_and_a_table(tmp_path: Path) -> tuple[Path, pd.DataFrame]:
    """A folder of three of the fork's dumps, and a main table in which daqp and osqp solved
    the dump family (daqp twice as fast)."""
    folder = tmp_path / "problems"
    folder.mkdir()
    for name in ("grid5_itr_0", "grid5_itr_1", "ok_itr_0"):
        files.save(import_dump(ROOT / f"problems/dumps/{name}.out"), folder / f"{name}.npz")
    return folder, pd.DataFrame(bench_rows("daqp", "daqp", "dump", [1e-4])
                                + bench_rows("osqp", "osqp", "dump", [2e-4]))


def test_a_pair_that_left_a_set_runs_there_in_no_later_pass(monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path) -> None:
    """The measuring loop asks the field before every solve: the slow pair's rows stop after
    the problem where it left, in this pass and the next, while its rivals run on."""
    folder, bench = three_dumps_and_a_table(tmp_path)
    seconds = {"pi-robust/lcp": 1e-5, "daqp/dual": 1e-4, "osqp/dual": 1e-2}

    def timed(pairs, repeats, accuracy=1e-8, pass_number=0, cold_repeats=0,  # noqa: ANN001, ANN202
              cap_s=math.inf):
        return [{"problem": problem.name, "set": head_to_head.set_of(problem),
                 "solver": spec.key, "pass": pass_number, "own": spec.key == "pi-robust/lcp",
                 "contacts": problem.n_contacts, "status": "solved", "success": True,
                 "residual": 0.0, "iterations": 1, "outer_iterations": None,
                 "time_s": seconds[spec.key], "time_cold_cache_s": seconds[spec.key]}
                for spec, problem in pairs]

    monkeypatch.setattr(head_to_head, "measure_batch", timed)
    # one problem per batch: the field is asked after every problem
    result = head_to_head.head_to_head(folder, bench, repeats=1, passes=2, batch_problems=1)
    measured = sorted((one["solver"], one["pass"]) for one in result["rows"])
    assert measured.count(("osqp/dual", 0)) == 1 and ("osqp/dual", 1) not in measured
    assert measured.count(("daqp/dual", 0)) == measured.count(("daqp/dual", 1)) == 3
    [entry] = result["summary"]
    assert entry["external"]["solver"] == "daqp/dual"
    assert entry["out_of_running"][0]["solver"] == "osqp/dual"
    everything = head_to_head.head_to_head(folder, bench, repeats=1, passes=1,
                                           out_of_running=math.inf, batch_problems=1)
    assert sum(one["solver"] == "osqp/dual" for one in everything["rows"]) == 3


def test_a_solve_past_the_cap_is_not_run_again_in_a_later_pass(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """osqp takes 12 s (past the cap of 10 s) on one dump and is the only external pair to
    solve it, so no pace takes it out of the set: in the second pass it runs on the other
    dumps but not on that one again, whose first row stands for the second pass too."""
    folder, bench = three_dumps_and_a_table(tmp_path)
    calls: list[tuple[str, str, int]] = []

    def timed(pairs, repeats, accuracy=1e-8, pass_number=0, cold_repeats=0,  # noqa: ANN001, ANN202
              cap_s=math.inf):
        rows = []
        for spec, problem in pairs:
            calls.append((spec.key, problem.name, pass_number))
            slow = spec.key == "osqp/dual" and problem.name == "grid5_itr_1"
            seconds = 12.0 if slow else 1e-4
            rows.append({"problem": problem.name, "set": head_to_head.set_of(problem),
                         "solver": spec.key, "pass": pass_number,
                         "own": spec.key == "pi-robust/lcp", "contacts": problem.n_contacts,
                         "status": "solved", "success": slow or spec.key != "daqp/dual",
                         "residual": 0.0, "iterations": 1, "outer_iterations": None,
                         "time_s": seconds, "time_cold_cache_s": math.nan if slow else seconds,
                         "over_cap": seconds > cap_s})
        return rows

    monkeypatch.setattr(head_to_head, "measure_batch", timed)
    result = head_to_head.head_to_head(folder, bench, repeats=1, passes=2, batch_problems=1,
                                       solve_cap_s=10.0)
    assert ("osqp/dual", "grid5_itr_1", 0) in calls
    assert ("osqp/dual", "grid5_itr_1", 1) not in calls
    assert ("osqp/dual", "ok_itr_0", 1) in calls  # no pace: still running on the set
    slow_rows = [one for one in result["rows"]
                 if (one["solver"], one["problem"]) == ("osqp/dual", "grid5_itr_1")]
    assert [one["pass"] for one in slow_rows] == [0, 1]
    assert all(one["time_s"] == 12.0 and one["over_cap"] for one in slow_rows)


def test_a_pair_that_left_a_size_bucket_is_not_measured_on_the_larger_ones() -> None:
    """daqp is 40x osqp's time on the 4x4 to 9x9 grids: it leaves that set and every larger
    grid bucket, where it was never measured; the box packings are another family."""
    running = head_to_head.Running(limit=30.0)
    rows = [{**row(solver, False, "grid-4-s0", time), "set": "grids 4-9"}
            for solver, time in (("osqp/dual", 1e-4), ("daqp/dual", 4e-3))]
    running.update(rows, "grids 4-9")
    for larger in ("grids 10-14", "grids 16-20", "grids 30-40"):
        assert not running.running(larger, "daqp/dual")
        assert running.out[larger]["daqp/dual"]["measured_on"] == "grids 4-9"
    assert running.running("grids 10-14", "osqp/dual")
    assert running.running("box packings 1k-4k", "daqp/dual")
    left = {"solver": "daqp/dual", **running.out["grids 16-20"]["daqp/dual"]}
    assert head_to_head.left_sentence(left) == (
        "`daqp/dual` measured no further after 1 problem of grids 4-9 (40.0x `osqp/dual`'s "
        "time there)")


def test_a_hard_familys_own_fastest_pair_runs_on_its_set_only(monkeypatch: pytest.MonkeyPatch,
                                                              tmp_path: Path) -> None:
    """osqp is the fastest external pair on k3 in the main table but not among the impact
    candidates: it runs on the k3 set and nowhere else. The problems are measured in the order
    of the sets (smaller grid bucket first, whatever their file names), and the report lists
    the generated problems' seeds, read from their files."""
    folder = tmp_path / "problems"
    folder.mkdir()
    for problem in [*generate("grid", 12, seed=41), *generate("grid", 4, seed=41),
                    *generate("k3", None, seed=40, count=2)]:
        files.save(problem, folder / problem.name)
    files.save(import_dump(ROOT / "problems/dumps/grid5_itr_0.out"), folder / "grid5.npz")
    bench = pd.DataFrame(bench_rows("daqp", "daqp", "grid", [1e-4])
                         + bench_rows("daqp", "daqp", "k3", [1e-4])
                         + bench_rows("osqp", "osqp", "k3", [1e-5]))

    def timed(pairs, repeats, accuracy=1e-8, pass_number=0, cold_repeats=0,  # noqa: ANN001, ANN202
              cap_s=math.inf):
        return [{"problem": problem.name, "set": head_to_head.set_of(problem),
                 "solver": spec.key, "pass": pass_number, "own": spec.key == "pi-robust/lcp",
                 "contacts": problem.n_contacts, "status": "solved", "success": True,
                 "residual": 0.0, "iterations": 1, "outer_iterations": None,
                 "time_s": 1e-4, "time_cold_cache_s": 1e-4} for spec, problem in pairs]

    monkeypatch.setattr(head_to_head, "measure_batch", timed)
    result = head_to_head.head_to_head(folder, bench, repeats=1, passes=1, candidates=1)
    assert result["candidates"]["impact"] == ["daqp/dual"]
    assert result["candidates"]["families"] == {"k3": ["osqp/dual"]}
    assert {one["set"] for one in result["rows"] if one["solver"] == "osqp/dual"} == {"k3"}
    order = list(dict.fromkeys(one["set"] for one in result["rows"]))
    assert order == ["fork 5x5 grid dumps", "grids 4-9", "grids 10-14", "k3"]
    assert result["seeds"] == {"grid": [41], "k3": [40, 41]}
    assert "Seeds of the generated problems" in result["markdown"]
    assert "grid 41; k3 40-41." in result["markdown"]


def test_seeds_are_listed_as_runs_of_consecutive_numbers() -> None:
    assert head_to_head_sets.seed_ranges([9, 5, 7, 6, 6]) == "5-7, 9"
    assert head_to_head_sets.seed_ranges([123456]) == "123456"
