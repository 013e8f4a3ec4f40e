"""What the import commands (``import-siconos``, ``import-fclib``) share: writing the problems
they read, each with its reference."""

from __future__ import annotations

import sys

from qpbench.bench.reduced_reference import attach, flag
from qpbench.problem import files
from qpbench.problem.files import AnyProblem


def save_imported(problems: list[AnyProblem], folder: str, command: str,
                  with_reference: bool) -> None:
    """Write each imported problem to ``folder/<name>.npz`` and print its path.

    Each problem's reference is attached first when ``with_reference``; a flagged reference is
    said on stderr, ``qpbench COMMAND: NAME: reference flagged: WHY``.

    Parameters
    ----------
    problems : list of AnyProblem
        The problems read, frictionless or frictional.
    folder : str
        The output folder.
    command : str
        The command's name, for the stderr lines.
    with_reference : bool
        Whether to compute and attach each problem's reference.
    """
    for problem in problems:
        if with_reference:
            attach(problem)
            why = flag(problem)
            if why:
                print(f"qpbench {command}: {problem.name}: reference flagged: {why}",
                      file=sys.stderr)
        print(files.save(problem, f"{folder}/{problem.name}"))
