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

from qpbench.bench import reduced_reference, stats
from qpbench.bench.report import write_report
from qpbench.bench.results import ResultStore, split_kinds
from qpbench.bench.runner import complete_row, fingerprint
from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.errors import InputError
from qpbench.problem import files
from qpbench.problem.siconos_import import import_siconos
from qpbench.studies import targets

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
    report = write_report(results, tmp_path / "out", sections=targets.SECTIONS)
    text = report.read_text()
    for heading in ("## Fastest pairs, per family and level", "## What accuracy costs, where",
                    "## Wrapper costs", "## Machine and versions", "## Per accuracy level",
                    "### Accuracy 1e-06", "## Success by family", "## Formulations side by side",
                    "## Work-precision diagrams",
                    "### Family k3", "### Family row", "## Performance profiles",
                    "## Time at each level, the most reliable pairs", "## Status honesty",
                    "## Warm against cold", "## pi-robust: its targets",
                    "## Accuracy options"):
        assert heading in text, heading
    assert "timer overhead" in text and "clarabel/dual" in text
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    names = {Path(image).name for image in images}
    # (the cost-of-accuracy chart needs a pair whose time grows with the level: real solves
    # of two tiny problems need not have one, the synthetic table below does)
    assert {"work_precision_k3.png", "work_precision_row.png", "profile_1e-04.png",
            "profile_1e-08.png", "success_by_level.png", "time_by_size.png"} <= names
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
    text = write_report(relabelled, tmp_path, sections=targets.SECTIONS).read_text()
    section = text.split("## pi-robust: its targets", 1)[1].split("\n## ", 1)[0]
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


def test_report_names_no_solver_of_its_own_unless_its_caller_brings_the_section(
        results: Path, tmp_path: Path) -> None:
    """The harness's report knows no solver: the targets of pi-robust are a study's section,
    placed after the comparison of every pair and the frictionless tables, when it is handed
    in; the report leads with the comparison."""
    neutral = write_report(results, tmp_path / "neutral").read_text()
    assert "## pi-robust: its targets" not in neutral
    studied = write_report(results, tmp_path / "studied", sections=targets.SECTIONS).read_text()
    headings = re.findall(r"^## (.+)$", studied, flags=re.MULTILINE)
    assert headings[:4] == ["Fastest pairs, per family and level",
                            "What accuracy costs, where it costs", "Wrapper costs", "Summary"]
    assert headings.index(targets.TITLE) > headings.index(
        "Time at each level, the most reliable pairs")


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
    # the report leads with the frictional comparison: a column per formulation
    lead = text.split("## Fastest pairs, per family and level", 1)[1].split("\n## ", 1)[0]
    row = _table_rows(lead, "### Frictional problems, accuracy 1e-08")["floor"]
    assert list(row) == ["family", "lcp", "nsgs", "staggered", "ccp", "fastest external",
                         "fastest of ours", "external / ours"]
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


# --- the comparison, what accuracy costs and the wrapper costs on a synthetic table ------------
SYNTHETIC_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8)
SYNTHETIC_PROBLEMS = {"a0": "a", "a1": "a", "b0": "b", "b1": "b"}
# pair -> (backend, time at 1e-2 [s], factor per level, problems it fails at every level)
SYNTHETIC_PAIRS = {
    "own/lcp": ("qpbench", 2e-5, 1.0, ()),
    "slow-own/lcp": ("qpbench", 9e-5, 1.0, ()),
    "quick/dual": ("qpsolvers", 4e-5, 1.0, ()),
    "flaky/dual": ("qpsolvers", 1e-5, 1.0, ("b1",)),  # the fastest, but solves half of b
    "grow/primal": ("cvxpy", 3e-5, 4.0, ()),  # iterative: 4 x the time every two digits
    "lone-native/dual": ("native", 5e-5, 1.0, ()),
    "lone/dual": ("qpsolvers", 1e-4, 1.0, ()),  # the native pair's qpsolvers twin: 2 x
    "cvxpy-lone/dual": ("cvxpy", 5e-4, 1.0, ("a0",)),  # ... its cvxpy twin: 10 x, fails a0
}


def synthetic_rows() -> list[dict]:
    """Every pair on every problem at every level, cold, with made-up times: a solve of
    problem i takes the pair's time x (1 + i / 10) x its factor per level to the power of the
    level's index."""
    rows = []
    for index, (problem, family) in enumerate(SYNTHETIC_PROBLEMS.items()):
        for key, (backend, time_s, factor, fails) in SYNTHETIC_PAIRS.items():
            solver, formulation = key.split("/")
            for step, accuracy in enumerate(SYNTHETIC_LEVELS):
                solved = problem not in fails
                rows.append({
                    "problem": problem, "family": family, "solver": solver,
                    "formulation": formulation, "backend": backend, "accuracy": accuracy,
                    "mode": "cold", "status": "solved" if solved else "failed",
                    "success": solved, "claimed_success": solved,
                    "residual": accuracy / 10 if solved else 1.0, "v_error": 1e-9,
                    "time_s": time_s * (1 + index / 10) * factor ** step,
                    "time_limit_s": 1.0, "contacts": 3})
    return rows


