"""The worker process: runs cells one at a time, inside its own process, for the runner.

A worker is forked by a multiprocessing fork server that has imported every solver
backend once (:func:`child_main`, messages over a Pipe), or, where a process may not
have children of its own (a daemonic Dask worker), started as the program
``python -m qpbench.bench.worker`` (:func:`main`, JSON lines on stdin/stdout). Solver
output goes to a log file or stderr, never into the messages. For each request it
says ``begin`` before and ``end`` after every solver call (the warm-up and each timed
repeat), so the runner can enforce the wall-clock limit per solve, then sends the ``row``.
When the runner has gone (its end of the messages closed), the worker ends quietly.

Before the first timed solve of a (problem, solver, formulation) the worker solves that
same problem once untimed (:meth:`CellSolver.warm_up`), so that no accuracy level is
charged for caches and lazy set-up that only the first call in a process pays.

The address space of the process is limited with ``resource.setrlimit`` (an
allocation beyond it raises MemoryError, which becomes the status
``out-of-memory``; without a cap a MemoryError is the solver's error, judged as such).
Numerical libraries are kept to one thread each (the runner sets
OPENBLAS/OMP/MKL_NUM_THREADS) so times do not depend on how many workers share the cores.
"""

from __future__ import annotations

import contextlib
import datetime
import json
import math
import os
import signal
import statistics
import sys
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from qpbench import EXTRA_SOLVERS_ENV
from qpbench.bench.provenance import provenance
from qpbench.bench.settings import OUT_OF_MEMORY, Cell, Limits
from qpbench.memory import limit_memory
from qpbench.memory import virtual_memory_mb as virtual_memory_mb  # imported from here too
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import BACKEND_TIMES, SolverOutput, SolverSpec
from qpbench.solvers.registry import all_solvers, resolve
from qpbench.solvers.run import call_solver, judge


def timer_overhead_s(samples: int = 2000) -> float:
    """The smallest gap between two back-to-back ``time.perf_counter()`` calls (seconds):
    the resolution below which a measured solve time means nothing."""
    best = math.inf
    for _ in range(samples):
        start = time.perf_counter()
        best = min(best, time.perf_counter() - start)
    return best


def warm_start_for(problem: ImpactProblem | FrictionalProblem) -> tuple[np.ndarray | None, str]:
    """The warm start of ``problem`` and where it came from.

    * ``previous``: the impulses the simulator carried into this step from the previous one
      (``problem.data["warm_start"]``, stored by a capture of a scene that caches impulses,
      as SCISim's ``cache_impulses``): what a simulator has;
    * ``none``: the problem carries none; the solve is then a cold start.

    Never anything derived from the reference: a solver must not see the answer it is judged
    against (sequence mode, ``qpbench sequence``, warm-starts every solver from its own
    answers instead).
    """
    previous = problem.data.get("warm_start")
    size = problem.n_contacts * (2 if isinstance(problem, FrictionalProblem) else 1)
    if previous is not None and np.shape(previous) == (size,):
        return np.asarray(previous, dtype=float), "previous"
    return None, "none"


def prepare_solvers() -> None:
    """Imports every backend and runs each usable solver's ``prepare`` (e.g. loading a compiled
    kernel) once in this process, so that no timed solve pays for it."""
    for spec in all_solvers():
        if spec.usable and spec.prepare is not None:
            spec.prepare()


def _finite(values: list[float]) -> list[float]:
    return [value for value in values if value is not None and math.isfinite(value)]


