"""``qpbench sim-precision [SCENE...] [--solvers A,B] [--accuracy L1,L2] [--steps N]
[--memory-limit MB] [--progress|--no-progress] -o OUT.json``: every scene simulated with each
solver as its inner solver at each level, its final state against a reference run (and SCISim's
own where known), its solve and wall times, penetration, energy and friction metrics
(``qpbench.bench.sim_precision``). Writes the JSON atomically and prints its ``markdown``.
Exit 0 when every scene was measured (a pair's failed run is a row, not an error); 2 on bad
input or an output that cannot be written; 130 on Ctrl-C.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from qpbench.bench import sim_precision
from qpbench.bench.defaults import (
    SIM_PRECISION_ACCURACY,
    SIM_PRECISION_SCENES,
    SIM_PRECISION_SOLVERS,
    SIM_PRECISION_STEPS,
)
from qpbench.bench.settings import check_at_least, parse_accuracies, parse_solver_names
from qpbench.cli.guards import add_memory_option, add_progress_option, guarded, progress_wanted
from qpbench.cli.output import writable_output, write_json
from qpbench.cli.progress import Progress
from qpbench.errors import InputError

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"
ROOT = Path(__file__).resolve().parents[2]


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench sim-precision`` and its options (scenes, solvers, levels, steps, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "sim-precision", help="what each level of inner accuracy costs in whole simulations",
        epilog=JSON_FIELDS)
    parser.add_argument("scenes", nargs="*", metavar="SCENE",
                        help=f"scene files (default: the {len(SIM_PRECISION_SCENES)} scenes of "
                             "qpbench/bench/defaults.py)")
    parser.add_argument("--solvers", default=",".join(SIM_PRECISION_SOLVERS),
                        help="comma-separated NAME[/FORMULATION], each mapped to the pair of a "
                             "scene's kind (default: %(default)s)")
    parser.add_argument("--accuracy", default=",".join(f"{level:g}"
                                                       for level in SIM_PRECISION_ACCURACY),
                        help="comma-separated levels; the tightest is the reference's "
                             "(default: %(default)s)")
    parser.add_argument("--steps", type=int, default=SIM_PRECISION_STEPS,
                        help="steps per run, fewer when the scene ends sooner "
                             "(default: %(default)s)")
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    add_memory_option(parser)
    add_progress_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Simulate every scene with each solver at each level, write the JSON, print its Markdown.

    The runs go under the guards (memory cap, Ctrl-C) with a bar counting them.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0 (a pair's failed run is a row, not an error).

    Raises
    ------
    QpbenchError
        When ``--steps`` is below 1, a level or solver does not parse, a scene file does not
        exist, or the output path cannot be written.
    """
    check_at_least(args.steps, 1, "--steps")
    levels = parse_accuracies(args.accuracy)
    names = parse_solver_names(args.solvers)
    output = writable_output(args.output)
    scenes = args.scenes or [str(ROOT / scene) for scene in SIM_PRECISION_SCENES]
    for scene in scenes:
        if not Path(scene).is_file():
            raise InputError(scene, "no such scene file")
    total = sim_precision.run_count(len(scenes), len(names), len(levels))
    with guarded(args, "sim-precision", "measuring whole simulations"), \
            Progress("sim-precision", progress_wanted(args), total, "runs") as progress:
        report = sim_precision.sim_precision(scenes, names, levels, args.steps,
                                             progress=progress.advance)
        progress.summary = f"{len(report['rows'])} rows over {len(scenes)} scenes"
    write_json(output, report)
    print(report["markdown"], end="")
    return 0
