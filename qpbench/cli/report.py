"""``qpbench report FILE.parquet [-o DIR] [--budget S] [--[no-]progress]``: REPORT.md, its figures
and index.html, then a closing summary: where they are and the fastest pair per level."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import pandas as pd

from qpbench.bench import html_report, plots, stats
from qpbench.bench.report import write_report
from qpbench.bench.results import ResultStore, split_kinds
from qpbench.cli.guards import add_progress_option, progress_wanted
from qpbench.cli.output import duration
from qpbench.cli.progress import Progress
from qpbench.studies import targets

# the columns the closing summary reads (html_report.frontier over every problem)
SUMMARY_COLUMNS = ("problem", "family", "kind", "mode", "solver", "formulation", "backend",
                   "accuracy", "success", "residual", "time_s", "time_limit_s")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench report`` and its options (results, ``-o``, ``--budget``, progress).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "report", help="write REPORT.md, plots and index.html from a results file",
        epilog="Progress (each figure and index.html as it is written) goes to stderr; the "
               "closing summary to stdout: where REPORT.md, its figures and index.html are, "
               "and per accuracy level the fastest pair that solves at least 95% of the "
               "frictionless problems.")
    parser.add_argument("results", help="results file written by qpbench run (.parquet)")
    parser.add_argument("-o", "--output", default=None,
                        help="folder for REPORT.md and figures/ (default: beside the results)")
    parser.add_argument("--budget", type=float, default=None,
                        help="time budget per solve for the accuracy-within-budget table "
                             "(default: the SGM shift)")
    add_progress_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Write REPORT.md, its figures and index.html, then print where they are and the fastest pairs.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``results``, ``output``, ``budget`` and
        ``progress``.

    Returns
    -------
    int
        The exit status: 0.
    """
    written: list[Path] = []
    with Progress("report", progress_wanted(args), None, "files") as progress:
        def starting(path: Path) -> None:
            written.append(path)
            progress.advance(1, path.name)

        with plots.on_figure(starting), html_report.on_page(starting):
            report = write_report(args.results, args.output, budget_s=args.budget,
                                  sections=targets.SECTIONS)
    figures = sum(path.suffix == ".png" for path in written)
    folder = report.parent
    print(f"REPORT.md:  {report}")
    print(f"index.html: {folder / 'index.html'}")
    print(f"figures:    {folder / 'figures'} ({figures} written)")
    for line in fastest_pairs(ResultStore(args.results).read(SUMMARY_COLUMNS)):
        print(line)
    return 0


def fastest_pairs(frame: pd.DataFrame) -> list[str]:
    """List the fastest pair per accuracy level, for the closing summary.

    Lines naming, per accuracy level (loosest first), the pair with the lowest shifted
    geometric mean time among those that solve at least 95% of the frictionless problems
    (cold starts where there are), as the "all problems" row of the report's frontier, and
    the fastest external pair (a backend not written here) by the same rule.

    Parameters
    ----------
    frame : pd.DataFrame
        Result rows with at least SUMMARY_COLUMNS.

    Returns
    -------
    list of str
        A heading line, then one line per level; one line saying so when there is no
        frictionless problem.
    """
    main, _ = split_kinds(frame)
    cold = main[main["mode"].astype(str) == "cold"]
    main = cold if not cold.empty else main
    if main.empty:
        return ["no frictionless problems in these results"]
    shift = stats.time_scale_shift(main)
    rows = html_report.frontier(main, [(html_report.ALL, shift,
                                        html_report.level_summary(main, shift))])
    external = main[main["backend"].astype(str) != stats.OWN_BACKEND]
    external_rows = {row["level"]: row for row in html_report.frontier(
        external, [(html_report.ALL, shift, html_report.level_summary(external, shift))])
        } if not external.empty else {}
    share = f"{html_report.FRONTIER_SUCCESS:.0%}"
    problems = main["problem"].nunique()
    lines = [f"fastest pair per level among those solving at least {share} of the {problems} "
             f"frictionless problem{'s' if problems != 1 else ''} (shifted geometric mean "
             "time, failures charged the limit):"]
    for row in rows:
        level = f"{row['level']:.0e}"
        if row["pair"] is None:
            lines.append(f"  {level}  none solves {share} of them")
        else:
            lines.append(f"  {level}  {_pair(row)}"
                         + _external(external_rows.get(row["level"]), row["pair"]))
    return lines


def _pair(row: dict[str, Any]) -> str:
    return f"{row['pair']} {duration(row['time'])} ({row['success']:.0%} solved)"


def _external(row: dict[str, Any] | None, fastest: str) -> str:
    """``; fastest external: PAIR TIME (SHARE solved)`` unless that pair is ``fastest``."""
    if row is None or row["pair"] is None or row["pair"] == fastest:
        return ""
    return f"; fastest external: {_pair(row)}"
