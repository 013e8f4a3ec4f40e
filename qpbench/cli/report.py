"""``qpbench report FILE.parquet [-o DIR] [--budget S]``: REPORT.md and its figures."""

from __future__ import annotations

import argparse

from qpbench.bench.report import write_report


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("report", help="write REPORT.md and plots from a results file")
    parser.add_argument("results", help="results file written by qpbench run (.parquet)")
    parser.add_argument("-o", "--output", default=None,
                        help="folder for REPORT.md and figures/ (default: beside the results)")
    parser.add_argument("--budget", type=float, default=None,
                        help="time budget per solve for the accuracy-within-budget table "
                             "(default: the SGM shift)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    report = write_report(args.results, args.output, budget_s=args.budget)
    print(report)
    return 0
