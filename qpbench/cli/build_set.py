"""``qpbench build-set SET.toml -o DIR``: the problem files of a problem set."""

from __future__ import annotations

import argparse

from qpbench.bench import problem_sets
from qpbench.problem import files


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "build-set", help="write the problems of a set file (families, dumps, captured scenes)"
    )
    parser.add_argument("set_file", metavar="SET.toml", help="e.g. problems/default.toml")
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    written = problem_sets.build(args.set_file, args.output)
    total = len(files.find([args.output]))
    print(f"{len(written)} problems written, {total} in {args.output}")
    return 0
