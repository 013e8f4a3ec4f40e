"""``qpbench run`` input errors: one line on stderr, exit 2, no results file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bench_problems import collinear_balls, exact_impulses, write_tiny_problems

from qpbench.bench.settings import HARNESS_STATUSES, STATUSES, VERDICTS, parse_statuses
from qpbench.cli import main
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.run import NO_SOLUTION, judge


@pytest.mark.parametrize(("arguments", "message"), [
    (["--solvers", "no-such-solver"], "unknown solver 'no-such-solver'"),
    (["--accuracy", "1e-4,tight"], "'tight' is not a number"),
    (["--mode", "lukewarm"], "unknown mode 'lukewarm'"),
    (["--timeout", "0"], "--timeout must be positive"),
    (["--executor", "mpi"], "unknown executor 'mpi'"),
    (["--solvers", ","], "--solvers: no solver named in ','"),
    (["--solvers", ""], "--solvers: no solver named in ''"),
    (["--accuracy", "1e-4,1e-30"], "--accuracy: 1e-30 is below 1e-14"),
    (["--accuracy", "1e-15"], "--accuracy: 1e-15 is below 1e-14"),
])
def test_bad_run_options_are_one_line_errors(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str],
        message: str) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)
    output = tmp_path / "results.parquet"
    code = main(["run", str(tmp_path / "problems"), *arguments, "-o", str(output)])
    error = capsys.readouterr().err
    assert code == 2
    assert message in error and error.count("\n") == 1
    assert not output.exists()


def test_a_missing_problem_folder_names_it(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", str(tmp_path / "nowhere"), "--solvers", "clarabel", "-o",
                 str(tmp_path / "r.parquet")])
    error = capsys.readouterr().err
    assert code == 2 and "nowhere" in error and "no such problem file or folder" in error


def test_duplicate_problem_names_are_refused(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    write_tiny_problems(tmp_path / "a", count=1)
    write_tiny_problems(tmp_path / "b", count=1)
    code = main(["run", str(tmp_path / "a"), str(tmp_path / "b"), "--solvers", "clarabel",
                 "-o", str(tmp_path / "r.parquet")])
    error = capsys.readouterr().err
    assert code == 2 and "problem name 'row3' is also used by" in error


def test_a_folder_as_results_file_is_refused(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)
    code = main(["run", str(tmp_path / "problems"), "--solvers", "clarabel", "-o", str(tmp_path)])
    assert code == 2
    assert capsys.readouterr().err == \
        f"qpbench run: {tmp_path}: is a folder, not a file qpbench can write\n"


def test_report_of_a_file_that_is_not_parquet_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bogus = tmp_path / "results.parquet"
    bogus.write_text("not parquet")
    code = main(["report", str(bogus), "-o", str(tmp_path / "out")])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "not a readable results file" in error
    assert not (tmp_path / "out" / "REPORT.md").exists()


def test_retry_of_an_unknown_status_is_refused_naming_the_known_ones(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", str(tmp_path), "--retry", "timedout", "-o", str(tmp_path / "r.parquet")])
    error = capsys.readouterr().err
    assert code == 2 and "--retry: unknown status 'timedout' (known: " in error
    assert error.count("\n") == 1
    for status in STATUSES:
        assert status in error


def test_retry_takes_every_status_a_row_can_carry() -> None:
    """The verdicts of judge (no-solution among them) and the harness's statuses alike."""
    assert parse_statuses(",".join(STATUSES)) == STATUSES
    assert NO_SOLUTION in STATUSES
    problem = collinear_balls("row", 3)
    spec = SolverSpec(name="any", formulation="lcp", backend="tests", solve=None)
    answers = [exact_impulses(problem), np.full(problem.n_contacts, 0.1), None]
    for impulses in answers:
        output = SolverOutput(impulses=impulses, status="", claimed_success=False)
        assert judge(spec, problem, output, 1e-8)["status"] in VERDICTS
    assert {*VERDICTS, *HARNESS_STATUSES} == set(STATUSES)


def test_a_run_with_no_solver_named_writes_nothing(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)
    output = tmp_path / "r.parquet"
    code = main(["run", str(tmp_path / "problems"), "--solvers", " , ", "-o", str(output)])
    assert code == 2 and "no solver named" in capsys.readouterr().err
    assert not output.exists()


def test_kind_runs_only_the_problems_of_that_kind_each_with_the_solvers_that_take_it(
        tmp_path: Path) -> None:
    """lemke/lcp takes both kinds; osqp/dual only impact problems, nsgs only frictional."""
    from friction_cases import ball_on_floor

    from qpbench.bench.results import ResultStore
    from qpbench.problem import files

    write_tiny_problems(tmp_path / "problems", count=1)
    files.save(ball_on_floor(-2.0, 1.5, 0.5, name="rough"), tmp_path / "problems" / "rough")
    output = tmp_path / "results.parquet"
    arguments = ["run", str(tmp_path / "problems"), "--solvers", "lemke,osqp/dual,nsgs",
                 "--accuracy", "1e-8", "--no-progress", "-o", str(output)]
    assert main([*arguments, "--kind", "frictional"]) == 0
    rows = ResultStore(output).read()
    assert set(zip(rows["problem"], rows["solver"], strict=True)) == {
        ("rough", "lemke"), ("rough", "nsgs")}
    assert main(arguments) == 0  # all kinds: the impact cells are added, nothing repeated
    rows = ResultStore(output).read()
    assert set(zip(rows["problem"], rows["solver"], strict=True)) == {
        ("rough", "lemke"), ("rough", "nsgs"), ("row3", "lemke"), ("row3", "osqp")}
    assert set(rows.loc[rows["problem"] == "rough", "kind"]) == {"frictional"}
