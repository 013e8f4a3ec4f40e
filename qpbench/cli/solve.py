"""``qpbench solve PROBLEM --solver NAME [--accuracy EPS] [--json]``."""

from __future__ import annotations

import argparse

from qpbench.bench.settings import check_accuracy
from qpbench.cli.output import print_json
from qpbench.problem import files
from qpbench.problem.friction import KIND as FRICTIONAL
from qpbench.problem.friction import kind_of
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("solve", help="solve one problem file and judge the answer")
    parser.add_argument("problem", help="a problem file (.npz)")
    parser.add_argument("--solver", required=True, help="NAME or NAME/FORMULATION")
    parser.add_argument("--accuracy", type=float, default=1e-8, help="residual bound (1e-8)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
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
        for key in ("problem", "solver", "status", "solver_status", "residual", "v_error",
                    "model", "coulomb_residual", "model_error", "energy_gain", "iterations",
                    "outer_iterations", "time_s"):
            if key in result:
                print(f"{key:>16}: {result[key]}")
    return 0 if row["success"] else 1
