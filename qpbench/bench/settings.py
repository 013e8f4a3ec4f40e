"""What a run is: the matrix problems x solvers x accuracy levels x modes, and its limits.

A *cell* is one entry of the matrix; its key ``(problem, solver, formulation, accuracy,
mode)`` identifies it in the results, so a resumed run skips the cells already there.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from qpbench.errors import QpbenchError

MODES = ("cold", "warm")

# the verdicts of qpbench.solvers.run.judge on an answer (no-solution: the problem has none;
# below-floor: the level is below the least residual a double vector is known to reach on it)
VERDICTS = ("solved", "inaccurate", "failed", "no-solution", "below-floor")
# statuses the harness gives a cell whose solve did not return an answer to judge
CRASHED = "crashed"  # the worker died of its own fault: a fatal signal or an exit code
KILLED = "killed"  # the worker died of a signal sent from outside (SIGKILL, SIGTERM, ...)
TIMEOUT = "timeout"  # the runner killed the worker at the wall-clock limit
OUT_OF_MEMORY = "out-of-memory"  # an allocation failed under the cap, or the kernel's OOM kill
ERROR = "error"  # the cell could not be set up (problem file, solver) or judged
HARNESS_STATUSES = (CRASHED, KILLED, TIMEOUT, OUT_OF_MEMORY, ERROR)
# every status a results row can carry, and so every status ``run --retry`` accepts
STATUSES = (*VERDICTS, *HARNESS_STATUSES)
# the statuses a plain resume solves again: a death the cell did not cause (a user's or
# another process's signal) says nothing about the solver; every other status is a finished
# cell, solved again only when named in ``--retry`` (after raising --timeout, say)
RETRIED_ON_RESUME = (KILLED,)
DEFAULT_ACCURACIES: tuple[float, ...] = (1e-4, 1e-8)
DEFAULT_TIMEOUT_S = 60.0
DEFAULT_MEMORY_LIMIT_MB = 4096
DEFAULT_REPEATS = 1

# the columns that identify one cell of the matrix (one row of the results)
CELL_KEY = ("problem", "solver", "formulation", "accuracy", "mode")


@dataclass(frozen=True)
class Cell:
    """One solve to run: a problem file, a solver ``NAME/FORMULATION``, a level, a mode."""

    problem_file: str
    problem: str
    solver: str
    formulation: str
    accuracy: float
    mode: str

    @property
    def key(self) -> tuple[str, str, str, float, str]:
        """(problem, solver, formulation, accuracy, mode), as in CELL_KEY."""
        return (self.problem, self.solver, self.formulation, float(self.accuracy), self.mode)

    @property
    def solver_key(self) -> str:
        return f"{self.solver}/{self.formulation}"

    def as_dict(self) -> dict[str, Any]:
        """Give the cell's fields as a dict.

        Returns
        -------
        dict
            ``problem_file``, ``problem``, ``solver``, ``formulation``, ``accuracy`` and ``mode``.
        """
        return asdict(self)


@dataclass(frozen=True)
class Limits:
    """Per-solve limits: wall clock (seconds, enforced by killing the worker process),
    address space of the worker (MiB, via resource.setrlimit), and timed repeats: up to
    ``repeats``, fewer once the repeats so far have taken ``repeat_budget_s`` of ``time_s``
    in all (so that fast solves, whose times vary most, are repeated, and slow ones are not)."""

    timeout_s: float = DEFAULT_TIMEOUT_S
    memory_limit_mb: int = DEFAULT_MEMORY_LIMIT_MB
    repeats: int = DEFAULT_REPEATS
    repeat_budget_s: float = math.inf

    def __post_init__(self) -> None:
        if not self.timeout_s > 0:
            raise QpbenchError(f"--timeout must be positive, got {self.timeout_s}")
        if self.repeats < 1:
            raise QpbenchError(f"--repeats must be at least 1, got {self.repeats}")
        if not self.repeat_budget_s > 0:
            raise QpbenchError(f"--repeat-budget must be positive, got {self.repeat_budget_s}")
        if self.memory_limit_mb < 0:
            raise QpbenchError(f"--memory-limit must be >= 0 (0: none), got {self.memory_limit_mb}")


PROBLEM_KINDS = ("impact", "frictional")


@dataclass(frozen=True)
class RunSettings:
    """The whole matrix and its limits, as the ``run`` command was given it."""

    solvers: tuple[str, ...]
    accuracies: tuple[float, ...] = DEFAULT_ACCURACIES
    modes: tuple[str, ...] = ("cold",)
    limits: Limits = field(default_factory=Limits)
    # the problem kinds run (``impact``, ``frictional``); the others' files are left out
    kinds: tuple[str, ...] = PROBLEM_KINDS

    def __post_init__(self) -> None:
        for kind in self.kinds:
            if kind not in PROBLEM_KINDS:
                raise QpbenchError(f"unknown problem kind '{kind}' (known: "
                                   f"{', '.join(PROBLEM_KINDS)})")
        for mode in self.modes:
            if mode not in MODES:
                raise QpbenchError(f"unknown mode '{mode}' (known: {', '.join(MODES)})")
        for accuracy in self.accuracies:
            check_accuracy(accuracy)


# the tightest level any command accepts (see check_accuracy)
ACCURACY_FLOOR = 1e-14


def check_accuracy(accuracy: float, option: str = "--accuracy") -> float:
    """Check that ``accuracy`` is a residual bound in [ACCURACY_FLOOR, 1).

    The floor, 1e-14, is where a relative residual computed in double precision still
    certifies the answer rather than the rounding (residual of docs/design.md section 2): each
    entry of ``w = Q l + b`` sums k + 1 terms (k the contacts that share a body with that
    one), and rounding alone moves it by up to about ``(k + 1) * 1.1e-16`` times the sum of
    their magnitudes, which is at least ``||b||_inf`` once the impulses cancel the approach
    velocity. With the tens of neighbours a contact has in a dense pile that bound reaches a
    few 1e-15; 1e-14 stays above it, while 1e-15 and below would pass or fail on rounding.

    Parameters
    ----------
    accuracy : float
        The relative residual bound to check.
    option : str, optional
        The option named in the error; ``--accuracy`` by default.

    Returns
    -------
    float
        ``accuracy`` itself.

    Raises
    ------
    QpbenchError
        On NaN, infinity, zero, a negative value, 1 or more, or a value below the floor.
    """
    if not 0 < accuracy < 1:
        raise QpbenchError(f"{option}: accuracy levels must lie in (0, 1), got {accuracy}")
    if not accuracy >= ACCURACY_FLOOR:
        raise QpbenchError(f"{option}: {accuracy:g} is below {ACCURACY_FLOOR:g}, the smallest "
                           "relative residual double precision can certify")
    return accuracy


def check_at_least(value: float, minimum: float, option: str) -> None:
    """Check that ``value >= minimum`` (NaN is refused).

    Parameters
    ----------
    value : float
        The option's value.
    minimum : float
        The smallest value allowed.
    option : str
        The option named in the error.

    Raises
    ------
    QpbenchError
        When ``value`` is below ``minimum`` or NaN.
    """
    if not value >= minimum:
        raise QpbenchError(f"{option} must be at least {minimum}, got {value}")


def parse_accuracies(text: str) -> tuple[float, ...]:
    """Parse a comma-separated list of accuracy levels: ``"1e-4,1e-8"`` -> (1e-4, 1e-8).

    Parameters
    ----------
    text : str
        The ``--accuracy`` value; empty items are skipped.

    Returns
    -------
    tuple of float
        The levels, in the order given.

    Raises
    ------
    QpbenchError
        On a value that is not a number or not a level :func:`check_accuracy` accepts, or when
        no level is given.
    """
    levels = []
    for part in text.split(","):
        if not part.strip():
            continue
        try:
            levels.append(check_accuracy(float(part)))
        except ValueError as error:
            raise QpbenchError(f"--accuracy: '{part.strip()}' is not a number") from error
    if not levels:
        raise QpbenchError("--accuracy: no level given")
    return tuple(levels)


def parse_modes(text: str) -> tuple[str, ...]:
    """Parse a comma-separated list of modes: ``"cold,warm"`` -> ("cold", "warm").

    Parameters
    ----------
    text : str
        The ``--mode`` value; empty items are skipped.

    Returns
    -------
    tuple of str
        The modes, in the order given.

    Raises
    ------
    QpbenchError
        On a mode not in MODES, or when no mode is given.
    """
    modes = tuple(part.strip() for part in text.split(",") if part.strip())
    for mode in modes:
        if mode not in MODES:
            raise QpbenchError(f"--mode: unknown mode '{mode}' (known: {', '.join(MODES)})")
    if not modes:
        raise QpbenchError("--mode: no mode given")
    return modes


def parse_statuses(text: str) -> tuple[str, ...]:
    """Parse a comma-separated list of statuses: ``"timeout,crashed"`` -> ("timeout", "crashed").

    Parameters
    ----------
    text : str
        The ``--retry`` value; empty items are skipped.

    Returns
    -------
    tuple of str
        The statuses, in the order given.

    Raises
    ------
    QpbenchError
        On a status no row can carry (one not in STATUSES), listing the known ones.
    """
    statuses = tuple(part.strip() for part in text.split(",") if part.strip())
    for status in statuses:
        if status not in STATUSES:
            raise QpbenchError(f"--retry: unknown status '{status}' (known: "
                               f"{', '.join(STATUSES)})")
    return statuses


def parse_solver_names(text: str) -> list[str]:
    """Parse a comma-separated list of solver names.

    ``"pi-robust, osqp/dual"`` -> ["pi-robust", "osqp/dual"].

    Parameters
    ----------
    text : str
        The ``--solvers`` value; items are stripped and empty ones skipped.

    Returns
    -------
    list of str
        The names, in the order given.

    Raises
    ------
    QpbenchError
        When the list names no solver at all (``""``, ``","``).
    """
    names = [part.strip() for part in text.split(",") if part.strip()]
    if not names:
        raise QpbenchError(f"--solvers: no solver named in '{text}' (name one or more, "
                           "comma-separated, or leave the option out for every usable one)")
    return names


def cells(problems: list[tuple[str, str]], solver_keys: list[str], settings: RunSettings
          ) -> list[Cell]:
    """List every cell of the matrix, problem-major.

    Parameters
    ----------
    problems : list of tuple of (str, str)
        (file, name) of each problem.
    solver_keys : list of str
        ``NAME/FORMULATION`` of each solver pair.
    settings : RunSettings
        The accuracy levels and modes of the matrix.

    Returns
    -------
    list of Cell
        One cell per problem, pair, level and mode, in that nesting order.
    """
    matrix = []
    for problem_file, name in problems:
        for solver_key in solver_keys:
            solver, formulation = solver_key.split("/", 1)
            for accuracy in settings.accuracies:
                for mode in settings.modes:
                    matrix.append(Cell(problem_file, name, solver, formulation, float(accuracy),
                                       mode))
    return matrix
