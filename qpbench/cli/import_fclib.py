"""``qpbench import-fclib FILE... [--no-reference] -o DIR``: FCLIB HDF5
files (2D, local or global) to problem files."""

from __future__ import annotations

import argparse

from qpbench.cli.imported import save_imported
from qpbench.problem import fclib


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
    save_imported(problems, args.output, "import-fclib", not args.no_reference)
    return 0