@pytest.fixture(scope="module")
def synthetic_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("synthetic")
    store = ResultStore(folder / "bench.parquet")
    store.write_part(synthetic_rows())
    store.compact()
    return write_report(store.path, folder / "out")


def _table_rows(text: str, heading: str) -> dict[str, dict[str, str]]:
    """The first Markdown table after ``heading``: first cell -> column -> cell."""
    after = text.split(heading + "\n", 1)[1].splitlines()
    start = next(i for i, line in enumerate(after) if line.startswith("|"))
    lines = [line for line in after[start:] if line.startswith("|")]
    lines = lines[:next((i for i, line in enumerate(after[start:])
                         if not line.startswith("|")), len(lines))]
    header = [cell.strip() for cell in lines[0].strip("|").split(" | ")]
    return {cells[0]: dict(zip(header, cells, strict=True)) for cells in
            ([cell.strip() for cell in line.strip("|").split(" | ")] for line in lines[2:])}


def _expected_lead(frame: pd.DataFrame, family: str, accuracy: float) -> dict[str, str | None]:
    """The fastest pair of each formulation, the fastest external pair and the fastest of
    ours among the pairs solving at least 95% of ``family`` at ``accuracy``, by the shifted
    geometric mean of charged times with the family's own shift."""
    rows = frame if family == "all problems" else frame[frame["family"] == family]
    shift = stats.time_scale_shift(rows)
    at_level = rows[rows["accuracy"] == accuracy]
    scores = {}
    for key, group in at_level.groupby(stats.solver_keys(at_level)):
        if group["success"].mean() >= 0.95:
            scores[key] = stats.shifted_geometric_mean(stats.charged_times(group), shift)
    backend = {f"{solver}/{formulation}": backend for (solver, formulation), (backend, *_)
               in ((key.split("/"), value) for key, value in SYNTHETIC_PAIRS.items())}

    def fastest(keys: list[str]) -> str | None:
        return min(keys, key=scores.__getitem__) if keys else None

    expected = {formulation: fastest([k for k in scores if k.endswith("/" + formulation)])
                for formulation in ("dual", "lcp", "primal")}
    expected["fastest external"] = fastest([k for k in scores if backend[k] != "qpbench"])
    expected["fastest of ours"] = fastest([k for k in scores if backend[k] == "qpbench"])
    return expected


def test_the_report_leads_with_the_fastest_pair_of_each_formulation_per_family(
        synthetic_report: Path) -> None:
    text = synthetic_report.read_text()
    assert re.findall(r"^## (.+)$", text, flags=re.MULTILINE)[0] == \
        "Fastest pairs, per family and level"
    frame = pd.DataFrame(synthetic_rows())
    for accuracy in SYNTHETIC_LEVELS:
        table = _table_rows(text, f"### Accuracy {accuracy:.0e}")
        assert list(table) == ["all problems", "a", "b"]
        for family, row in table.items():
            expected = _expected_lead(frame, family, accuracy)
            for column, pair in expected.items():
                if pair is None:
                    assert row[column] == "-", (accuracy, family, column)
                elif column.startswith("fastest"):
                    assert row[column].startswith(f"`{pair}` "), (accuracy, family, column)
                else:
                    assert f"`{pair.split('/')[0]}` " in row[column], (accuracy, family, column)
    # flaky/dual is the fastest on a, but fails half of b: there quick/dual is the fastest dual
    loose = _table_rows(text, "### Accuracy 1e-02")
    assert "`flaky`" in loose["a"]["dual"] and "`quick`" in loose["b"]["dual"]
    assert loose["a"]["fastest external"].startswith("`flaky/dual`")
    assert loose["b"]["fastest external"].startswith("`grow/primal`")
    assert _table_rows(text, "### Accuracy 1e-08")["b"]["fastest external"].startswith(
        "`quick/dual`")
    # ours: own/lcp, the fastest row of b in bold; 4e-5 against 2e-5 (shifted) on b
    assert loose["b"]["lcp"].startswith("**`own`")
    assert float(loose["b"]["external / ours"]) > 1.0


def test_what_accuracy_costs_lists_only_the_pairs_whose_time_grows(
        synthetic_report: Path) -> None:
    text = synthetic_report.read_text()
    section = text.split("## What accuracy costs, where it costs\n", 1)[1].split("\n## ", 1)[0]
    table = _table_rows(section, "")
    assert list(table["per digit, all problems"])[1:] == ["grow/primal"]
    assert table["time 1e-08 / 1e-02"]["grow/primal"] == "64"
    assert table["per digit, a"]["grow/primal"] == "2"
    assert table["solves (>= 95.0%) down to"]["grow/primal"] == "1e-08"
    image = re.search(r"!\[cost of accuracy\]\(([^)]+)\)", section)
    assert image and (synthetic_report.parent / image.group(1)).read_bytes()[:4] == b"\x89PNG"


