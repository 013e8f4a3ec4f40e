"""``qpbench head-to-head FOLDER --results results/bench.parquet [--repeats 20] [--passes 3]
[--candidates 6] [--out-of-running 30] [--cold-repeats 3] [--solve-cap 10]
-o results/head_to_head.json``, or ``qpbench head-to-head --summarize-again FILE.json -o
FILE.json``:
pi-robust against the fastest external pairs of the main benchmark, no warm start, timed
interleaved and with the CPU caches flushed, per set of ``problems/head_to_head.toml``
(built into FOLDER by ``qpbench build-set``; ``qpbench.studies.head_to_head``). Runs with
single-threaded BLAS, in a child process unless this one already has it."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from qpbench.bench.defaults import (
    HEAD_TO_HEAD_CANDIDATES,
    HEAD_TO_HEAD_COLD_REPEATS,
    HEAD_TO_HEAD_OUT_OF_RUNNING,
    HEAD_TO_HEAD_PASSES,
    HEAD_TO_HEAD_REPEATS,
    HEAD_TO_HEAD_SOLVE_CAP_S,
)
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import check_at_least
from qpbench.cli.guards import add_memory_option, guarded, memory_arguments
from qpbench.cli.output import single_threaded_rerun, writable_output, write_json
from qpbench.errors import InputError, QpbenchError
from qpbench.studies.few_contacts import few_contacts_summary
from qpbench.studies.head_to_head import UNDECIDED, head_to_head, markdown, summarize
from qpbench.studies.head_to_head_pairs import BENCH_COLUMNS

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench head-to-head`` and its options (folder, results, repeats, passes, ``-o``).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser(
        "head-to-head", help="pi-robust against the fastest external pairs, per set, cold",
        epilog=JSON_FIELDS)
    parser.add_argument("folder", nargs="?",
                        help="problem folder built from problems/head_to_head.toml")
    parser.add_argument("--results",
                        help="the main benchmark's table, which names the fastest pairs")
    parser.add_argument("--summarize-again", metavar="FILE",
                        help="instead of timing: an earlier run's JSON, whose rows are "
                             "summarized again under the current rules (its summary, "
                             "few-contacts figures and Markdown rewritten into -o)")
    parser.add_argument("--repeats", type=int, default=HEAD_TO_HEAD_REPEATS,
                        help=f"timed repeats, minimum kept ({HEAD_TO_HEAD_REPEATS})")
    parser.add_argument("--passes", type=int, default=HEAD_TO_HEAD_PASSES,
                        help="whole-set passes, one after another; the table keeps each "
                             "problem's fastest, and the spread of the passes' speedups is "
                             f"shown ({HEAD_TO_HEAD_PASSES})")
    parser.add_argument("--candidates", type=int, default=HEAD_TO_HEAD_CANDIDATES,
                        help="fastest external impact pairs compared, and each candidate "
                             f"family's fastest besides ({HEAD_TO_HEAD_CANDIDATES})")
    parser.add_argument("--out-of-running", type=float, default=HEAD_TO_HEAD_OUT_OF_RUNNING,
                        help="an external pair whose times on a set's problems so far, summed, "
                             "are more than this many times the fastest external pair's is "
                             "measured no further on that set; inf: every pair on every "
                             f"problem ({HEAD_TO_HEAD_OUT_OF_RUNNING:g})")
    parser.add_argument("--cold-repeats", type=int, default=HEAD_TO_HEAD_COLD_REPEATS,
                        help="timed calls per solve with the CPU caches flushed before each, "
                             "minimum kept, beside the interleaved figure; 0: none "
                             f"({HEAD_TO_HEAD_COLD_REPEATS})")
    parser.add_argument("--solve-cap", type=float, default=HEAD_TO_HEAD_SOLVE_CAP_S,
                        help="seconds: a solve whose untimed warm-up took longer is timed no "
                             "further, and its pair leaves the set once another pair solved "
                             f"it within the cap; inf: none ({HEAD_TO_HEAD_SOLVE_CAP_S:g})")
    parser.add_argument("-o", "--output", required=True, help="the JSON file to write")
    add_memory_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Time pi-robust against the fastest external pairs per set; write and print the report.

    Reruns the command in a child process with single-threaded BLAS unless this one already
    has it. The solves run under the memory cap (``--memory-limit``): a pair whose solve would
    take more memory than that (a dense backend on a pile of 10,000 bodies) fails that solve
    with MemoryError instead of taking the machine's memory.

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
        When an option is out of range, the folder does not exist or holds no problem of a
        head-to-head set, or the results are empty or not the main benchmark's table.
    """
    if args.summarize_again is not None:
        output = writable_output(args.output)
        report = summarized_again(args.summarize_again)
        write_json(output, report)
        print(report["markdown"], end="")
        return 0
    if args.folder is None or args.results is None:
        raise QpbenchError("a problem folder and --results are needed (or --summarize-again)")
    if args.repeats < 1 or args.passes < 1 or args.candidates < 1:
        raise QpbenchError("--repeats, --passes and --candidates must be at least 1")
    if args.cold_repeats < 0:
        raise QpbenchError(f"--cold-repeats must be at least 0, got {args.cold_repeats}")
    check_at_least(args.out_of_running, 1, "--out-of-running")  # (inf: every pair stays)
    if not args.solve_cap > 0:  # NaN too
        raise QpbenchError(f"--solve-cap must be positive seconds (inf: none), got "
                           f"{args.solve_cap}")
    if not Path(args.folder).is_dir():
        raise InputError(args.folder, "no such problem folder")
    output = writable_output(args.output)
    child = single_threaded_rerun(
        ["head-to-head", args.folder, "--results", args.results, "--repeats", str(args.repeats),
         "--passes", str(args.passes), "--candidates", str(args.candidates),
         "--out-of-running", repr(args.out_of_running), "--cold-repeats",
         str(args.cold_repeats), "--solve-cap", repr(args.solve_cap), "-o", str(args.output),
         *memory_arguments(args)])
    if child is not None:
        return child

    with guarded(args, "head-to-head", "timing the head-to-head"):
        bench = ResultStore(args.results).read(BENCH_COLUMNS)
        if bench.empty:
            raise InputError(args.results, "no results to choose the external pairs from")
        for column in ("solver", "formulation", "accuracy", "time_s"):
            if bench[column].isna().all():
                raise InputError(args.results, f"no column {column}: not a results table of "
                                 "the main benchmark")
        report = head_to_head(args.folder, bench, args.repeats, args.candidates,
                              progress=lambda text: print(text, file=sys.stderr),
                              passes=args.passes, out_of_running=args.out_of_running,
                              cold_repeats=args.cold_repeats, solve_cap_s=args.solve_cap)
    if not report["rows"]:
        raise InputError(args.folder, "no problem of a head-to-head set")
    write_json(output, report)
    print(report["markdown"], end="")
    return 0


