"""results/index.html: written by the report, self-contained, and working in a real headless
browser (Debian's chromium driven by Playwright): plots render, legend entries hide traces,
the table sorts and filters, nothing is fetched."""

from __future__ import annotations

import importlib
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bench_problems import write_tiny_problems
from friction_cases import ball_on_floor

from qpbench.bench import html_report, stats
from qpbench.bench.report import split_kinds, write_report
from qpbench.bench.results import ResultStore
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
    for section in ("answer", "work-precision", "profiles", "results", "problem", "friction",
                    "provenance"):
        assert f"id='{section}'" in text, section


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
