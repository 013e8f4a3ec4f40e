"""``qpbench import-fclib FILE... [--no-reference] -o DIR``: FCLIB HDF5
files (2D, local or global) to problem files."""

from __future__ import annotations

import argparse

from qpbench.cli.imported import save_imported
from qpbench.problem import fclib


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench import-fclib`` and its options (files, ``--no-reference``, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "import-fclib", help="import FCLIB HDF5 files (2D, local or global) as problems")
    parser.add_argument("files", nargs="+", metavar="FILE", help="FCLIB .hdf5 files")
    parser.add_argument("--no-reference", action="store_true", help="skip reference solutions")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Read every FCLIB file, then write each as a problem file (:func:`save_imported`).

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``files``, ``no_reference`` and ``output``.

    Returns
    -------
    int
        The exit status: 0.
    """
    # read and check every file before writing anything
    problems = [fclib.read(path) for path in args.files]
    save_imported(problems, args.output, "import-fclib", not args.no_reference)
    return 0
