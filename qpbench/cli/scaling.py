"""``qpbench scaling [--sizes 1000,10000] [--steps N] [--solver NAME] [--pile-sizes 1000,10000]
[--box-pile-sizes 1000,10000] [--pile-steps N] [--pile-passes N] [--pile-solve-budget S]
[--no-piles] [--[no-]progress] -o results/scaling.json``: the measurements as JSON, their
Markdown on stdout, a bar over the measurements and a closing line on stderr. Each pile's
inner solves are set against one sparse factorization of its final active block
(``qpbench.studies.factorization.active_block_factorization``)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from qpbench.bench.settings import check_at_least
from qpbench.cli.guards import add_progress_option, progress_wanted
from qpbench.cli.output import write_json
from qpbench.cli.progress import Progress
from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name
from qpbench.simulation.scaling import (
    DEFAULT_PILE_PASSES,
    DEFAULT_PILE_SOLVE_BUDGET_S,
    DEFAULT_PILE_STEPS,
    DEFAULT_SIZES,
    DEFAULT_STEPS,
    measurement_count,
    scaling,
)
from qpbench.studies.factorization import active_block_factorization

DEFAULT_SOLVER = "clarabel/dual"
JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"


def _sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of integers: {text!r}") from None
    if len(sizes) < 2 or any(size < 1 for size in sizes):
        raise argparse.ArgumentTypeError("give at least two positive sizes, e.g. 1000,10000")
    return sizes


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench scaling`` and its options (sizes, steps, solver, piles, progress, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("scaling", help="cost per ball per step of the simulator",
                                   epilog=JSON_FIELDS)
    parser.add_argument("--sizes", type=_sizes, default=DEFAULT_SIZES,
                        help="comma-separated ball counts (1000,10000)")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                        help=f"timed steps per size ({DEFAULT_STEPS})")
    parser.add_argument("--solver", default=DEFAULT_SOLVER,
                        help=f"inner solver ({DEFAULT_SOLVER})")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pile-sizes", type=_sizes, default=None,
                        help="body counts of the dense circle pile (default: --sizes)")
    parser.add_argument("--box-pile-sizes", type=_sizes, default=None,
                        help="body counts of the dense box pile (default: --sizes)")
    parser.add_argument("--pile-steps", type=int, default=DEFAULT_PILE_STEPS,
                        help=f"timed steps per pile ({DEFAULT_PILE_STEPS})")
    parser.add_argument("--pile-passes", type=int, default=DEFAULT_PILE_PASSES,
                        help="passes over every pile, the sizes in turn; each size keeps the "
                             f"pass whose inner solves took least ({DEFAULT_PILE_PASSES})")
    parser.add_argument("--pile-solve-budget", type=float, default=DEFAULT_PILE_SOLVE_BUDGET_S,
                        help="seconds of inner solves after which a pile stops timing further "
                             f"steps; at least one is timed ({DEFAULT_PILE_SOLVE_BUDGET_S:g})")
    parser.add_argument("--no-piles", action="store_true", help="only the sparse box scenes")
    add_progress_option(parser)
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Measure the simulator's cost per ball per step, write the JSON and print its Markdown.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0.

    Raises
    ------
    QpbenchError
        When the steps, passes or seed are out of range, the pile solve budget is not positive, or
        the solver is unknown.
    """
    check_at_least(args.steps, 1, "--steps")
    check_at_least(args.pile_steps, 1, "--pile-steps")
    check_at_least(args.pile_passes, 1, "--pile-passes")
    check_at_least(args.seed, 0, "--seed")
    if not args.pile_solve_budget > 0:
        raise QpbenchError("--pile-solve-budget must be a positive number of seconds")
    circles = args.pile_sizes or args.sizes
    boxes = args.box_pile_sizes or args.sizes
    piles = None if args.no_piles else {"circles": circles, "boxes": boxes}
    with Progress("scaling", progress_wanted(args),
                  measurement_count(args.sizes, piles, args.pile_passes),
                  "measurements") as progress:
        report = scaling(choose_by_name(args.solver), args.sizes, args.steps, args.seed, piles,
                         args.pile_steps, args.pile_solve_budget, progress.advance,
                         active_block_factorization, args.pile_passes)
    write_json(args.output, report)
    print(report["markdown"], end="")
    print(f"qpbench scaling: {closing_line(report)} -> {args.output}", file=sys.stderr)
    return 0


def closing_line(report: dict[str, Any]) -> str:
    """Say the verdicts of a scaling report in one line.

    The growth of the cost per ball per step of the box scenes and, per kind of pile, of the
    simulator's own cost per body per step, each against the target, and the pile's largest
    inner solves per step against one factorization of its final active block.

    Parameters
    ----------
    report : dict
        The report of :func:`qpbench.simulation.scaling.scaling`.

    Returns
    -------
    str
        The line, without the ``qpbench scaling:`` prefix.
    """
    rows = report["rows"]
    parts = [f"cost per ball per step {rows[-1]['balls']} vs {rows[0]['balls']} balls "
             f"{report['ratio']:.2f}x ({_verdict(report['meets_target'])})"]
    for kind, entry in report.get("piles", {}).get("kinds", {}).items():
        failed = "" if all(row["success"] for row in entry["rows"]) else ", an inner solve failed"
        parts.append(f"{kind} pile own cost {entry['own_ratio']:.2f}x "
                     f"({_verdict(entry['meets_target'])}{failed})")
        if entry.get("max_solve_to_factorization") is not None:
            parts.append(f"{kind} pile solves per step vs one factorization "
                         f"{entry['max_solve_to_factorization']:.2f}x "
                         f"({_verdict(entry['meets_factorization_target'])}, target <= "
                         f"{report['piles']['factorization_target']:g}x)")
    return f"{'; '.join(parts)}; target <= {report['target_ratio']:g}x"


def _verdict(met: bool) -> str:
    return "met" if met else "missed"
