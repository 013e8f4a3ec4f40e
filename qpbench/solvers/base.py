"""What every solver is and returns.

A solver is a :class:`SolverSpec`: a name, the formulation it poses, the backend
family that runs it, and a ``solve(problem, accuracy, warm_start)`` function
returning a :class:`SolverOutput`. qpbench judges the output with its own
metrics (``qpbench.problem.metrics``); ``claimed_success`` is only recorded, to measure
status honesty.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from qpbench.problem.impact import ImpactProblem

# the parts of a solve that a backend reports itself, stored beside ``time_s``, never as it
BACKEND_TIMES = ("compile_time_s", "backend_setup_time_s", "backend_solve_time_s")
# what time_s covers, in the words the README and the report use
TIME_S_COVERS = ("`time_s` is the wall time, on one stopwatch around every solver alike, from "
                 "the formulation's matrices to l as a NumPy array: conversion to the "
                 "backend's format, its set-up and factorizations, the solve and reading the "
                 "answer back (cvxpy's compile step included); the minimum over repeats.")
# SolverOutput.info keys of a solver that times itself (SolverSpec.reports_own_time): the time
# it measured across the same boundary, and the harness's stopwatch around the whole call
OWN_TIME = "own_time_s"
ROUND_TRIP_TIME = "round_trip_time_s"


def reported_times(**seconds: Any) -> dict[str, float]:
    """The backend-reported times among ``seconds`` that are numbers.

    A backend that recorded none of them gives an empty dict.

    Parameters
    ----------
    **seconds : Any
        Times keyed by names in BACKEND_TIMES, in seconds; a value that is not a number
        (None, a string, a bool) is left out.

    Returns
    -------
    dict[str, float]
        The numeric values as floats, under their keys.

    Raises
    ------
    ValueError
        When a key is not one of BACKEND_TIMES.
    """
    unknown = set(seconds) - set(BACKEND_TIMES)
    if unknown:
        raise ValueError(f"not a backend time: {sorted(unknown)}")
    return {key: float(value) for key, value in seconds.items()
            if isinstance(value, int | float | np.floating) and not isinstance(value, bool)}


@dataclass
class SolverOutput:
    """One solve as the solver reported it, and the harness's two times of it.

    A solve function fills ``impulses`` (l in the problem's contact order), ``status`` (the
    backend's own words), ``claimed_success``, ``iterations`` and ``backend_times`` (keys
    of BACKEND_TIMES: cvxpy's compile time, a backend's own set-up/solve split), and never
    times itself. :func:`qpbench.solvers.run.call_solver` sets ``time_s``: the wall time from
    the formulation's matrices to l as a NumPy array (conversions, set-up, solve, reading
    back), and ``formulation_time_s``: building those matrices from G, M^-1 and v-.
    """

    impulses: np.ndarray | None
    status: str
    claimed_success: bool
    iterations: int | None = None
    backend_times: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    time_s: float = math.nan
    formulation_time_s: float = math.nan


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
    # loads what the solver needs once per process (a compiled kernel), before any timed solve;
    # called by the harness each time, so it must return at once after the first call
    prepare: Callable[[], None] | None = None
    # stops on qpbench's own residual, so its claim agrees with the verdict by construction
    own_stopping_rule: bool = False
    # the problem kinds it takes: "impact" (ImpactProblem) and/or "frictional"
    # (FrictionalProblem, whose impulses are r = (l_N, l_T))
    kinds: tuple[str, ...] = ("impact",)
    # solves in another process, which times the same boundary itself (from the arrays it
    # received to l) and returns it as info[OWN_TIME]: that becomes time_s, and the harness's
    # stopwatch (the round trip, messages included) is kept as info[ROUND_TRIP_TIME]
    reports_own_time: bool = False

    @property
    def key(self) -> str:
        """``NAME/FORMULATION``."""
        return f"{self.name}/{self.formulation}"

    @property
    def usable(self) -> bool:
        return self.solve is not None and not self.reason


class Stopwatch:
    """Measures wall time of a block with ``time.perf_counter``: ``with Stopwatch() as t: ...``.

    Python's cyclic garbage collector is paused inside the block (as ``timeit`` does) and
    restored after it: a collection there would be triggered by garbage the harness left
    behind (posing, judging, result tables), not by the timed solve, and would make the
    repeated timings of a solve of tens of microseconds vary from one round to the next.
    Reference counting still frees every object outside a cycle inside the block."""

    def __enter__(self) -> Stopwatch:
        self.collecting = gc.isenabled()
        gc.disable()
        self.start = time.perf_counter()
        self.elapsed = 0.0
        return self

    def __exit__(self, *exc: object) -> None:
        self.elapsed = time.perf_counter() - self.start
        if self.collecting:
            gc.enable()

