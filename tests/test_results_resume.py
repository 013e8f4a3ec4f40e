"""Results survive kill -9 and Ctrl-C: nothing written is lost, nothing is duplicated on
resume, and an interrupted run leaves a readable table."""

from __future__ import annotations

import importlib
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pandas as pd
import pytest
from bench_problems import write_tiny_problems

from qpbench.bench import isolation, runner
from qpbench.bench.executors import SerialExecutor
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import CELL_KEY, Cell, Limits, RunSettings
from qpbench.errors import InputError, QpbenchError
from qpbench.problem import files

isolation.start_fork_server()  # its imports overlap with this process's

TESTS = Path(__file__).parent


def _row(problem: str, accuracy: float, residual: float) -> dict[str, object]:
    return {"problem": problem, "solver": "s", "formulation": "dual", "accuracy": accuracy,
            "mode": "cold", "status": "solved", "success": True, "residual": residual}


def test_parts_are_compacted_into_one_file_and_read_without_duplicates(tmp_path: Path) -> None:
    store = ResultStore(tmp_path / "r.parquet")
    store.write_part([_row("a", 1e-4, 1e-5), _row("a", 1e-8, 1e-9)])
    store.write_part([_row("b", 1e-4, 2e-5)])
    assert len(store.part_files()) == 2
    assert store.finished_keys() == {("a", "s", "dual", 1e-4, "cold"),
                                     ("a", "s", "dual", 1e-8, "cold"),
                                     ("b", "s", "dual", 1e-4, "cold")}
    kept_part = store.part_files()[0].read_bytes()
    assert store.compact() == 3
    assert store.part_files() == [] and store.path.exists()

    # a kill -9 after the compacted file was renamed in but before the parts were deleted
    # leaves a part whose rows are already in the main file: still no duplicate
    store.parts.mkdir()
    (store.parts / "part-00000000000000000001-1-abcdef01.parquet").write_bytes(kept_part)
    (store.parts / ".tmp-half-written.parquet").write_bytes(b"PAR1 torn")  # ignored
    frame = store.read()
    assert len(frame) == 3
    assert not frame.duplicated(subset=list(CELL_KEY)).any()
    assert store.compact() == 3 and not store.parts.exists()


@pytest.mark.parametrize(("change", "message"), [
    (lambda frame: frame.drop(columns=["time_s"]), "not a results table of this qpbench: no "
                                                   "column time_s"),
    (lambda frame: frame.assign(time_s="fast"), "column 'time_s' must hold numbers, not"),
    (lambda frame: frame.assign(success=1.0), "column 'success' must hold true/false flags"),
])
def test_a_results_file_of_other_columns_is_one_line_naming_the_column(
        tmp_path: Path, change: Callable[[pd.DataFrame], pd.DataFrame], message: str) -> None:
    store = ResultStore(tmp_path / "r.parquet")
    store.write_part([_row("a", 1e-4, 1e-5)])
    store.compact()
    assert store.read()["residual"].tolist() == [1e-5]  # as written, it reads
    change(pd.read_parquet(store.path)).to_parquet(store.path)
    with pytest.raises(InputError, match=message):
        store.read()


def _matrix_command(problems: Path, output: Path) -> list[str]:
    command = Path(sys.executable).with_name("qpbench")  # the console script beside python
    return [str(command), "run", str(problems), "--solvers", "test-slow",
            "--accuracy", "1e-4,1e-6,1e-8", "--batch", "1", "--no-progress", "-o", str(output)]


@pytest.fixture
def misbehaving_solvers() -> Iterator[None]:
    with importlib.import_module("bench_solvers").registered():
        yield


