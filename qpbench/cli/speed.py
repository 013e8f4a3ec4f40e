"""``qpbench speed [--sizes 1000,4000] [--seed 0] [--repeats 5] -o results/speed.json``:
pi-robust against one sparse factorization of Q + eps I on box packings
(``qpbench.studies.speed``). The measurement runs in a child process with single-threaded BLAS
unless this one already has it."""

from __future__ import annotations

import argparse

from qpbench.bench.defaults import REPEATS, SPEED_SIZES
from qpbench.bench.settings import check_at_least
from qpbench.cli.output import single_threaded_rerun, writable_output, write_json
from qpbench.studies.speed import speed

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"


def _sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of integers: {text!r}") from None
    if not sizes or any(size < 1 for size in sizes):
        raise argparse.ArgumentTypeError("give positive ball counts, e.g. 1000,4000")
    return sizes


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench speed`` and its options (``--sizes``, ``--seed``, ``--repeats``, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "speed", help="pi-robust against one sparse factorization on box packings",
        epilog=JSON_FIELDS)
    parser.add_argument("--sizes", type=_sizes, default=SPEED_SIZES,
                        help="comma-separated ball counts "
                             f"({','.join(str(size) for size in SPEED_SIZES)})")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=REPEATS,
                        help=f"timed repeats, minimum kept ({REPEATS})")
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Time pi-robust against one sparse factorization, write the JSON and print its Markdown.

    Reruns the command in a child process with single-threaded BLAS unless this one already
    has it.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``sizes``, ``seed``, ``repeats`` and ``output``.

    Returns
    -------
    int
        The exit status: 0, or the child's.

    Raises
    ------
    QpbenchError
        When ``--repeats`` is below 1, ``--seed`` below 0, or the output path cannot be written.
    """
    check_at_least(args.repeats, 1, "--repeats")
    check_at_least(args.seed, 0, "--seed")
    output = writable_output(args.output)
    child = single_threaded_rerun(["speed", "--sizes", ",".join(str(size) for size in args.sizes),
                                   "--seed", str(args.seed), "--repeats", str(args.repeats),
                                   "-o", str(args.output)])
    if child is not None:
        return child

    report = speed(args.sizes, args.seed, args.repeats)
    write_json(output, report)
    print(report["markdown"], end="")
    return 0
