"""``qpbench build-set SET.toml [--seed-offset N] -o DIR``: the problem files of a problem set.

``--seed-offset N`` adds N to every family's seeds, so that the same set file gives problems
nobody has looked at (``make bench`` draws N for the head-to-head set at run time).

A family size or scene that needs more memory than ``--memory-limit`` or the machine allows
is refused in one line before anything is written (exit 2); Ctrl-C ends the command within
about a second (exit 130), leaving every problem file whole. ``--progress`` counts the
problems written on stderr.
"""

from __future__ import annotations

import argparse

from qpbench.bench import problem_sets
from qpbench.cli.guards import add_memory_option, add_progress_option, guarded, progress_wanted
from qpbench.cli.progress import Progress
from qpbench.errors import QpbenchError
from qpbench.problem import files


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench build-set`` and its options (set file, seed offset, ``-o``, memory
    and progress).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "build-set", help="write the problems of a set file (families, dumps, captured scenes)"
    )
    parser.add_argument("set_file", metavar="SET.toml", help="e.g. problems/default.toml")
    parser.add_argument("--seed-offset", type=int, default=0, metavar="N",
                        help="added to every family's seeds: problem i of a family size gets "
                             "seed (its seed in the set file) + N + i; dumps and scenes are "
                             "unchanged (0)")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    add_memory_option(parser)
    add_progress_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Write the problems of a set file to the output folder and print how many.

    The build runs under :func:`qpbench.cli.guards.guarded` (memory cap, Ctrl-C) with a
    progress bar counting the problems written.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``set_file``, ``seed_offset``, ``output``,
        ``memory_limit`` and ``progress``.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        On a negative ``--seed-offset``, before anything is written, and as
        :func:`qpbench.bench.problem_sets.build` raises.
    """
    if args.seed_offset < 0:
        raise QpbenchError(f"--seed-offset must be at least 0, got {args.seed_offset}")
    with (guarded(args, "build-set", f"building {args.set_file}", [args.output]),
          Progress("build-set", progress_wanted(args), None, "problems") as progress):
        written = problem_sets.build(args.set_file, args.output,
                                     on_problem=lambda name: progress.advance(note=name),
                                     seed_offset=args.seed_offset)
        progress.summary = f"{len(written)} problems written"
    total = len(files.find([args.output]))
    print(f"{len(written)} problems written, {total} in {args.output}")
    return 0
