"""``qpbench export PROBLEMS... [--format parquet|mat|fclib] [--formulation dual|primal]
-o PATH``."""

from __future__ import annotations

import argparse
import sys

from qpbench.bench.export import FORMATS, FORMULATIONS, export


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench export`` and its options (problems, format, formulation, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "export", help="write problems for other QP benchmarks (qpbenchmark Parquet, .mat)")
    parser.add_argument("problems", nargs="+", help="problem files (.npz) or folders of them")
    parser.add_argument("--format", choices=FORMATS, default="parquet",
                        help="parquet: qpbenchmark's problem list (one file); mat: one .mat per "
                             "problem in a folder; fclib: one FCLIB HDF5 file per problem "
                             "in a folder, W, q, mu or M, H, f, w, mu as they stand "
                             "(default: parquet)")
    parser.add_argument("--formulation", choices=FORMULATIONS, default="dual",
                        help="dual: P=Q, q=b, lb=0; primal: velocity-space QP (default: dual)")
    parser.add_argument("-o", "--output", required=True,
                        help="the .parquet file, or the folder for .mat or .hdf5 files")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Write the problems in the format asked (:func:`qpbench.bench.export.export`).

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``problems``, ``format``, ``formulation`` and
        ``output``.

    Returns
    -------
    int
        The exit status: 0.
    """
    count = export(args.problems, args.output, args.format, args.formulation)
    print(f"qpbench export: {count} problems -> {args.output}", file=sys.stderr)
    return 0