def summarized_again(path: str) -> dict[str, Any]:
    """An earlier head-to-head's JSON with its summary, few-contacts figures and Markdown
    made again from its rows, as measured, under the current rules.

    Parameters
    ----------
    path : str
        The JSON that ``qpbench head-to-head -o`` wrote.

    Returns
    -------
    dict
        The report with ``summary``, ``few_contacts`` and ``markdown`` replaced; the pairs
        that left a set stay out of its figures, as in the run.

    Raises
    ------
    InputError
        When the file cannot be read as such a JSON.
    """
    try:
        report = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise InputError(path, f"not a head-to-head JSON: {error}") from None
    for field, kind in (("rows", list), ("summary", list), ("repeats", int)):
        if not isinstance(report, dict) or not isinstance(report.get(field), kind) or (
                field == "rows" and not report[field]):
            raise InputError(path, f"no {kind.__name__} '{field}' of a head-to-head run",
                             attribute=field)
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for entry in report["summary"]:
        for left in entry.get("out_of_running", []):
            out.setdefault(entry["set"], {})[left["solver"]] = {
                key: value for key, value in left.items() if key != "solver"}
    summary = summarize(report["rows"], out)
    few_contacts = few_contacts_summary(report["rows"], UNDECIDED)
    limits = [report.get(key) for key in ("out_of_running", "solve_cap_s")]  # (null: inf)
    out_of_running, cap = (value if isinstance(value, (int, float)) else math.inf
                           for value in limits)
    report.update(summary=summary, few_contacts=few_contacts, markdown=markdown(
        summary, report["repeats"], report.get("passes", 1), out_of_running,
        report.get("cold_repeats", 0), report.get("seeds"), few_contacts, cap))
    return report
