"""``qpbench fuzz --scenes N --problems N --seed S [--steps K] [--time-limit-s T]
[--memory-limit MB] [--corpus DIR]... -o OUT.json``: mutated scenes and problem files run
through the command line (``qpbench.cli.fuzz_harness``).

Writes the report to OUT.json (counts per outcome and mutation, attribute coverage, the
failing cases) and the input of every failing case to the folder ``OUT.cases`` beside it.
Exit 0 when every case passed, 1 when any failed, 2 on bad options.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from qpbench.bench.settings import check_at_least
from qpbench.cli import fuzz_harness as fuzz
from qpbench.cli.output import writable_output, write_json
from qpbench.errors import QpbenchError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench fuzz`` and its options (case counts, seed, steps, limits, corpus, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "fuzz", help="run mutated scenes and problem files through qpbench, judge the errors")
    parser.add_argument("--scenes", type=int, default=200, help="scene cases (200)")
    parser.add_argument("--problems", type=int, default=200, help="problem-file cases (200)")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed (0)")
    parser.add_argument("--steps", type=int, default=3, help="steps simulated per scene (3)")
    parser.add_argument("--time-limit-s", type=float, default=30.0,
                        help="wall-clock seconds per case before it counts as a hang (30)")
    parser.add_argument("--memory-limit", type=int, default=1024, metavar="MB",
                        help="address space a case may add to its process, MiB (1024)")
    parser.add_argument("--corpus", action="append", default=None, metavar="DIR",
                        help="a folder of scenes to mutate (repeatable; default: "
                             "problems/scenes and ../shared/scisim, ../shared/scenes)")
    parser.add_argument("-o", "--output", required=True, help="the JSON report to write")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the fuzz cases, write the report and print the counts and failures.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`.

    Returns
    -------
    int
        The exit status: 0 when every case passed, 1 when any failed.

    Raises
    ------
    QpbenchError
        When a count, the seed, the steps or the memory limit is below its least value, the
        time limit is not a positive number, or the output path cannot be written.
    """
    check_at_least(args.scenes, 0, "--scenes")
    check_at_least(args.problems, 0, "--problems")
    check_at_least(args.seed, 0, "--seed")
    check_at_least(args.steps, 1, "--steps")
    check_at_least(args.memory_limit, 64, "--memory-limit")
    if not (math.isfinite(args.time_limit_s) and args.time_limit_s > 0):
        raise QpbenchError(f"--time-limit-s must be a positive number, got {args.time_limit_s}")
    output = writable_output(args.output)
    settings = fuzz.Settings(scenes=args.scenes, problems=args.problems, seed=args.seed,
                             steps=args.steps, time_limit_s=args.time_limit_s,
                             memory_limit_mb=args.memory_limit)
    folders = [Path(folder) for folder in args.corpus] if args.corpus else None
    report = fuzz.fuzz(settings, folders, output.with_suffix(".cases"))
    write_json(output, report)
    for kind in fuzz.KINDS:
        counts = report["kinds"][kind]
        outcomes = ", ".join(f"{outcome} {count}" for outcome, count in
                             counts["outcomes"].items())
        print(f"{kind}: {counts['cases']} cases, {counts['failed']} failed ({outcomes})")
    for failure in report["failures"]:
        print(f"failed: {failure['kind']} case {failure['case']}: {failure['outcome']}: "
              f"{' '.join(failure['command'])}")
    return 0 if report["passed"] else 1
