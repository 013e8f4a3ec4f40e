"""``qpbench scaling [--sizes 1000,10000] [--steps N] [--solver NAME] -o results/scaling.json``."""

from __future__ import annotations

import argparse

from qpbench.cli.output import write_json
from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name
from qpbench.simulation.scaling import DEFAULT_SIZES, DEFAULT_STEPS, scaling

DEFAULT_SOLVER = "clarabel/dual"


def _sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of integers: {text!r}") from None
    if len(sizes) < 2 or any(size < 1 for size in sizes):
        raise argparse.ArgumentTypeError("give at least two positive sizes, e.g. 1000,10000")
    return sizes


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("scaling", help="cost per ball per step of the simulator")
    parser.add_argument("--sizes", type=_sizes, default=DEFAULT_SIZES,
                        help="comma-separated ball counts (1000,10000)")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                        help=f"timed steps per size ({DEFAULT_STEPS})")
    parser.add_argument("--solver", default=DEFAULT_SOLVER,
                        help=f"inner solver ({DEFAULT_SOLVER})")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.steps < 1:
        raise QpbenchError("--steps must be at least 1")
    report = scaling(choose_by_name(args.solver), args.sizes, args.steps, args.seed)
    write_json(args.output, report)
    print(report["markdown"], end="")
    return 0