@pytest.mark.slow
def test_a_run_killed_mid_way_and_resumed_has_exactly_the_rows_of_an_uninterrupted_run(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    problems = tmp_path / "problems"
    write_tiny_problems(problems, count=3)  # 3 problems x 3 levels = 9 cells of 0.3 s each
    killed = tmp_path / "killed.parquet"
    environment = {**os.environ, "QPBENCH_EXTRA_SOLVERS": "bench_solvers",
                   "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    process = subprocess.Popen(_matrix_command(problems, killed), env=environment,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    store = ResultStore(killed)
    deadline = time.monotonic() + 240
    while len(store.part_files()) < 2 and time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read().decode() if process.stderr else ""
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    process.stderr.close()
    before = store.read()
    assert 2 <= len(before) < 9, "the kill must land mid-way"
    assert not killed.exists()  # never compacted: the parts are all there is

    settings = RunSettings(solvers=("test-slow/lcp",), accuracies=(1e-4, 1e-6, 1e-8),
                           limits=Limits(timeout_s=30))
    counts = runner.run([str(problems)], settings, killed, SerialExecutor(), progress=False)
    assert counts["skipped"] == len(before) and counts["run"] == 9 - len(before)
    resumed = ResultStore(killed).read()

    uninterrupted = tmp_path / "uninterrupted.parquet"
    runner.run([str(problems)], settings, uninterrupted, SerialExecutor(), progress=False)
    reference = ResultStore(uninterrupted).read()

    key = list(CELL_KEY)
    assert len(resumed) == 9 and not resumed.duplicated(subset=key).any()
    compared = ["status", "success", "residual", "v_error"]
    pd.testing.assert_frame_equal(resumed.sort_values(key)[key + compared].reset_index(drop=True),
                                  reference.sort_values(key)[key + compared]
                                  .reset_index(drop=True))
    # the rows written before the kill were kept as they were, not solved again
    kept = resumed.merge(before[key + ["date", "cell_wall_s"]], on=key, suffixes=("", "_before"))
    assert len(kept) == len(before)
    assert (kept["cell_wall_s"] == kept["cell_wall_s_before"]).all()


@pytest.mark.slow
@pytest.mark.parametrize("interrupt", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_run_leaves_a_readable_table_that_a_resume_completes(
        tmp_path: Path, misbehaving_solvers: None, interrupt: signal.Signals) -> None:
    problems = tmp_path / "problems"
    write_tiny_problems(problems, count=3)  # 9 cells of 0.3 s each
    output = tmp_path / "interrupted.parquet"
    logs = tmp_path / "tmp"  # the run's temporary folder: where worker logs would stay
    logs.mkdir()
    environment = {**os.environ, "QPBENCH_EXTRA_SOLVERS": "bench_solvers", "TMPDIR": str(logs),
                   "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    process = subprocess.Popen(_matrix_command(problems, output), env=environment,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    store = ResultStore(output)
    deadline = time.monotonic() + 240
    while len(store.part_files()) < 2 and time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read() if process.stderr else ""
        time.sleep(0.02)
    process.send_signal(interrupt)
    _, error = process.communicate(timeout=120)
    assert process.returncode == 130
    assert error == "qpbench run: interrupted\n"  # one line, no traceback
    assert list(logs.iterdir()) == []  # no worker log left behind

    # the named file alone holds every row finished before the interrupt
    assert store.part_files() == [] and not store.parts.exists()
    before = pd.read_parquet(output)
    assert 2 <= len(before) < 9, "the interrupt must land mid-way"
    key = list(CELL_KEY)
    assert not before.duplicated(subset=key).any()
    assert set(before["status"]) == {"solved"}

    settings = RunSettings(solvers=("test-slow/lcp",), accuracies=(1e-4, 1e-6, 1e-8),
                           limits=Limits(timeout_s=30))
    counts = runner.run([str(problems)], settings, output, SerialExecutor(), progress=False)
    assert counts["skipped"] == len(before) and counts["run"] == 9 - len(before)
    resumed = pd.read_parquet(output)
    assert len(resumed) == 9 and not resumed.duplicated(subset=key).any()
    assert set(resumed["status"]) == {"solved"}
    assert resumed[[*key, "residual", "time_s", "lock_hash"]].notna().all().all()


def test_a_second_run_on_the_same_results_is_refused_while_the_first_writes(
        tmp_path: Path) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)
    store = ResultStore(tmp_path / "r.parquet")
    settings = RunSettings(solvers=("clarabel/dual",), accuracies=(1e-8,))
    with store.exclusive(), pytest.raises(QpbenchError, match="another qpbench run is writing"):
        runner.run([str(tmp_path / "problems")], settings, store.path, SerialExecutor(),
                   progress=False)
    assert not store.path.exists() and store.part_files() == []


def test_a_problem_stored_with_other_numbers_is_solved_again_on_resume(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A problem of the same name with other numbers (a scene captured on another CPU, say)
    is solved again, its rows replaced by rows of the new numbers, and the run says so."""
    (path,) = write_tiny_problems(tmp_path / "problems", count=1)
    settings = RunSettings(solvers=("clarabel/dual",), accuracies=(1e-8,))
    output = tmp_path / "r.parquet"
    runner.run([str(tmp_path / "problems")], settings, output, SerialExecutor(), progress=False)
    (first,) = ResultStore(output).read()["problem_hash"]

    problem = files.load(path)
    problem.v_minus[0] = 2.0  # same name, other numbers
    files.save(problem, path)
    capsys.readouterr()
    more = RunSettings(solvers=("clarabel/dual",), accuracies=(1e-8, 1e-4))
    counts = runner.run([str(tmp_path / "problems")], more, output, SerialExecutor(),
                        progress=False)
    assert counts["run"] == 2 and counts["skipped"] == 0
    assert "1 problems differ from those of the same names" in capsys.readouterr().err
    stored = ResultStore(output).read()
    assert len(stored) == 2 and set(stored["problem_hash"]) == {runner.fingerprint(problem)}
    assert first != runner.fingerprint(problem)


def test_retry_solves_timed_out_cells_again_and_replaces_their_rows(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)
    output = tmp_path / "r.parquet"
    problems = [str(tmp_path / "problems")]
    short = RunSettings(solvers=("test-slow/lcp",), accuracies=(1e-8,),
                        limits=Limits(timeout_s=0.05))  # test-slow pauses 0.3 s
    runner.run(problems, short, output, SerialExecutor(), progress=False)
    assert list(ResultStore(output).read()["status"]) == ["timeout"]

    longer = RunSettings(solvers=("test-slow/lcp",), accuracies=(1e-8,),
                         limits=Limits(timeout_s=30))
    counts = runner.run(problems, longer, output, SerialExecutor(), progress=False)
    assert counts["run"] == 0  # a stored timeout is a finished cell unless retried
    counts = runner.run(problems, longer, output, SerialExecutor(), progress=False,
                        retry=("timeout",))
    assert counts["run"] == 1
    rows = ResultStore(output).read()
    assert list(rows["status"]) == ["solved"] and list(rows["time_limit_s"]) == [30.0]


def test_a_pair_past_the_limit_is_not_started_at_tighter_levels_and_resumes_alike(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    """test-hang runs past the limit at 1e-4, so its cells at 1e-6 and 1e-8 of that problem
    are timeouts never started; test-exact solves every level; a resume keeps the rows, and
    ``--retry timeout`` starts the loosest level again and ends the tighter ones alike."""
    write_tiny_problems(tmp_path / "problems", count=1)
    output = tmp_path / "r.parquet"
    problems = [str(tmp_path / "problems")]
    settings = RunSettings(solvers=("test-hang/lcp", "test-exact/lcp"),
                           accuracies=(1e-4, 1e-6, 1e-8), limits=Limits(timeout_s=0.5))

    def hang_rows() -> pd.DataFrame:
        rows = ResultStore(output).read()
        return rows[rows["solver"] == "test-hang"].set_index("accuracy").sort_index()

    counts = runner.run(problems, settings, output, SerialExecutor(), progress=False)
    assert counts["run"] == 6 and counts["timeout"] == 3 and counts["solved"] == 3
    rows = hang_rows()
    assert set(rows["status"]) == {"timeout"}
    assert rows.loc[1e-4, "solver_status"].startswith("killed after 0.5 s")
    for level in (1e-6, 1e-8):
        assert rows.loc[level, "solver_status"] == (
            f"{isolation.NOT_STARTED}the pair ran past 0.5 s at the looser level 1e-04 of this "
            "problem")
        assert math.isnan(rows.loc[level, "time_s"]) and rows.loc[level, "repeats"] == 0

    assert runner.run(problems, settings, output, SerialExecutor(), progress=False)["run"] == 0
    counts = runner.run(problems, settings, output, SerialExecutor(), progress=False,
                        retry=("timeout",))
    assert counts["run"] == 3 and counts["timeout"] == 3
    assert len(ResultStore(output).read()) == 6
    assert hang_rows()["solver_status"].str.startswith(isolation.NOT_STARTED).sum() == 2


def test_a_cell_is_not_started_only_at_tighter_levels_of_the_same_problem_pair_and_mode(
        ) -> None:
    overran = Cell("a.npz", "a", "s", "dual", 1e-6, "cold")
    others = [Cell("a.npz", "a", "s", "dual", 1e-4, "cold"),  # looser: runs
              Cell("a.npz", "a", "s", "dual", 1e-8, "cold"),  # tighter: not started
              Cell("a.npz", "a", "s", "dual", 1e-8, "warm"),  # another mode
              Cell("a.npz", "a", "s", "primal", 1e-8, "cold"),  # another formulation
              Cell("a.npz", "a", "t", "dual", 1e-8, "cold"),  # another solver
              Cell("b.npz", "b", "s", "dual", 1e-8, "cold")]  # another problem
    assert isolation.tighter_levels(overran, others) == [others[1]]


def test_a_resume_solves_killed_cells_again_and_keeps_the_other_statuses(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    """A worker killed from outside says nothing about the solver, so a plain resume solves
    its cell again; a timeout is a finished cell until ``--retry timeout``."""
    write_tiny_problems(tmp_path / "problems", count=1)
    store = ResultStore(tmp_path / "r.parquet")
    stored = [{**_row("row3", level, math.nan), "solver": "test-exact", "formulation": "lcp",
               "status": status, "success": False}
              for level, status in ((1e-4, "timeout"), (1e-8, "killed"))]
    store.write_part(stored)
    settings = RunSettings(solvers=("test-exact/lcp",), accuracies=(1e-4, 1e-8))
    counts = runner.run([str(tmp_path / "problems")], settings, store.path, SerialExecutor(),
                        progress=False)
    assert counts["skipped"] == 1 and counts["run"] == 1 and counts["solved"] == 1
    rows = store.read().set_index("accuracy")
    assert rows.loc[1e-8, "status"] == "solved" and rows.loc[1e-4, "status"] == "timeout"
