"""results/index.html: written by the report, self-contained, and working in a real headless
browser (Debian's chromium driven by Playwright): plots render, legend entries hide traces,
the table sorts and filters, nothing is fetched."""

from __future__ import annotations

import importlib
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bench_problems import write_tiny_problems
from friction_cases import ball_on_floor

from qpbench.bench import html_report, stats
from qpbench.bench.report import write_report
from qpbench.bench.results import ResultStore, split_kinds
from qpbench.bench.runner import complete_row
from qpbench.bench.settings import Cell, Limits
from qpbench.bench.worker import CellSolver
from qpbench.errors import InputError
from qpbench.problem import files

LEVELS = (1e-4, 1e-8)
SOLVERS = ("test-exact/lcp", "clarabel/dual", "osqp/dual")
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def _store(folder: Path, rows: list[dict]) -> Path:
    store = ResultStore(folder / "bench.parquet")
    store.write_part(rows)
    store.compact()
    return store.path


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Real in-process solves of two tiny problems by three pairs at two levels, and of two
    frictional balls by two pairs."""
    folder = tmp_path_factory.mktemp("html")
    limits = Limits(timeout_s=10.0)
    rows = []
    with importlib.import_module("bench_solvers").registered():
        solver = CellSolver()
        cells = [(path, key) for path in write_tiny_problems(folder / "problems", count=2)
                 for key in SOLVERS]
        for problem in (ball_on_floor(-2.0, 0.6, 0.5, name="sticks", family="floor"),
                        ball_on_floor(-2.0, 3.0, 0.5, name="slides", family="floor")):
            path = files.save(problem, folder / "problems" / problem.name)
            cells += [(path, key) for key in ("nsgs/nsgs", "clarabel/ccp")]
        for path, key in cells:
            problem = files.load(path)
            name, formulation = key.split("/")
            for accuracy in LEVELS:
                cell = Cell(str(path), problem.name, name, formulation, accuracy, "cold")
                rows.append(complete_row(solver.solve(cell, limits), cell, problem.summary(),
                                         limits))
    return _store(folder, rows)


@pytest.fixture(scope="module")
def page(results: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    report = write_report(results, tmp_path_factory.mktemp("out"))
    return report.parent / "index.html"


def test_the_report_writes_index_html_and_points_to_it(page: Path) -> None:
    assert page.exists()
    assert "[index.html](index.html)" in (page.parent / "REPORT.md").read_text()
    text = page.read_text()
    assert text.count("Plotly=") >= 1 and "<script src" not in text
    sections = ("comparison", "accuracy-cost", "wrappers", "answer", "work-precision",
                "profiles", "results", "problem", "friction", "provenance")
    for section in sections:
        assert f"id='{section}'" in text, section
    # the comparison leads, then every section that was there before
    assert re.findall(r"<section id='([^']+)'", text) == list(sections)


def test_the_frontier_is_the_fastest_pair_that_solves_enough(results: Path) -> None:
    frame, _ = split_kinds(ResultStore(results).read())
    rows = html_report.frontier(frame)
    shift = stats.time_scale_shift(frame)
    summary = stats.level_summary(frame, shift)
    fast = html_report.level_summary(frame, shift)
    for column in ("success_rate", "sgm_time_s", "median_residual"):
        assert list(fast[column].round(12)) == list(summary[column].round(12)), column
    for row in (r for r in rows if r["family"] == html_report.ALL):
        at_level = summary[(summary["accuracy"] == row["level"])
                           & (summary["success_rate"] >= html_report.FRONTIER_SUCCESS)]
        assert row["pair"] == at_level.sort_values("sgm_time_s").iloc[0]["solver"]
    tight = [r for r in rows if r["family"] == html_report.ALL]
    assert tight[0]["per_digit"] is None and tight[1]["per_digit"] == pytest.approx(
        (tight[1]["time"] / tight[0]["time"]) ** 0.25)


def test_small_and_odd_tables_give_a_page_or_the_refusal(results: Path, tmp_path: Path) -> None:
    frictionless, frictional = split_kinds(ResultStore(results).read())
    one = frictionless[(frictionless["solver"] == "clarabel")
                       & (frictionless["problem"] == frictionless["problem"].iloc[0])]
    cases = {"one": one, "friction": frictional, "one-level": frictionless[
        np.isclose(frictionless["accuracy"].astype(float), 1e-8)]}
    for name, rows in cases.items():
        path = _store(tmp_path / name, rows.to_dict("records"))
        if name == "one-level":  # the page alone: the PNGs of REPORT.md are tested elsewhere
            html_report.write_html(rows, tmp_path / f"{name}-out", path.name)
        else:
            write_report(path, tmp_path / f"{name}-out")
        text = (tmp_path / f"{name}-out" / "index.html").read_text()
        assert "qpbench: what accuracy costs" in text, name
    assert "No frictionless problems" in (tmp_path / "friction-out" / "index.html").read_text()
    empty = _store(tmp_path / "empty", [])
    with pytest.raises(InputError):
        write_report(empty, tmp_path / "empty-out")


@pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="needs Debian's chromium")
def test_the_page_works_in_a_headless_browser(page: Path) -> None:
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            tab = browser.new_page()
            errors: list[str] = []
            requests: list[str] = []
            tab.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            tab.on("pageerror", lambda e: errors.append(str(e)))
            tab.on("request", lambda r: requests.append(r.url))
            tab.goto(page.as_uri(), wait_until="load")
            tab.wait_for_selector("#wp .scatterlayer .trace")
            plots = tab.query_selector_all(".js-plotly-plot")
            ids = {plot.get_attribute("id") for plot in plots}
            assert {"frontier-plot", "wp", "profile-0", "profile-1", "problem-plot",
                    "fwp"} <= ids
            for plot in plots:
                assert plot.query_selector_all(".scatterlayer .trace"), plot.get_attribute("id")
            for plot_id in ("wp", "problem-plot", "fwp"):
                assert tab.query_selector_all(f"#{plot_id} path.point"), plot_id

            # hiding a legend entry removes its trace
            def visible(plot_id: str) -> list:
                return tab.evaluate(f"document.getElementById('{plot_id}').data"
                                    ".map((t) => t.visible)")

            before = len(tab.query_selector_all("#wp .scatterlayer .trace"))
            assert visible("wp")[0] is True
            tab.click("#wp .legend .traces >> nth=0")
            tab.wait_for_function("document.getElementById('wp').data[0].visible"
                                  " === 'legendonly'")
            assert len(tab.query_selector_all("#wp .scatterlayer .trace")) == before - 1

            # the table sorts on a header click and filters
            def column(index: int) -> list[str]:
                return tab.eval_on_selector_all(
                    f"#results-table tbody tr td:nth-child({index})",
                    "(cells) => cells.map((c) => c.textContent)")

            tab.click("#results-table th[data-col='7']")
            times = [float(t) for t in column(8) if t != "-"]
            assert times == sorted(times) and len(times) > 2
            tab.click("#results-table th[data-col='7']")
            times = [float(t) for t in column(8) if t != "-"]
            assert times == sorted(times, reverse=True)
            everything = len(column(1))
            tab.select_option("#filters select[data-filter='4']", "1e-08")
            assert set(column(5)) == {"1e-08"} and len(column(1)) < everything
            tab.fill("#pair-filter", "osqp")
            assert set(column(2)) == {"osqp/dual"}

            # the per-problem view redraws for another problem
            names = tab.eval_on_selector_all("#problem-select option",
                                             "(o) => o.map((x) => x.value)")
            tab.select_option("#problem-select", names[-1])
            assert names[-1] in (tab.text_content("#problem-plot .gtitle") or "")
            assert not errors, errors
            assert all(url.startswith(("file://", "data:")) for url in requests), requests
        finally:
            browser.close()


def test_the_embedded_data_is_json(page: Path) -> None:
    text = page.read_text()
    start = text.index('id="qpbench-data">') + len('id="qpbench-data">')
    data = json.loads(text[start:text.index("</script>", start)].replace("<\\/", "</"))
    assert len(data["main"]["pairs"]) == len(SOLVERS)
    assert {row[0] for row in data["table"]} >= {html_report.ALL}
    assert data["friction"]["error"] == "coulomb_residual"
    assert pd.Series(data["main"]["time"]).notna().any()


# --- the comparison and what accuracy costs, on a synthetic table ------------------------------
# pair -> (backend, time at the loosest level [s], factor per level)
SYNTHETIC_PAIRS = {"own/lcp": ("qpbench", 2e-5, 1.0), "flat/dual": ("qpsolvers", 5e-5, 1.0),
                   "grow/dual": ("qpsolvers", 3e-5, 4.0), "solo-native/dual": ("native", 4e-5, 1.0),
                   "solo/dual": ("qpsolvers", 8e-5, 1.0),
                   "cvxpy-solo/dual": ("cvxpy", 4e-4, 1.0)}
SYNTHETIC_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8)


@pytest.fixture(scope="module")
def synthetic_page(tmp_path_factory: pytest.TempPathFactory) -> str:
    """index.html of made-up solves of two problems: every solve succeeds, in the pair's time
    times its factor per level to the power of the level's index."""
    folder = tmp_path_factory.mktemp("synthetic")
    rows = [{"problem": problem, "family": "f", "solver": key.split("/")[0],
             "formulation": key.split("/")[1], "backend": backend, "accuracy": accuracy,
             "mode": "cold", "status": "solved", "success": True, "claimed_success": True,
             "residual": accuracy / 10, "v_error": 1e-9, "time_limit_s": 1.0, "contacts": 2,
             "time_s": time_s * (1 + index / 10) * factor ** step}
            for index, problem in enumerate(("p0", "p1"))
            for key, (backend, time_s, factor) in SYNTHETIC_PAIRS.items()
            for step, accuracy in enumerate(SYNTHETIC_LEVELS)]
    path = _store(folder, rows)
    return html_report.write_html(ResultStore(path).read(), folder, path.name).read_text()


