"""``qpbench sequence SCENE... [--solvers A,B] [--steps 30] [--accuracy 1e-8] [--repeats 5]
[--passes 3] [--out-of-running 30] -o results/sequence.json``: every solver replays captured
scene sequences, cold and warm-started from its own previous answer on the persisting contacts
(``qpbench.studies.sequence``). Runs with single-threaded BLAS, in a child process unless this
one already has it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from qpbench.bench.defaults import (
    REPEATS,
    SEQUENCE_ACCURACY,
    SEQUENCE_OUT_OF_RUNNING,
    SEQUENCE_PASSES,
    SEQUENCE_STEPS,
)
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import check_accuracy, check_at_least
from qpbench.cli.guards import add_memory_option, guarded, memory_arguments
from qpbench.cli.output import single_threaded_rerun, writable_output, write_json
from qpbench.errors import InputError, QpbenchError
from qpbench.solvers.registry import get
from qpbench.studies import sequence, sequence_pairs

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench sequence`` and its options (scenes, solvers, steps, accuracy, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "sequence", help="replay captured scenes, each solver warm from its own answers",
        epilog=JSON_FIELDS)
    parser.add_argument("scenes", nargs="*", metavar="SCENE",
                        help="scene files (simulated and captured) or capture folders "
                             "(default: the shared box and butterfly scenes)")
    parser.add_argument("--solvers", default=None,
                        help="comma-separated NAME[/FORMULATION] (default: pi-robust, every "
                             "warm-startable external pair and the fastest cold ones)")
    parser.add_argument("--results", default=None,
                        help="the main benchmark's table: its fastest pairs without warm "
                             "starts are shown beside (default: none of those)")
    parser.add_argument("--steps", type=int, default=SEQUENCE_STEPS,
                        help=f"impact steps per scene ({SEQUENCE_STEPS})")
    parser.add_argument("--accuracy", type=float, default=SEQUENCE_ACCURACY,
                        help=f"residual bound ({SEQUENCE_ACCURACY:g})")
    parser.add_argument("--repeats", type=int, default=REPEATS,
                        help=f"timed repeats per solve, the fastest kept ({REPEATS})")
    parser.add_argument("--passes", type=int, default=SEQUENCE_PASSES,
                        help="replays of every scene, one after another; each step's fastest "
                             f"is kept, and each pass alone gives a speedup ({SEQUENCE_PASSES})")
    parser.add_argument("--out-of-running", type=float, default=SEQUENCE_OUT_OF_RUNNING,
                        help="an external pair whose solves on a scene so far take more than "
                             "this many times those of the fastest warm-startable external "
                             "pair stops there and is left out; inf: none stops so "
                             f"({SEQUENCE_OUT_OF_RUNNING:g})")
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    add_memory_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Replay the scenes with every solver cold and warm, write the JSON and print its Markdown.

    Reruns the command in a child process with single-threaded BLAS unless this one already
    has it. Without ``--solvers``, the solvers are pi-robust, the warm-startable external pairs
    and, with ``--results``, the fastest cold pairs of the main benchmark. The scenes are
    simulated and solved under the memory cap (``--memory-limit``): a solve that would take
    more fails with MemoryError.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0, or the child's.

    Raises
    ------
    QpbenchError
        When an option is out of range, a scene does not exist, a solver named is unknown or
        not usable here, or the results are empty.
    """
    if args.steps < 1 or args.repeats < 1 or args.passes < 1:
        raise QpbenchError("--steps, --repeats and --passes must be at least 1")
    check_at_least(args.out_of_running, 1, "--out-of-running")  # (inf: every pair stays)
    check_accuracy(args.accuracy)
    output = writable_output(args.output)
    for scene in args.scenes:
        if not Path(scene).exists():
            raise InputError(scene, "no such scene file or capture folder")
    child = single_threaded_rerun(
        ["sequence", *args.scenes, "--steps", str(args.steps), "--accuracy", repr(args.accuracy),
         "--repeats", str(args.repeats), "--passes", str(args.passes),
         "--out-of-running", repr(args.out_of_running), "-o", str(args.output),
         *(["--solvers", args.solvers] if args.solvers else []),
         *(["--results", args.results] if args.results else []), *memory_arguments(args)])
    if child is not None:
        return child

    with guarded(args, "sequence", "replaying the scenes"):
        report = _replayed(args)
    write_json(output, report)
    print(report["markdown"], end="")
    return 0


def _replayed(args: argparse.Namespace) -> dict:
    """The sequence report of :func:`run`'s options: the solvers named, or the default ones
    (with ``--results``, the main table's fastest cold pairs too), on the scenes given."""
    if args.solvers:
        specs = [get(name.strip()) for name in args.solvers.split(",") if name.strip()]
        unusable = [spec.key for spec in specs if spec.solve is None]
        if unusable:
            raise QpbenchError(f"not usable here: {', '.join(unusable)}")
    else:
        cold: list[str] = []
        if args.results:
            bench = ResultStore(args.results).read()
            if bench.empty:
                raise InputError(args.results, "no results to choose the cold pairs from")
            cold = sequence_pairs.fastest_cold(bench, accuracy=args.accuracy)
        specs = sequence_pairs.default_solvers(cold)
    return sequence.sequence(args.scenes or list(sequence.DEFAULT_SCENES), specs, args.steps,
                             args.accuracy, progress=lambda text: print(text, file=sys.stderr),
                             repeats=args.repeats, passes=args.passes,
                             out_of_running=args.out_of_running)
