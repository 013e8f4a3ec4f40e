"""Export: qpbenchmark's Parquet problem list and one .mat per problem, readable back;
frictional problems as their ccp relaxation; nothing half-written."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
from bench_problems import write_tiny_problems
from friction_cases import pair_on_floor

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


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of one frictionless and one frictional problem (3 contacts, mu 0.5)."""
    folder = tmp_path_factory.mktemp("mixed")
    write_tiny_problems(folder, count=1)
    files.save(pair_on_floor(mu=0.5), folder / "pair")
    return folder


def test_a_frictional_problem_is_exported_as_its_ccp_relaxation(
        mixed: Path, tmp_path: Path) -> None:
    frictional = files.load(mixed / "pair.npz")
    relaxed = frictional.relaxed()
    assert export([mixed], tmp_path / "mat", "mat", "dual") == 2
    pair = scipy.io.loadmat(tmp_path / "mat" / "pair.mat")
    assert str(pair["model"][0]) == "ccp" and np.array_equal(pair["mu"].ravel(), frictional.mu)
    assert pair["P"].shape == (6, 6)  # z = (z+, z-): two unknowns per contact
    assert np.allclose(pair["P"].toarray(), relaxed.Q.toarray())
    assert np.allclose(pair["q"].ravel(), relaxed.b) and np.all(pair["lb"] == 0)
    assert str(scipy.io.loadmat(tmp_path / "mat" / "row3.mat")["model"][0]) == "impact"

    assert export([mixed], tmp_path / "list.parquet", "parquet", "primal") == 2
    frame = pd.read_parquet(tmp_path / "list.parquet").set_index("name")
    qp = primal_qp(relaxed)
    assert np.allclose(frame.loc["pair", "h"], -qp.lower)
    assert np.array_equal(frame.loc["pair", "G"].reshape(6, -1), -qp.A.toarray())  # row per
    # relaxed contact, a column per free degree of freedom
    assert frame.loc["row3", "lb"] is None


def test_the_readme_command_exports_a_mixed_folder(
        mixed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for fmt, output in (("mat", tmp_path / "mat"), ("parquet", tmp_path / "p.parquet")):
        assert main(["export", str(mixed), "--format", fmt, "-o", str(output)]) == 0
        assert "2 problems" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path / "mat")) == ["pair.mat", "row3.mat"]


def test_a_bad_problem_among_good_ones_leaves_no_mat_file(
        mixed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "problems"
    shutil.copytree(mixed, folder)
    (folder / "zz-broken.npz").write_bytes(b"not an archive")  # read after the good ones
    output = tmp_path / "mat"
    assert main(["export", str(folder), "--format", "mat", "-o", str(output)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "zz-broken.npz" in error
    assert os.listdir(output) == []  # neither the two written first nor any temporary file


def test_two_problems_of_one_name_are_refused_for_mat(
        mixed: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "copy").mkdir()
    shutil.copy(mixed / "row3.npz", tmp_path / "copy" / "row3.npz")
    output = tmp_path / "mat"
    code = main(["export", str(mixed), str(tmp_path / "copy"), "--format", "mat",
                 "-o", str(output)])
    assert code == 2 and "problem name 'row3'" in capsys.readouterr().err
    assert os.listdir(output) == []


def test_mat_output_that_is_a_file_is_refused_before_reading(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "out").write_text("a file")
    code = main(["export", str(tmp_path / "missing"), "--format", "mat",
                 "-o", str(tmp_path / "out")])
    assert code == 2 and "out: is a file; --format mat writes a folder" in capsys.readouterr().err
