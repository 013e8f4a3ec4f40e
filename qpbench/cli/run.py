"""``qpbench run [PROBLEMS...] [--solvers ...] [--accuracy ...] [--timeout S] [--repeats K]
[--repeat-budget S] [--mode cold,warm] [--workers N]
[--executor serial|processes|dask://HOST:PORT] [--retry STATUSES] -o FILE.parquet``.

Re-running the same command resumes: cells already in FILE.parquet are skipped, except those
whose worker was killed by an outside signal (status ``killed``), which are solved again;
``--retry`` names further statuses to solve again. An interrupt (Ctrl-C or SIGTERM) leaves
FILE.parquet readable with every row finished so far, and exits 130.
"""

from __future__ import annotations

import argparse
import math
import sys

from qpbench.bench import isolation, runner
from qpbench.bench.executors import DaskExecutor, make_executor
from qpbench.bench.settings import (
    DEFAULT_ACCURACIES,
    DEFAULT_MEMORY_LIMIT_MB,
    DEFAULT_REPEATS,
    DEFAULT_TIMEOUT_S,
    PROBLEM_KINDS,
    RETRIED_ON_RESUME,
    STATUSES,
    Limits,
    RunSettings,
    check_at_least,
    parse_accuracies,
    parse_modes,
    parse_solver_names,
    parse_statuses,
)
from qpbench.cli.output import writable_output

DEFAULT_PROBLEMS = ("problems",)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench run`` and its options (problems, solvers, levels, limits, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "run", help="solve problems x solvers x accuracy levels into one Parquet table",
        description="Every cell runs in an isolated worker process: a crash, hang or memory "
                    "blow-up becomes a row (crashed, timeout, out-of-memory; killed when a "
                    "signal from outside ended the worker). Re-running the same command "
                    "resumes where it stopped; an interrupt keeps every finished row.")
    parser.add_argument("problems", nargs="*", default=list(DEFAULT_PROBLEMS),
                        help="problem files (.npz) or folders of them (default: problems/)")
    parser.add_argument("--solvers", default=None,
                        help="NAME or NAME/FORMULATION, comma-separated (default: every usable)")
    parser.add_argument("--accuracy", default=",".join(f"{a:.0e}" for a in DEFAULT_ACCURACIES),
                        help="accuracy levels, comma-separated (default: %(default)s)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S,
                        help="wall-clock limit per solve in seconds (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=DEFAULT_REPEATS,
                        help="timed repeats per cell, in rounds interleaved with the other "
                             "cells of a worker's batch; time_s is the minimum (default: 1)")
    parser.add_argument("--repeat-budget", type=float, default=math.inf, metavar="S",
                        help="stop repeating a cell once its repeats have taken S seconds of "
                             "time_s in all (default: no budget)")
    parser.add_argument("--mode", default="cold",
                        help="cold, warm or cold,warm (default: cold)")
    parser.add_argument("--memory-limit", type=int, default=DEFAULT_MEMORY_LIMIT_MB,
                        help="address-space cap of a worker in MiB, 0 for none "
                             "(default: %(default)s)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes (default: 1)")
    parser.add_argument("--executor", default="auto",
                        help="serial, processes or dask://HOST:PORT (default: serial, or "
                             "processes with --workers > 1)")
    parser.add_argument("--retry", default="",
                        help="statuses to solve again although stored, comma-separated, of "
                             f"{', '.join(STATUSES)} (e.g. timeout,out-of-memory after "
                             "raising --timeout or --memory-limit); the new row replaces the "
                             f"old. A resume always solves {', '.join(RETRIED_ON_RESUME)} "
                             "cells again")
    parser.add_argument("--batch", type=int, default=20,
                        help="rows per part file written (default: %(default)s)")
    parser.add_argument("--kind", default="all", choices=("all", *PROBLEM_KINDS),
                        help="run only the problems of this kind (default: all)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-o", "--output", required=True, help="results file (.parquet)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Solve every cell of problems x solvers x levels x modes into the results file.

    Cells already stored are skipped (but those in RETRIED_ON_RESUME and ``--retry``); the
    fork server starts before the solver backends are imported. A line of counts goes to
    stderr at the end.

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
        When an option does not parse or is out of range, a solver is unknown, or the output
        path cannot be written.
    """
    check_at_least(args.workers, 1, "--workers")
    check_at_least(args.batch, 1, "--batch")
    retry = parse_statuses(args.retry)
    solver_names = None if args.solvers is None else parse_solver_names(args.solvers)
    accuracies = parse_accuracies(args.accuracy)
    modes = parse_modes(args.mode)
    writable_output(args.output)
    limits = Limits(timeout_s=args.timeout, memory_limit_mb=args.memory_limit,
                    repeats=args.repeats, repeat_budget_s=args.repeat_budget)
    executor = make_executor(args.executor, args.workers)
    if not isinstance(executor, DaskExecutor):
        # started before this process imports the solver backends, so both import at once
        isolation.start_fork_server()
    from qpbench.solvers.registry import resolve, usable_solvers  # (after the fork server)

    specs = usable_solvers() if solver_names is None else resolve(solver_names)
    kinds = PROBLEM_KINDS if args.kind == "all" else (args.kind,)
    settings = RunSettings(solvers=tuple(spec.key for spec in specs), accuracies=accuracies,
                           modes=modes, limits=limits, kinds=kinds)
    counts = runner.run(args.problems, settings, args.output, executor,
                        progress=not args.no_progress, batch_rows=args.batch, retry=retry)
    statuses = ", ".join(f"{status} {count}" for status, count in sorted(counts.items())
                         if status not in ("cells", "skipped", "run"))
    print(f"qpbench run: {counts['cells']} cells, {counts['skipped']} already done, "
          f"{counts['run']} run{f' ({statuses})' if statuses else ''} -> {args.output}",
          file=sys.stderr)
    return 0
