"""``qpbench import-fclib FILE... [--no-reference] -o DIR``: FCLIB HDF5
files (2D, local or global) to problem files."""

from __future__ import annotations

import argparse
import sys

from qpbench.bench.reduced_reference import attach, flag
from qpbench.problem import fclib, files


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "import-fclib", help="import FCLIB HDF5 files (2D, local or global) as problems")
    parser.add_argument("files", nargs="+", metavar="FILE", help="FCLIB .hdf5 files")
    parser.add_argument("--no-reference", action="store_true", help="skip reference solutions")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    # read and check every file before writing anything
    problems = [fclib.read(path) for path in args.files]
    for problem in problems:
        if not args.no_reference:
            attach(problem)
            why = flag(problem)
            if why:
                print(f"qpbench import-fclib: {problem.name}: reference flagged: {why}",
                      file=sys.stderr)
        print(files.save(problem, f"{args.output}/{problem.name}"))
    return 0
