"""``qpbench breakdown [--repeats 20] -o results/breakdown.json``: where pi-robust's time goes
on the 5x5 and 7x7 grids of the SCISim research fork and a 1000-ball box, against one
Cholesky of the final active block and one product, in compiled code
(``qpbench.studies.breakdown``). Runs with single-threaded BLAS, in a child process unless this
one already has it."""

from __future__ import annotations

import argparse

from qpbench.bench.defaults import BREAKDOWN_REPEATS
from qpbench.cli.output import single_threaded_rerun, writable_output, write_json
from qpbench.errors import QpbenchError
from qpbench.studies.breakdown import breakdown

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench breakdown`` and its options (``--repeats``, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("breakdown", help="where pi-robust's time goes",
                                   epilog=JSON_FIELDS)
    parser.add_argument("--repeats", type=int, default=BREAKDOWN_REPEATS,
                        help=f"timed rounds, each part's fastest kept ({BREAKDOWN_REPEATS})")
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Measure where pi-robust's time goes, write the JSON and print its Markdown.

    Reruns the command in a child process with single-threaded BLAS unless this one already
    has it.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``repeats`` and ``output``.

    Returns
    -------
    int
        The exit status: 0, or the child's.

    Raises
    ------
    QpbenchError
        When ``--repeats`` is below 1, or the output path cannot be written.
    """
    if args.repeats < 1:
        raise QpbenchError("--repeats must be at least 1")
    output = writable_output(args.output)
    child = single_threaded_rerun(["breakdown", "--repeats", str(args.repeats),
                                   "-o", str(args.output)])
    if child is not None:
        return child

    report = breakdown(repeats=args.repeats)
    write_json(output, report)
    print(report["markdown"], end="")
    return 0
