"""A solver that aborts, segfaults, hangs or eats memory becomes a row; the run goes on; and
a worker's death is named by what happened, out-of-memory only on evidence."""

from __future__ import annotations

import importlib
import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from bench_problems import write_tiny_problems

from qpbench.bench import isolation, runner
from qpbench.bench.executors import SerialExecutor
from qpbench.bench.isolation import classify_death
from qpbench.bench.lock import lock_label
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import Cell, Limits, RunSettings

isolation.start_fork_server()  # its imports overlap with this process's


@pytest.fixture
def misbehaving_solvers() -> Iterator[None]:
    with importlib.import_module("bench_solvers").registered():
        yield


@pytest.mark.slow
def test_crash_hang_and_memory_blowup_become_rows_while_the_others_finish(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    write_tiny_problems(tmp_path / "problems", count=1)  # K3 only
    settings = RunSettings(
        # the misbehaving ones first: the solvers after them must still run
        solvers=("test-abort/lcp", "test-segfault/lcp", "test-hang/lcp", "test-greedy/lcp",
                 "test-exact/lcp", "clarabel/dual"),
        accuracies=(1e-8,),
        limits=Limits(timeout_s=2.0, memory_limit_mb=3072),
    )
    output = tmp_path / "results.parquet"
    counts = runner.run([str(tmp_path / "problems")], settings, output, SerialExecutor(),
                        progress=False)
    assert counts == {"cells": 6, "skipped": 0, "run": 6, "crashed": 2, "timeout": 1,
                      "out-of-memory": 1, "solved": 2}

    rows = ResultStore(output).read().set_index("solver")
    assert rows.loc["test-abort", "status"] == "crashed"
    assert "SIGABRT" in rows.loc["test-abort", "solver_status"]
    assert rows.loc["test-segfault", "status"] == "crashed"
    assert "SIGSEGV" in rows.loc["test-segfault", "solver_status"]
    assert rows.loc["test-hang", "status"] == "timeout"
    assert rows.loc["test-hang", "time_s"] == 2.0  # charged the limit it was killed at
    assert rows.loc["test-greedy", "status"] == "out-of-memory"
    for failed in ("test-abort", "test-segfault", "test-hang", "test-greedy"):
        assert not rows.loc[failed, "success"]
        assert rows.loc[failed, "problem"] == "row3"
        assert rows.loc[failed, "family"] == "k3"  # the problem's summary is there too
        assert rows.loc[failed, "lock_hash"] == lock_label()  # and where it was measured
        assert rows.loc[failed, "python_version"]

    exact = rows.loc["test-exact"]
    assert exact["status"] == "solved" and exact["success"]
    assert exact["residual"] <= 1e-12 and exact["v_error"] <= 1e-12
    clarabel = rows.loc["clarabel"]
    assert clarabel["status"] == "solved" and clarabel["residual"] <= 1e-8
    assert clarabel["backend"] == "qpsolvers" and clarabel["solver_version"]
    # provenance and timing columns of a finished solve
    for column in ("qpbench_version", "python_version", "cpu_model", "hostname", "date"):
        assert isinstance(exact[column], str) and exact[column]
    assert 0 < exact["timer_overhead_s"] < 1e-3
    assert exact["time_s"] <= exact["time_median_s"]


@pytest.mark.slow
def test_a_worker_started_as_a_program_is_isolated_too(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    # the way a daemonic process (a Dask worker under a nanny) runs cells: no fork server
    (path,) = write_tiny_problems(tmp_path, count=1)
    worker = isolation.IsolatedWorker(program=True)
    limits = Limits(timeout_s=5.0)
    try:
        crashed = worker.solve(Cell(str(path), "row3", "test-abort", "lcp", 1e-8, "cold"), limits)
        solved = worker.solve(Cell(str(path), "row3", "test-exact", "lcp", 1e-8, "cold"), limits)
    finally:
        worker.close()
    assert crashed["status"] == "crashed" and "SIGABRT" in crashed["solver_status"]
    assert solved["status"] == "solved" and solved["residual"] <= 1e-12


@pytest.mark.slow
def test_a_worker_killed_from_outside_is_killed_not_out_of_memory(
        tmp_path: Path, misbehaving_solvers: None) -> None:
    """SIGKILL sent by someone else (a user's kill -9) to a worker that allocated nothing."""
    (path,) = write_tiny_problems(tmp_path, count=1)
    worker = isolation.IsolatedWorker()
    worker.start()
    pid = worker.process.pid

    def kill_soon() -> None:
        time.sleep(1.0)  # test-hang is asleep in its solve by then
        os.kill(pid, signal.SIGKILL)

    killer = threading.Thread(target=kill_soon)
    killer.start()
    try:
        row = worker.solve(Cell(str(path), "row3", "test-hang", "lcp", 1e-8, "cold"),
                           Limits(timeout_s=60.0, memory_limit_mb=3072))
    finally:
        killer.join()
        worker.close()
    assert row["status"] == "killed"
    assert "killed by SIGKILL" in row["solver_status"]
    assert "a signal qpbench did not send" in row["solver_status"]
    assert row["memory_limit_mb"] == 3072  # the cap it ran under, stated on the row


@pytest.mark.parametrize(("returncode", "log", "cap", "oom_killer_ran", "status", "named"), [
    (-signal.SIGKILL, "", 0, False, "killed", "SIGKILL"),
    (-signal.SIGKILL, "", 4096, False, "killed", "SIGKILL"),  # a cap alone is no evidence
    (-signal.SIGTERM, "", 4096, False, "killed", "SIGTERM"),
    (-signal.SIGKILL, "", 0, True, "out-of-memory", "OOM killer"),
    (-signal.SIGABRT, "terminate called after throwing std::bad_alloc", 3072, False,
     "out-of-memory", "under the 3072 MiB cap"),
    (-signal.SIGABRT, "terminate called after throwing std::bad_alloc", 0, False,
     "crashed", "SIGABRT"),  # no cap: the solver's own crash, its message kept
    (-signal.SIGSEGV, "", 4096, False, "crashed", "SIGSEGV"),
    (3, "fatal: bad pivot", 4096, False, "crashed", "exit code 3"),
])
def test_a_dead_worker_is_classified_by_what_happened(
        returncode: int, log: str, cap: int, oom_killer_ran: bool, status: str,
        named: str) -> None:
    found, message = classify_death(returncode, log, cap, oom_killer_ran)
    assert found == status
    assert named in message and message.startswith("worker died: ")
    assert log in message
