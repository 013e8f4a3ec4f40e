"""``qpbench import-siconos FILE... [--kind fc2d|gfc2d|lcp] [--no-reference] -o DIR``: Siconos'
text files to problem files."""

from __future__ import annotations

import argparse
import sys

from qpbench.cli.imported import save_imported
from qpbench.errors import UnsupportedError
from qpbench.problem import siconos_files
from qpbench.problem.siconos_import import import_siconos


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench import-siconos`` and its options (files, ``--kind``, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "import-siconos", help="import Siconos' fc2d, gfc2d and LCP text files as problems")
    parser.add_argument("files", nargs="+", metavar="FILE", help="Siconos .dat files")
    parser.add_argument("--kind", choices=siconos_files.KINDS, default=None,
                        help="the file kind (default: from the name: fc2d_*, gfc2d_*, lcp_*)")
    parser.add_argument("--no-reference", action="store_true", help="skip reference solutions")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Read every Siconos file, then write each as a problem file (:func:`save_imported`).

    A file qpbench does not support (a general LCP) is skipped with one line on stderr.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``files``, ``kind``, ``no_reference`` and
        ``output``.

    Returns
    -------
    int
        The exit status: 0.
    """
    # read and check every file before writing anything; a general LCP is skipped, one line
    problems = []
    for path in args.files:
        try:
            problems.append(import_siconos(path, args.kind))
        except UnsupportedError as refused:
            print(f"qpbench import-siconos: skipped: {refused}", file=sys.stderr)
    save_imported(problems, args.output, "import-siconos", not args.no_reference)
    return 0