class CellSolver:
    """Runs cells in this process, keeping the last problem loaded (cells come problem-major)
    and warming each solver up on it once (:meth:`warm_up`)."""

    def __init__(self, announce: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.announce = announce
        self._problem_file: str | None = None
        self._problem: ImpactProblem | None = None
        self._specs: dict[str, SolverSpec] = {}
        self._warmed: set[str] = set()  # the solver keys warmed up on the loaded problem
        self.timer_overhead_s = timer_overhead_s()
        self.provenance = provenance()
        self.memory_limit_mb = 0

    def say(self, event: str, **fields: Any) -> None:
        if self.announce is not None:
            self.announce({"event": event, **fields})

    def problem(self, path: str) -> ImpactProblem:
        if path != self._problem_file:
            self._problem, self._problem_file = None, None
            self._warmed.clear()
            self._problem = files.load(path)
            self._problem_file = path
        assert self._problem is not None
        return self._problem

    def spec(self, key: str) -> SolverSpec:
        if key not in self._specs:
            self._specs[key] = resolve([key])[0]
        return self._specs[key]

    def warm_up(self, spec: SolverSpec, problem: ImpactProblem | FrictionalProblem,
                accuracy: float, warm_start: np.ndarray | None) -> None:
        """Solves ``problem`` once with ``spec``, exactly as the timed solves will (a blind
        copy posed in the solver's formulation, the same warm start), and discards the
        answer and its time, the first time this process meets the pair: the first call
        fills the caches and does the lazy set-up (a backend's imports and code paths, the
        problem's own arrays) that every later call finds done, so every timed level of the
        pair sees the same state. The runner's wall-clock limit applies to it as to a timed
        solve."""
        if spec.key in self._warmed:
            return
        self._warmed.add(spec.key)
        self.say("begin", warm_up=True, memory_limit_mb=self.memory_limit_mb)
        call_solver(spec, problem, accuracy, warm_start)
        self.say("end", warm_up=True)

    def solve(self, cell: Cell, limits: Limits) -> dict[str, Any]:
        """The row of ``cell``: qpbench's judgement of the first repeat's answer, the times of
        all repeats (``time_s`` their minimum; up to ``limits.repeats``, fewer once they have
        taken ``limits.repeat_budget_s`` in all, none after a failed solve). The first cell of
        a (problem, solver, formulation) in this process is preceded by :meth:`warm_up` at
        its level."""
        problem = self.problem(cell.problem_file)
        spec = self.spec(cell.solver_key)
        warm_start, warm_source = (None, "cold")
        if cell.mode == "warm":
            warm_start, warm_source = warm_start_for(problem)
        self.warm_up(spec, problem, cell.accuracy, warm_start)
        outputs: list[SolverOutput] = []
        for repeat in range(limits.repeats):
            # the runner's clock for --timeout starts
            self.say("begin", repeat=repeat, memory_limit_mb=self.memory_limit_mb)
            output = call_solver(spec, problem, cell.accuracy, warm_start)
            self.say("end", repeat=repeat)
            outputs.append(output)
            if output.impulses is None:
                break  # a failed solve is not repeated
            if sum(done.time_s for done in outputs) >= limits.repeat_budget_s:
                break
        row = judge(spec, problem, outputs[0], cell.accuracy)
        if (self.memory_limit_mb > 0
                and str(row.get("solver_status", "")).startswith("error: MemoryError")):
            row["status"] = OUT_OF_MEMORY  # the allocation failed under the cap
        finite_times = _finite([output.time_s for output in outputs])
        row.update({
            "mode": cell.mode,
            "warm_start_source": warm_source,
            "warm_start_used": bool(warm_start is not None and spec.warm_start),
            "repeats": len(outputs),
            "time_s": min(finite_times) if finite_times else math.nan,
            "time_median_s": statistics.median(finite_times) if finite_times else math.nan,
            "time_max_s": max(finite_times) if finite_times else math.nan,
            "formulation_time_s": min(_finite([o.formulation_time_s for o in outputs]),
                                      default=math.nan),
            **{column: min(_finite([o.backend_times.get(column, math.nan) for o in outputs]),
                           default=math.nan) for column in BACKEND_TIMES},
            "timer_overhead_s": self.timer_overhead_s,
            "memory_limit_mb": self.memory_limit_mb,
            "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            **self.provenance,
        })
        return row


def serve(receive: Callable[[], dict[str, Any] | None],
          send: Callable[[dict[str, Any]], None]) -> None:
    """Answers each request ``{"cell": ..., "limits": ...}`` (until ``receive`` gives None) with
    begin/end events and a row (or ``{"event": "error"}`` if the cell could not be set up).
    A message that cannot be sent (the runner closed its end: it stopped or was interrupted)
    ends the process quietly (SystemExit 0), with no traceback in its log."""

    def send_or_leave(message: dict[str, Any]) -> None:
        try:
            send(message)
        except (OSError, EOFError, ValueError):  # BrokenPipeError, a closed connection
            raise SystemExit(0) from None

    solver = CellSolver(announce=send_or_leave)
    prepare_solvers()  # every backend imported and prepared before the memory cap and timing
    solver.say("ready", pid=os.getpid())
    while (request := receive()) is not None:
        cell = Cell(**request["cell"])
        limits = Limits(**request["limits"])
        if not solver.memory_limit_mb and limits.memory_limit_mb:
            solver.memory_limit_mb = limit_memory(limits.memory_limit_mb)
        try:
            row = solver.solve(cell, limits)
        except MemoryError:  # outside the solver call: loading the problem or judging
            if solver.memory_limit_mb > 0:
                solver.say("row", row={"status": OUT_OF_MEMORY, "solver_status": "MemoryError",
                                       "memory_limit_mb": solver.memory_limit_mb})
            else:
                solver.say("error", message="MemoryError (no memory cap set)")
            continue
        except Exception as error:  # a problem file or solver that cannot be set up
            solver.say("error", message=f"{type(error).__name__}: {error}")
            continue
        solver.say("row", row=row)


def die_with_parent() -> None:
    """Asks Linux to SIGKILL this process when the runner dies (even by kill -9), so no
    orphaned worker keeps solving; a no-op elsewhere."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:  # the process that started this one is already gone
        os._exit(1)


def _plain(value: Any) -> Any:
    """numpy scalars and arrays as Python values, for JSON."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot send {type(value).__name__}")


def main() -> None:
    """Entry point of a worker started as a program: JSON lines on stdin and on a private copy
    of stdout (stray solver output goes to stderr)."""
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the runner's to handle
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "w", encoding="utf-8")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())

    def receive() -> dict[str, Any] | None:
        for line in sys.stdin:
            if line.strip():
                return json.loads(line)
        return None

    def send(message: dict[str, Any]) -> None:
        answers.write(json.dumps(message, default=_plain) + "\n")
        answers.flush()

    serve(receive, send)


def child_main(connection: Connection, log_path: str, extra_solvers: str = "",
               search_path: list[str] | None = None) -> None:
    """Entry point of a worker forked by the multiprocessing fork server: messages on
    ``connection``; stdout and stderr go to ``log_path``; the runner's current
    $QPBENCH_EXTRA_SOLVERS and module search path are taken over."""
    try:  # never created here: a log that is gone means the runner has stopped this worker
        log = os.open(log_path, os.O_WRONLY | os.O_APPEND)
    except OSError:
        os._exit(0)
    with contextlib.suppress(OSError):  # the runner reads it through its own descriptor
        os.unlink(log_path)
    os.dup2(log, 1)
    os.dup2(log, 2)
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the runner's to handle
    if extra_solvers:
        os.environ[EXTRA_SOLVERS_ENV] = extra_solvers
    else:
        os.environ.pop(EXTRA_SOLVERS_ENV, None)
    sys.path.extend(entry for entry in (search_path or []) if entry not in sys.path)

    def receive() -> dict[str, Any] | None:
        try:
            return connection.recv()
        except (EOFError, OSError):
            return None

    serve(receive, connection.send)


if __name__ == "__main__":
    main()
