"""What every solver is and returns.

A solver is a :class:`SolverSpec`: a name, the formulation it poses, the backend
family that runs it, and a ``solve(problem, accuracy, warm_start)`` function
returning a :class:`SolverOutput`. qpbench judges the output with its own
metrics (``qpbench.metrics``); ``claimed_success`` is only recorded, to measure
status honesty.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from qpbench.problem.impact import ImpactProblem


@dataclass
class SolverOutput:
    """One solve as the solver reported it.

    ``solve_time_s`` times the solver call alone; ``setup_time_s`` the conversions
    and model building before it (cvxpy's compile time, matrix formats).
    """

    impulses: np.ndarray | None
    status: str
    claimed_success: bool
    solve_time_s: float
    setup_time_s: float = 0.0
    iterations: int | None = None
    info: dict[str, Any] = field(default_factory=dict)


class SolveFunction(Protocol):
    def __call__(
        self, problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
    ) -> SolverOutput: ...


@dataclass(frozen=True)
class SolverSpec:
    """A solver and formulation pair that qpbench can run (or says why it cannot)."""

    name: str
    formulation: str
    backend: str
    solve: SolveFunction | None
    version: str = ""
    warm_start: bool = False
    description: str = ""
    reason: str = ""  # why it is not usable; empty when usable

    @property
    def key(self) -> str:
        """``NAME/FORMULATION``."""
        return f"{self.name}/{self.formulation}"

    @property
    def usable(self) -> bool:
        return self.solve is not None and not self.reason


class Stopwatch:
    """Measures wall time of a block with ``time.perf_counter``: ``with Stopwatch() as t: ...``."""

    def __enter__(self) -> Stopwatch:
        self.start = time.perf_counter()
        self.elapsed = 0.0
        return self

    def __exit__(self, *exc: object) -> None:
        self.elapsed = time.perf_counter() - self.start


def timed(call: Callable[[], Any]) -> tuple[Any, float]:
    """Runs ``call()`` and returns (its result, seconds it took)."""
    start = time.perf_counter()
    result = call()
    return result, time.perf_counter() - start
