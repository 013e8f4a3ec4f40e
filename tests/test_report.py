"""The report: tables, figures that exist, the targets of our own solver, extra sections."""

from __future__ import annotations

import importlib
import json
import re
from pathlib import Path

import pandas as pd
import pytest
from bench_problems import write_tiny_problems
from friction_cases import ball_on_floor

from qpbench.bench import stats
from qpbench.bench.report import write_report
from qpbench.bench.results import ResultStore
from qpbench.bench.runner import complete_row
from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.errors import InputError
from qpbench.problem import files

LEVELS = (1e-4, 1e-6, 1e-8)
SOLVERS = ("test-exact/lcp", "clarabel/dual", "osqp/dual")


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Real solves (in this process) of two tiny problems by three solvers at three levels,
    cold and warm, stored as a results file."""
    folder = tmp_path_factory.mktemp("bench")
    limits = Limits(timeout_s=10.0)
    rows = []
    with importlib.import_module("bench_solvers").registered():
        solver = CellSolver()
        for path in write_tiny_problems(folder / "problems", count=2):
            problem = files.load(path)
            for key in SOLVERS:
                name, formulation = key.split("/")
                for accuracy in LEVELS:
                    for mode in ("cold", "warm"):
                        cell = Cell(str(path), problem.name, name, formulation, accuracy, mode)
                        rows.append(complete_row(solver.solve(cell, limits), cell,
                                                 problem.summary(), limits))
    store = ResultStore(folder / "bench.parquet")
    store.write_part(rows)
    store.compact()
    return store.path


def test_report_has_every_section_and_its_figures_exist(results: Path, tmp_path: Path) -> None:
    report = write_report(results, tmp_path / "out")
    text = report.read_text()
    for heading in ("## Machine and versions", "## Per accuracy level", "### Accuracy 1e-06",
                    "## Success by family", "## Formulations side by side",
                    "## Work-precision diagrams",
                    "### Family k3", "### Family row", "## Performance profiles",
                    "## What accuracy costs", "## Status honesty", "## Warm against cold",
                    "## Targets of our own solver", "## Accuracy options"):
        assert heading in text, heading
    assert "timer overhead" in text and "clarabel/dual" in text
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    names = {Path(image).name for image in images}
    assert {"work_precision_k3.png", "work_precision_row.png", "profile_1e-04.png",
            "profile_1e-08.png", "success_by_level.png", "cost_of_accuracy.png",
            "time_by_size.png"} <= names
    for image in images:
        assert (report.parent / image).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", image
    # the cost-of-accuracy table has the level-to-level ratio columns
    assert "1e-04 -> 1e-06" in text and "1e-06 -> 1e-08" in text


def test_report_shows_the_targets_of_our_own_solver_with_the_figures(
        results: Path, tmp_path: Path) -> None:
    # the exact test solver's rows, relabelled, stand in for our own solver pi-robust
    frame = ResultStore(results).read()
    own = frame[frame["solver"] == "test-exact"].assign(solver="pi-robust", backend="qpbench")
    relabelled = tmp_path / "relabelled.parquet"
    store = ResultStore(relabelled)
    store.write_part(pd.concat([frame[frame["solver"] != "test-exact"], own])
                     .to_dict("records"))
    store.compact()
    text = write_report(relabelled, tmp_path).read_text()
    section = text.split("## Targets of our own solver", 1)[1].split("\n## ", 1)[0]
    # only K3 (family k3) is a hard family here, one cold solve at 1e-8, exact
    assert "succeeds on 100.0% of 1 hard-family solves" in section
    assert "**met**" in section.split("\n2.")[0]
    cold = frame[(frame["mode"] == "cold")]
    shift = stats.time_scale_shift(cold)
    hard = cold[(cold["family"] == "k3") & (cold["accuracy"] == 1e-8)]
    sgm = {solver: stats.shifted_geometric_mean(stats.charged_times(group), shift)
           for solver, group in hard.groupby("solver")}
    fastest = min(("clarabel", "osqp"), key=sgm.get)
    assert f"Fastest external backend `{fastest}/dual`" in section
    assert f"ratio {sgm[fastest] / sgm['test-exact']:.2f}" in section


def test_report_takes_extra_sections_from_json_files_beside_the_results(
        results: Path, tmp_path: Path) -> None:
    (results.parent / "scaling.json").write_text(json.dumps(
        {"markdown": "Simulator steps per second: 1234.", "steps": 10}))
    (results.parent / "unrelated.json").write_text(json.dumps({"no": "markdown"}))
    text = write_report(results, tmp_path).read_text()
    assert "## Scaling\n\nSimulator steps per second: 1234." in text
    assert "unrelated" not in text.lower()


def test_report_of_a_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such results file"):
        write_report(tmp_path / "missing.parquet")


@pytest.fixture(scope="module")
def frictional_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Real solves of a sticking and a sliding ball by nsgs, Lemke, a staggered and a ccp
    pair at two levels."""
    folder = tmp_path_factory.mktemp("friction")
    limits = Limits(timeout_s=10.0)
    solver = CellSolver()
    rows = []
    for problem in (ball_on_floor(-2.0, 0.6, 0.5, name="sticks", family="floor"),
                    ball_on_floor(-2.0, 3.0, 0.5, name="slides", family="floor")):
        path = files.save(problem, folder / problem.name)
        for key in ("nsgs/nsgs", "lemke/lcp", "clarabel/staggered", "clarabel/ccp"):
            name, formulation = key.split("/")
            for accuracy in (1e-4, 1e-8):
                cell = Cell(str(path), problem.name, name, formulation, accuracy, "cold")
                rows.append(complete_row(solver.solve(cell, limits), cell, problem.summary(),
                                         limits))
    store = ResultStore(folder / "bench.parquet")
    store.write_part(rows)
    store.compact()
    return store.path


def test_a_friction_only_table_gets_its_friction_section(frictional_results: Path,
                                                         tmp_path: Path) -> None:
    text = write_report(frictional_results, tmp_path).read_text()
    assert "_No frictionless problems in these results._" in text
    friction = text.split("## Friction\n", 1)[1].split("\n## ", 1)[0]
    assert "2 frictional problems (floor), 0 of them without a solution" in friction
    for formulation in ("ccp", "lcp", "nsgs", "staggered"):
        assert f"| 1e-08 | {formulation} |" in friction
    assert "### Inner backends of `staggered`" in friction
    # the sliding ball separates in the relaxed model: its Coulomb residual is not zero
    assert "### Model error of `ccp`" in friction
    row = friction.split("### Model error of `ccp`", 1)[1].split("| floor |", 1)[1]
    assert float(row.split("|")[1]) > 1e-3


def test_frictional_rows_stay_out_of_the_frictionless_tables(
        results: Path, frictional_results: Path, tmp_path: Path) -> None:
    both = ResultStore(tmp_path / "both.parquet")
    both.write_part(pd.concat([ResultStore(results).read(),
                               ResultStore(frictional_results).read()]).to_dict("records"))
    both.compact()
    text = write_report(both.path, tmp_path / "out").read_text()
    levels = text.split("## Per accuracy level", 1)[1].split("## Friction", 1)[0]
    assert "nsgs/nsgs" not in levels and "clarabel/dual" in levels
    assert "2 frictional problems" in text
