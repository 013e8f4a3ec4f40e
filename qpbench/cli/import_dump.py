"""``qpbench import-dump FILE... -o DIR``: SCISim LCP dumps to problem files."""

from __future__ import annotations

import argparse
import sys

from qpbench.problem import files
from qpbench.problem.dumps import import_dump
from qpbench.problem.reference import attach_reference


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench import-dump`` and its options (dumps, ``--restitution``, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("import-dump", help="import SCISim LCP dumps as problems")
    parser.add_argument("dumps", nargs="+", metavar="FILE", help="dump files (.json or .out)")
    parser.add_argument("--restitution", type=float, default=None,
                        help="CoR when the dump has no b (default 1)")
    parser.add_argument("--no-reference", action="store_true", help="skip reference solutions")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Read every dump, then write each as a problem file with its reference and print its path.

    A reference whose solvers disagree is said on stderr.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``dumps``, ``restitution``, ``no_reference`` and
        ``output``.

    Returns
    -------
    int
        The exit status: 0.
    """
    # read and check every dump before writing anything
    problems = [import_dump(path, args.restitution) for path in args.dumps]
    for problem in problems:
        if not args.no_reference:
            attach_reference(problem)
            if not problem.reference.verified:
                print(f"qpbench import-dump: {problem.name}: references disagree "
                      f"({problem.reference.agreement:.1e})", file=sys.stderr)
        print(files.save(problem, f"{args.output}/{problem.name}"))
    return 0