def _embedded(text: str) -> dict:
    start = text.index('id="qpbench-data">') + len('id="qpbench-data">')
    return json.loads(text[start:text.index("</script>", start)].replace("<\\/", "</"))


def test_the_accuracy_cost_chart_draws_the_pairs_whose_time_grows(synthetic_page: str) -> None:
    cost = _embedded(synthetic_page)["accuracy_cost"]
    assert cost["levels"] == list(SYNTHETIC_LEVELS)
    assert [pair["key"] for pair in cost["pairs"]] == ["grow/dual"]
    assert cost["pairs"][0]["relative"] == [1.0, 4.0, 16.0, 64.0]
    assert "id='accuracy-cost-plot'" in synthetic_page


def test_the_page_leads_with_the_fastest_pair_of_each_formulation(synthetic_page: str) -> None:
    comparison = synthetic_page.split("<section id='comparison'>", 1)[1].split("</section>")[0]
    tables = re.findall(r"<table class='static comparison' data-level='([^']+)'>(.*?)</table>",
                        comparison)
    assert [level for level, _ in tables] == ["1e-02", "1e-04", "1e-06", "1e-08"]
    for level, table in tables:
        cells = dict(re.findall(r"data-column='([^']+)' data-pair='([^']+)'",
                                table.split("<th>f</th>", 1)[1]))
        # grow/dual is the fastest dual pair at 1e-02 only; then flat-timed solo-native/dual
        fastest_dual = "grow/dual" if level == "1e-02" else "solo-native/dual"
        assert cells == {"dual": fastest_dual, "lcp": "own/lcp", "external": fastest_dual,
                         "ours": "own/lcp"}, level


def test_the_wrapper_table_pairs_a_native_pair_with_its_twins_on_the_page(
        synthetic_page: str) -> None:
    wrappers = synthetic_page.split("<section id='wrappers'>", 1)[1].split("</section>")[0]
    rows = [re.sub(r"<[^>]+>", "", row).split("|") for row in re.findall(
        r"<tr>(.*?)</tr>", wrappers.replace("</td><td>", "|"))[1:]]
    assert rows == [["solo-native/dual", "qpsolvers", "solo/dual", "8", "100.0%", "100.0%",
                     "8", "2"],
                    ["solo-native/dual", "cvxpy", "cvxpy-solo/dual", "8", "100.0%", "100.0%",
                     "8", "10"]]