def test_the_wrapper_table_pairs_a_native_pair_with_its_twins(synthetic_report: Path) -> None:
    text = synthetic_report.read_text()
    section = text.split("## Wrapper costs\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `lone-native/dual`")]
    assert rows == [
        "| `lone-native/dual` | qpsolvers | `lone/dual` | 16 | 100.0% | 100.0% | 16 | 2 |",
        "| `lone-native/dual` | cvxpy | `cvxpy-lone/dual` | 16 | 100.0% | 75.0% | 12 | 10 |"]


# --- the imported problems described as Acary, Bremond and Huber do ------------------------
# one contact, W = [[2, 0.5], [0.5, 1]] in Siconos' (N, T) order, q = (-1, 0.3), mu = 0.5: a
# dense NumericsMatrix (column-major); eigenvalues 1.5 +- sqrt(0.5), so cond(W) = 2.78
FC2D_ONE_CONTACT = "2\n1\n0\n2\n2\n2\t2\n2 0.5\n0.5 1\n-1 0.3\n0.5\n"
# an LCP of two contacts with M = [[1, 1], [1, 1]] (PSD, rank 1), q = (-1, 0), M dense
LCP_RANK_ONE = "2\n0\n2\n2\n2\t2\n1 1\n1 1\n-1 0\n"


@pytest.fixture(scope="module")
def imported_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Real solves of a Siconos fc2d problem (by nsgs) and a Siconos LCP (by Lemke), imported
    and built as ``qpbench build-set`` builds them, stored with their fingerprints."""
    folder = tmp_path_factory.mktemp("imported")
    (folder / "fc2d_one_contact.dat").write_text(FC2D_ONE_CONTACT)
    (folder / "lcp_rank_one.dat").write_text(LCP_RANK_ONE)
    limits = Limits(timeout_s=10.0)
    solver = CellSolver()
    rows = []
    for name, key in (("fc2d_one_contact", "nsgs/nsgs"), ("lcp_rank_one", "lemke/lcp")):
        problem = reduced_reference.attach(import_siconos(folder / f"{name}.dat"))
        path = files.save(problem, folder / "problems" / name)
        summary = {**problem.summary(), "problem_hash": fingerprint(problem)}
        for accuracy in (1e-4, 1e-8):
            cell = Cell(str(path), name, *key.split("/"), accuracy, "cold")
            rows.append(complete_row(solver.solve(cell, limits), cell, summary, limits))
    store = ResultStore(folder / "bench.parquet")
    store.write_part(rows)
    store.compact()
    return store.path


def test_the_report_describes_each_imported_problem_as_abh_do(imported_results: Path,
                                                               tmp_path: Path) -> None:
    text = write_report(imported_results, tmp_path).read_text()
    table = _table_rows(text, "## Imported problems (Siconos, FCLIB)")
    assert list(table) == ["fc2d_one_contact", "lcp_rank_one"]
    assert table["fc2d_one_contact"] == {
        "problem": "fc2d_one_contact", "source": "fc2d_one_contact.dat", "format": "reduced",
        "contacts": "1", "dofs": "-", "density": "-", "rank deficiency": "0",
        "cond(W)": "2.78", "mu": "0.5"}
    # M of rank 1: one degree of freedom for two contacts, so a density of 2 and W singular
    assert table["lcp_rank_one"] == {
        "problem": "lcp_rank_one", "source": "lcp_rank_one.dat", "format": "lcp",
        "contacts": "2", "dofs": "1", "density": "2", "rank deficiency": "1",
        "cond(W)": "inf", "mu": "0"}
    page = (tmp_path / "index.html").read_text()
    assert "<section id='imported'>" in page and "<td>2.78</td>" in page


def test_an_imported_problem_whose_file_changed_is_listed_but_not_described(
        imported_results: Path, tmp_path: Path) -> None:
    frame = ResultStore(imported_results).read()
    frame.loc[frame["problem"] == "lcp_rank_one", "problem_hash"] = "0" * 16
    store = ResultStore(tmp_path / "changed.parquet")
    store.write_part(frame.to_dict("records"))
    store.compact()
    text = write_report(store.path, tmp_path / "out").read_text()
    table = _table_rows(text, "## Imported problems (Siconos, FCLIB)")
    assert table["lcp_rank_one"]["contacts"] == "2"
    assert table["lcp_rank_one"]["cond(W)"] == "-"
    assert table["fc2d_one_contact"]["cond(W)"] == "2.78"
    assert "1 of 2 problems not described" in text


def test_a_table_without_imported_problems_has_no_such_section(results: Path,
                                                              tmp_path: Path) -> None:
    assert "## Imported problems" not in write_report(results, tmp_path).read_text()


def test_a_problem_reduced_to_its_contacts_is_reported_with_the_frictional_ones() -> None:
    """Siconos' fc2d problems are of kind ``frictional-reduced`` in the table: they belong to
    the frictional sections, never to the frictionless tables (whose pairs solve no friction),
    and a row without a kind is frictionless."""
    frame = pd.DataFrame({"problem": ["k3", "rough-box", "fc2d_flow", "old"],
                          "kind": ["impact", "frictional", "frictional-reduced", None]})
    frictionless, frictional = split_kinds(frame)
    assert list(frictionless["problem"]) == ["k3", "old"]
    assert list(frictional["problem"]) == ["rough-box", "fc2d_flow"]
