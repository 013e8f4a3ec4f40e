"""What the import commands (``import-siconos``, ``import-fclib``) share: writing the problems
they read, each with its reference."""

from __future__ import annotations

import sys

from qpbench.bench.reduced_reference import attach, flag
from qpbench.problem import files
from qpbench.problem.files import AnyProblem


def save_imported(problems: list[AnyProblem], folder: str, command: str,
                  with_reference: bool) -> None:
    """Writes each imported problem to ``folder/<name>.npz`` and prints its path, after
    attaching its reference when ``with_reference`` (a flagged reference is said on stderr,
    ``qpbench COMMAND: NAME: reference flagged: WHY``)."""
    for problem in problems:
        if with_reference:
            attach(problem)
            why = flag(problem)
            if why:
                print(f"qpbench {command}: {problem.name}: reference flagged: {why}",
                      file=sys.stderr)
        print(files.save(problem, f"{folder}/{problem.name}"))
