"""``qpbench solve PROBLEM --solver NAME [--accuracy EPS] [--json]``."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from qpbench.bench.settings import check_accuracy
from qpbench.cli.output import plain, print_json
from qpbench.problem import files
from qpbench.problem.friction import KIND as FRICTIONAL
from qpbench.problem.friction import kind_of
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"
# the keys of the text output, in order (the JSON has these and the answer itself)
TEXT_KEYS = ("problem", "solver", "status", "solver_status", "residual", "v_error", "model",
             "coulomb_residual", "model_error", "energy_gain", "iterations", "outer_iterations",
             "time_s")
NO_ANSWER = "none (no finite answer)"
# what a missing value (None, NaN) means, per key of the text output, when the answer is finite
MISSING = {
    "v_error": "none (a ccp answer solves another model than the reference's)",
    "model_error": "none (the formulation solves Coulomb's law itself)",
    "iterations": "not reported by the solver",
    "outer_iterations": "none (no outer loop)",
    "time_s": "not measured",
}


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench solve`` and its options (problem, ``--solver``, ``--accuracy``, JSON).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("solve", help="solve one problem file and judge the answer",
                                   epilog=JSON_FIELDS)
    parser.add_argument("problem", help="a problem file (.npz)")
    parser.add_argument("--solver", required=True, help="NAME or NAME/FORMULATION")
    parser.add_argument("--accuracy", type=float, default=1e-8, help="residual bound (1e-8)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Solve one problem file, judge the answer and print it, as text or one JSON object.

    The answer is judged by qpbench's own residual (:func:`qpbench.solvers.run.solve_and_judge`),
    its velocity error against a verified reference, and for a frictional problem its Coulomb
    model metrics.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``problem``, ``solver``, ``accuracy`` and ``json``.

    Returns
    -------
    int
        The exit status: 0 when the answer meets the accuracy, 1 (with one line on stderr) when
        not.

    Raises
    ------
    QpbenchError
        When the accuracy is out of range, the problem file does not read, or the solver is
        unknown or does not fit the problem's kind.
    """
    check_accuracy(args.accuracy)
    problem = files.load(args.problem)
    spec = get(args.solver, kind_of(problem))
    row, output = solve_and_judge(spec, problem, args.accuracy)
    result = {
        "problem": problem.name,
        "solver": spec.key,
        "status": row["status"],
        "solver_status": row["solver_status"],
        "success": row["success"],
        "lambda": output.impulses,
        "v_plus": problem.v_plus(output.impulses) if output.impulses is not None else None,
        "residual": row["residual"],
        "energy_gain": row["energy_gain"],
        "iterations": row["iterations"],
        "time_s": row["time_s"],
    }
    if kind_of(problem) == FRICTIONAL:  # r = (l_N, l_T); the model its formulation solves
        for key in ("model", "mu_max", "coulomb_residual", "model_error", "outer_iterations"):
            result[key] = row.get(key)
    if problem.reference is not None and problem.reference.verified:
        result["v_error"] = row["v_error"]
    if args.json:
        print_json(result)
    else:
        answered = _finite(result["residual"])
        for key in TEXT_KEYS:
            if key in result:
                missing = MISSING.get(key, "none") if answered or key == "time_s" \
                    else NO_ANSWER
                text = plain(result[key], missing, seconds=key == "time_s")
                print(f"{key:>16}: {text}")
    if row["success"]:
        return 0
    print(f"qpbench solve: {args.problem}: {spec.key} missed the accuracy asked "
          f"({args.accuracy:g}): status {row['status']}, residual "
          f"{plain(row['residual'], NO_ANSWER)}", file=sys.stderr)
    return 1


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)
