"""``qpbench solvers [--json]``: every solver and formulation, version, usable or why not."""

from __future__ import annotations

import argparse

from qpbench.cli.output import print_json
from qpbench.solvers.registry import all_solvers

JSON_FIELDS = "Every JSON field, its unit and when it is null: docs/json-output.md"
# the problem kinds as the output names them (``SolverSpec.kinds`` calls frictionless
# impact problems ``impact``)
KIND_NAMES = {"impact": "frictionless", "frictional": "frictional"}


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``qpbench solvers`` and its ``--json`` option.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``qpbench`` parser's subcommands, to which this one is added.
    """
    parser = subparsers.add_parser("solvers", help="list solvers, formulations and availability",
                                   epilog=JSON_FIELDS)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Print every solver and formulation with its backend, version and usability.

    As a table with a closing count per formulation, or one JSON object with ``--json``.

    Parameters
    ----------
    args : argparse.Namespace
        The options of :func:`add_parser`: ``json``.

    Returns
    -------
    int
        The exit status: 0.
    """
    rows = [
        {"name": s.name, "formulation": s.formulation, "backend": s.backend,
         "version": s.version, "usable": s.usable, "reason": s.reason,
         "kinds": [KIND_NAMES[kind] for kind in KIND_NAMES if kind in s.kinds]}
        for s in all_solvers()
    ]
    if args.json:
        print_json({"solvers": rows})
        return 0
    width = max((len(f"{r['name']}/{r['formulation']}") for r in rows), default=10)
    backend_width = max((len(r["backend"]) for r in rows), default=10)
    version_width = max((len(r["version"]) for r in rows), default=10)
    for row in rows:
        key = f"{row['name']}/{row['formulation']}"
        state = "usable" if row["usable"] else f"unusable: {row['reason']}"
        print(f"{key:<{width}}  {row['backend']:<{backend_width}}  "
              f"{row['version']:<{version_width}}  {state}")
    usable = [r for r in rows if r["usable"]]
    formulations = sorted({r["formulation"] for r in usable})
    per_formulation = ", ".join(
        f"{formulation} {sum(r['formulation'] == formulation for r in usable)}"
        for formulation in formulations)
    print(f"{len(usable)} usable of {len(rows)} ({per_formulation})")
    return 0
