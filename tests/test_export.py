"""Export: qpbenchmark's Parquet problem list and one .mat per problem, readable back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
from bench_problems import write_tiny_problems

from qpbench.bench.export import export
from qpbench.cli import main
from qpbench.problem import files
from qpbench.problem.formulations import primal_qp


@pytest.fixture(scope="module")
def problems(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("problems")
    write_tiny_problems(folder, count=2)
    return folder


def test_parquet_problem_list_as_qpbenchmark_reads_it(problems: Path, tmp_path: Path) -> None:
    output = tmp_path / "collisions.parquet"
    assert export([problems], output, "parquet", "dual") == 2
    frame = pd.read_parquet(output)
    assert list(frame.columns) == ["P", "q", "G", "h", "A", "b", "lb", "ub", "name"]
    for _, row in frame.iterrows():
        problem = files.load(problems / f"{row['name']}.npz")
        n = row["q"].size
        # qpbenchmark reshapes P to (P.size // n, n), row by row
        assert np.array_equal(row["P"].reshape(-1, n), problem.Q.toarray())
        assert np.array_equal(row["q"], problem.b)
        assert np.array_equal(row["lb"], np.zeros(n))
        assert row["G"] is None and row["A"] is None and row["ub"] is None


def test_mat_files_hold_the_dual_and_the_primal(problems: Path, tmp_path: Path) -> None:
    assert export([problems], tmp_path / "dual", "mat", "dual") == 2
    problem = files.load(problems / "row3.npz")
    dual = scipy.io.loadmat(tmp_path / "dual" / "row3.mat")
    assert np.allclose(dual["P"].toarray(), problem.Q.toarray())
    assert np.allclose(dual["q"].ravel(), problem.b) and np.all(dual["lb"] == 0)

    export([problems], tmp_path / "primal", "mat", "primal")
    primal = scipy.io.loadmat(tmp_path / "primal" / "row3.mat")
    qp = primal_qp(problem)
    # G x <= h is A v >= lower: at the reference v+ it holds, and with equality where l > 0
    v_plus = problem.reference.v_plus[qp.free]
    slack = primal["h"].ravel() - primal["G"] @ v_plus
    assert np.all(slack >= -1e-12)
    assert np.allclose(slack[problem.reference.impulses > 1e-12], 0.0, atol=1e-12)
    assert np.allclose(primal["P"].toarray(), np.diag(1.0 / problem.m_inv))


def test_cli_export_of_a_missing_file_is_one_line_and_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["export", str(tmp_path / "nope.npz"), "-o", str(tmp_path / "x.parquet")])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1 and "nope.npz" in error
    assert not (tmp_path / "x.parquet").exists()
