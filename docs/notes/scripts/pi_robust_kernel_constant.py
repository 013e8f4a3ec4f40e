"""Compare pi-robust's compiled kernel with one of its module constants changed.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_kernel_constant.py MODULE NAME
VALUE... [--quick] [--folder DIR]``, e.g. ``active_set UPDATE_FIXED 0 4`` (row deletions for
few fixed contacts, against refactoring), ``active_set UPDATE_SPREAD 1e6 inf`` (the spread
gate), ``prox DRIFT_RATIO 0.999 inf`` (the drift rule; inf: never).
numba reads a module's globals when it compiles, so each value runs in its own process with
its own, empty numba cache (each compiles the kernel: about a minute).
"""

from __future__ import annotations

import ast
import importlib
import json
import sys

from pi_robust_common import (
    folder_argument,
    groups,
    quick_flag,
    results_in_children,
    run,
    table,
    words,
)


def child(module: str, name: str, value: object, quick: bool) -> None:
    """Set the constant before anything compiles, then print the groups' results as JSON."""
    kernel_module = importlib.import_module(f"qpbench.solvers.pi_robust_kernel.{module}")
    setattr(kernel_module, name, value)
    results = {group: run(problems, 1 if quick else 5) for group, problems in groups(quick)}
    print(json.dumps(results))


def main() -> None:
    given = words()
    module, name, values = given[0], given[1], given[2:]
    quick = quick_flag()
    if "--child" in sys.argv:
        text = values[0]
        child(module, name, float("inf") if text == "inf" else ast.literal_eval(text), quick)
        return
    results, names = results_in_children(values, lambda value: [
        __file__, module, name, value, "--child", *(["--quick"] if quick else []),
        *(["--folder", str(folder_argument())] if folder_argument() else [])])
    table(f"pi-robust at 1e-8, {module}.{name} = {' / '.join(values)}", values, results, names)


if __name__ == "__main__":
    main()
