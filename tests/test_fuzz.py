"""``qpbench fuzz``: mutated scenes and problem files get qpbench's own one-line errors.

The runs use the repository's scenes (problems/scenes) unless marked as needing ../shared.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

import pytest

from qpbench.bench.report import fuzz_section
from qpbench.cli import fuzz_harness as fuzz
from qpbench.cli import main
from qpbench.cli.fuzz_inputs import FEATURES, case_rng, features, mutate_scene

REPOSITORY = Path(__file__).resolve().parents[1]
SCENES = REPOSITORY / "problems" / "scenes"
SHARED = REPOSITORY.parent / "shared"
# failures whose cause lies outside the scene parser, each in a file being fixed elsewhere:
# (pattern of the failing stderr or outcome, the file and the fault)
def test_a_clean_run_and_a_refusal_are_passing_outcomes() -> None:
    assert fuzz.judge(0, "qpbench simulate: warning: x.xml: ignoring <foo>\n") == "ok"
    assert fuzz.judge(2, "qpbench simulate: x.xml: <ball> attribute 'r': missing\n") == \
        "input-error"
    assert fuzz.judge(1, "qpbench simulate: note: n\nqpbench simulate: inner solve failed\n") \
        == "solve-failed"


@pytest.mark.parametrize(("exit_code", "stderr", "must_refuse", "outcome"), [
    (3, "qpbench simulate: internal error: RecursionError: deep\n", False, "internal-error"),
    (3, "qpbench solve: internal error: MemoryError: 8 TiB\n", False, "out-of-memory"),
    (1, "Traceback (most recent call last):\n  File ...\n", False, "traceback"),
    (2, "qpbench solve: x: bad\n/x/y.py:3: RuntimeWarning: overflow\n", False, "stray-stderr"),
    (2, "qpbench solve: one\nqpbench solve: two\n", False, "several-lines"),
    (1, "", False, "no-message"),
    (2, "qpbench simulate: " + "x" * 2000 + "\n", False, "overlong-line"),
    (0, "", True, "entity-accepted"),
    (137, "qpbench simulate: x\n", False, "other-exit"),
])
def test_every_other_outcome_is_a_failure(exit_code: int, stderr: str, must_refuse: bool,
                                          outcome: str) -> None:
    assert fuzz.judge(exit_code, stderr, must_refuse) == outcome
    assert outcome not in fuzz.PASSING


def test_a_case_is_the_same_bytes_for_the_same_seed_and_number() -> None:
    corpus = [(path.name, path.read_bytes()) for path in sorted(SCENES.rglob("*.xml"))]
    first = [mutate_scene(corpus, case_rng("scene", 7, case)).data for case in range(30)]
    again = [mutate_scene(corpus, case_rng("scene", 7, case)).data for case in range(30)]
    other = [mutate_scene(corpus, case_rng("scene", 8, case)).data for case in range(30)]
    assert first == again and first != other


@pytest.mark.parametrize("dialect", ["ball2d", "rigidbody2d"])
def test_every_inserted_feature_is_valid_as_written(dialect: str, tmp_path: Path) -> None:
    """Friction solvers, boxes, portals and kinematic bodies are inserted valid, so that a
    corrupted attribute of theirs reaches the code that reads it."""
    base = {"ball2d": SCENES / "scisim" / "two_balls.xml",
            "rigidbody2d": SCENES / "ura" / "K3.xml"}[dialect].read_text()
    available = features(dialect, base.count("<static_plane"), base.count("<geometry"))
    assert {"sobogus_friction_solver", "planar_portal", "lees_edwards_portal"} <= set(available)
    assert set(available) <= set(FEATURES)
    for name, xml in available.items():
        text = base
        if "operator" in name or "friction" in name:  # a scene has one
            text = re.sub(r"<impact_operator.*?</impact_operator>", "", text, flags=re.S)
        if name in ("integrator", "end_time"):
            text = re.sub(rf"<{name}[^>]*/>", "", text)
        scene = tmp_path / f"{name}.xml"
        scene.write_text(text.replace(f"</{dialect}_scene>", xml + f"</{dialect}_scene>"))
        status, stderr = fuzz.run_command(["simulate", str(scene), "--steps", "2"])
        assert (status, fuzz.judge(status, stderr)) == (0, "ok"), (name, stderr)


def test_200_scene_cases_of_the_repository_scenes_all_pass(tmp_path: Path) -> None:
    settings = fuzz.Settings(scenes=200, problems=0, seed=11, time_limit_s=60)
    report = fuzz.fuzz(settings, [SCENES], tmp_path / "cases")
    assert report["kinds"]["scene"]["cases"] == 200
    assert report["failures"] == [] and report["passed"]
    outcomes = report["kinds"]["scene"]["outcomes"]
    assert outcomes.get("ok", 0) > 0 and outcomes.get("input-error", 0) > 0
    operations = report["kinds"]["scene"]["operations"]
    assert {"insert", "set", "delete", "entity"} <= set(operations)


def test_200_problem_cases_give_only_qpbench_own_outcomes(tmp_path: Path) -> None:
    settings = fuzz.Settings(scenes=0, problems=200, seed=11, time_limit_s=60)
    report = fuzz.fuzz(settings, [SCENES], tmp_path / "cases")
    assert report["kinds"]["problem"]["cases"] == 200
    assert report["failures"] == [] and report["passed"]
    assert report["kinds"]["problem"]["outcomes"].get("input-error", 0) > 100


def test_a_problem_mutation_is_made_whatever_the_mutations_before_it_did(
        tmp_path: Path) -> None:
    """Case 3786 of seed 0 first turns G's column pointers into objects and then sets one of
    them out of range: the second mutation takes the array it finds as it is (its numbers, or
    zeros), so the case is made (that case once failed to be made again for the failures'
    folder, which ended a ``make bench-large`` run's fuzz report with an internal error);
    and so are the 1,000 cases of another seed."""
    corpus = fuzz.Corpus(scenes=[], problems=fuzz.problem_corpus(tmp_path))
    made = fuzz.make_case("problem", 3786, fuzz.Settings(scenes=0, problems=1, seed=0), corpus)
    assert made.operations == ["G_indptr as object", "G_indptr (-1, 3)"]
    settings = fuzz.Settings(scenes=0, problems=1000, seed=5)
    for case in range(1000):
        assert fuzz.make_case("problem", case, settings, corpus).operations


def test_a_failing_case_whose_input_cannot_be_made_again_is_recorded_not_fatal(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*_: object) -> None:
        raise ValueError("a mutation's own fault")

    monkeypatch.setattr(fuzz, "make_case", broken)
    failures = [{"kind": "problem", "case": 7, "outcome": "crash"}]
    fuzz._save_failures(failures, fuzz.Settings(scenes=0, problems=8), fuzz.Corpus([], []),
                        tmp_path / "cases")
    assert failures[0]["input"] == "not made: ValueError: a mutation's own fault"
    assert list((tmp_path / "cases").iterdir()) == []


@pytest.mark.shared
@pytest.mark.skipif(not (SHARED / "scisim").is_dir(), reason="needs ../shared (SCISim scenes)")
def test_200_scene_cases_of_the_shared_scisim_scenes_all_pass(tmp_path: Path) -> None:
    settings = fuzz.Settings(scenes=200, problems=0, seed=5, time_limit_s=60)
    report = fuzz.fuzz(settings, None, tmp_path / "cases")
    assert any(name.startswith("shared/") for name in report["corpus"]["scenes"])
    assert report["failures"] == []


def _misbehaving_main(argv: list[str]) -> int:
    """Stands in for qpbench's main in the children: case 1 hangs, case 2 kills its
    process, case 3 prints a traceback; the rest pass."""
    case = argv[1]
    if case.endswith("scene-000001.xml"):
        time.sleep(30)
    if case.endswith("scene-000002.xml"):
        os._exit(9)
    if case.endswith("scene-000003.xml"):
        print("Traceback (most recent call last):", file=sys.stderr)
        return 1
    return 0


def test_a_hang_a_crash_and_a_traceback_are_caught_and_saved(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fuzz, "main", _misbehaving_main)
    settings = fuzz.Settings(scenes=6, problems=0, seed=1, time_limit_s=2)
    report = fuzz.fuzz(settings, [SCENES], tmp_path / "cases")
    outcomes = {failure["case"]: failure["outcome"] for failure in report["failures"]}
    assert outcomes == {1: "timeout", 2: "crashed", 3: "traceback"}
    assert report["kinds"]["scene"]["outcomes"]["ok"] == 3  # the run went on after each
    saved = report["failures"][0]
    assert Path(saved["input"]).read_bytes() == fuzz.make_case(
        "scene", saved["case"], settings, fuzz.Corpus(
            scenes=fuzz.scene_corpus([SCENES]), problems=[])).data


def test_the_command_writes_the_counts_that_the_report_prints(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture
                                                              ) -> None:
    output = tmp_path / "fuzz.json"
    assert main(["fuzz", "--scenes", "20", "--problems", "0", "--seed", "3", "--corpus",
                 str(SCENES), "-o", str(output)]) == 0
    report = json.loads(output.read_text())
    assert report["kinds"]["scene"]["cases"] == 20 and report["passed"]
    assert "scene: 20 cases, 0 failed" in capsys.readouterr().out
    section = fuzz_section([tmp_path])
    assert section is not None and "every case passed" in section
    assert "| scene | 20 | 0 |" in section


@pytest.mark.parametrize("arguments", [["--scenes", "-1"], ["--time-limit-s", "nan"],
                                       ["--memory-limit", "1"], ["--corpus", "/no/such/dir"]])
def test_bad_options_are_one_line(arguments: list[str], tmp_path: Path,
                                  capsys: pytest.CaptureFixture) -> None:
    assert main(["fuzz", *arguments, "--problems", "0", "-o", str(tmp_path / "f.json")]) == 2
    error = capsys.readouterr().err
    assert error.startswith("qpbench fuzz: ") and error.count("\n") == 1
