"""Serial, local processes and a Dask cluster give the same rows."""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from bench_problems import write_tiny_problems

from qpbench.bench import isolation, runner
from qpbench.bench.executors import DaskExecutor, ProcessExecutor, SerialExecutor, make_executor
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import CELL_KEY, Limits, RunSettings
from qpbench.cli import main
from qpbench.errors import QpbenchError

isolation.start_fork_server()  # its imports overlap with this process's

SETTINGS = RunSettings(solvers=("test-exact/lcp", "clarabel/dual", "osqp/dual", "test-abort/lcp"),
                       accuracies=(1e-4, 1e-8), limits=Limits(timeout_s=30))
COMPARED = ["status", "success", "residual", "v_error", "iterations"]


@pytest.fixture(scope="module")
def problems(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("problems")
    write_tiny_problems(folder, count=2)
    return folder


@pytest.fixture
def misbehaving_solvers() -> Iterator[None]:
    with importlib.import_module("bench_solvers").registered():
        yield


def _rows(problems: Path, output: Path, executor: object) -> pd.DataFrame:
    runner.run([str(problems)], SETTINGS, output, executor, progress=False)
    frame = ResultStore(output).read()
    key = list(CELL_KEY)
    return frame.sort_values(key)[key + COMPARED].reset_index(drop=True)


@pytest.mark.slow
def test_processes_and_dask_give_the_rows_of_a_serial_run(
        tmp_path: Path, problems: Path, misbehaving_solvers: None) -> None:
    distributed = pytest.importorskip("distributed")
    serial = _rows(problems, tmp_path / "serial.parquet", SerialExecutor())
    assert len(serial) == 2 * 4 * 2
    assert set(serial.loc[serial["solver"] == "test-abort", "status"]) == {"crashed"}
    assert serial.loc[serial["solver"] == "test-exact", "success"].all()

    processes = _rows(problems, tmp_path / "processes.parquet", ProcessExecutor(workers=2))
    pd.testing.assert_frame_equal(processes, serial)

    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        address = cluster.scheduler_address.replace("tcp://", "dask://")
        code = main(["run", str(problems), "--solvers", ",".join(SETTINGS.solvers),
                     "--accuracy", "1e-4,1e-8", "--timeout", "30", "--executor", address,
                     "--no-progress", "-o", str(tmp_path / "dask.parquet")])
    assert code == 0
    dask = ResultStore(tmp_path / "dask.parquet").read()
    dask = dask.sort_values(list(CELL_KEY))[list(CELL_KEY) + COMPARED].reset_index(drop=True)
    pd.testing.assert_frame_equal(dask, serial)


def test_executor_names() -> None:
    assert isinstance(make_executor("auto", workers=1), SerialExecutor)
    assert isinstance(make_executor("auto", workers=3), ProcessExecutor)
    dask = make_executor("dask://127.0.0.1:8786")
    assert isinstance(dask, DaskExecutor) and dask.address == "tcp://127.0.0.1:8786"
    with pytest.raises(QpbenchError, match="unknown executor"):
        make_executor("mpi")
