"""The worker process: runs cells one at a time, inside its own process, for the runner.

A worker is forked by a multiprocessing fork server that has imported every solver
backend once (:func:`child_main`, messages over a Pipe), or, where a process may not
have children of its own (a daemonic Dask worker), started as the program
``python -m qpbench.bench.worker`` (:func:`main`, JSON lines on stdin/stdout). Solver
output goes to a log file or stderr, never into the messages. Each request is a batch of
cells (several problems and pairs), run under the timing protocol of docs/design.md
section 7 (:meth:`CellSolver.solve_batch`): no cell's repeats back to back, but round after
round of every cell in a rotated order. The worker says ``load`` before setting a cell up,
``begin`` before and ``end`` after every solver call (the warm-up and each timed repeat),
each naming the cell, so the runner can enforce the wall-clock limit per solve and knows
which cell was running when the process died, and sends each cell's ``row`` once the cell
is done. When the runner has gone (its end of the messages closed), the worker ends quietly.

Before the first timed solve of a (problem, solver, formulation) the worker solves that
same problem once untimed (:meth:`CellSolver.warm_up`), in the batch's warm-up round, so
that no accuracy level is charged for caches and lazy set-up that only the first call in a
process pays.

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
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from qpbench import EXTRA_SOLVERS_ENV
from qpbench.bench.provenance import provenance
from qpbench.bench.schedule import Schedule, fastest
from qpbench.bench.settings import OUT_OF_MEMORY, Cell, Limits
from qpbench.memory import limit_memory
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import BACKEND_TIMES, SolverOutput, SolverSpec
from qpbench.solvers.registry import all_solvers, resolve
from qpbench.solvers.run import call_solver, judge


def timer_overhead_s(samples: int = 2000) -> float:
    """Measure the resolution below which a measured solve time means nothing.

    It is the smallest gap between two back-to-back ``time.perf_counter()`` calls.

    Parameters
    ----------
    samples : int, optional
        Pairs of calls to take the minimum over; 2000 by default.

    Returns
    -------
    float
        The smallest gap in seconds.
    """
    best = math.inf
    for _ in range(samples):
        start = time.perf_counter()
        best = min(best, time.perf_counter() - start)
    return best


def warm_start_for(problem: ImpactProblem | FrictionalProblem) -> tuple[np.ndarray | None, str]:
    """Give the warm start of ``problem`` and where it came from.

    * ``previous``: the impulses the simulator carried into this step from the previous one
      (``problem.data["warm_start"]``, stored by a capture of a scene that caches impulses,
      as SCISim's ``cache_impulses``): what a simulator has;
    * ``none``: the problem carries none (or one of the wrong size); the solve is then a cold
      start.

    Never anything derived from the reference: a solver must not see the answer it is judged
    against (sequence mode, ``qpbench sequence``, warm-starts every solver from its own
    answers instead).

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to warm-start.

    Returns
    -------
    tuple of (numpy.ndarray or None, str)
        The warm start (n impulses, 2n for a frictional problem) or None, and ``previous`` or
        ``none``.
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
    """Runs batches of cells in this process under the timing protocol (docs/design.md
    section 7, ``qpbench.bench.schedule``): every (problem, solver/formulation) of a batch
    warmed up once (:meth:`warm_up`), then round after round of one timed solve of each cell
    still running, in the schedule's interleaved, rotated order."""

    def __init__(self, announce: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.announce = announce
        self._problems: dict[str, ImpactProblem | FrictionalProblem] = {}
        self._specs: dict[str, SolverSpec] = {}
        # the (problem file, solver key) pairs warmed up in this process
        self._warmed: set[tuple[str, str]] = set()
        self.timer_overhead_s = timer_overhead_s()
        self.provenance = provenance()
        self.memory_limit_mb = 0

    def say(self, event: str, **fields: Any) -> None:
        """Announce an event to the runner (nothing without an ``announce`` callback).

        Parameters
        ----------
        event : str
            The event's name (``ready``, ``load``, ``begin``, ``end``, ``row``, ``error``).
        **fields : Any
            The message's other fields (the cell's index, ...).
        """
        if self.announce is not None:
            self.announce({"event": event, **fields})

    def problem(self, path: str) -> ImpactProblem | FrictionalProblem:
        """Load the problem of ``path`` once per batch.

        Parameters
        ----------
        path : str
            The problem file.

        Returns
        -------
        ImpactProblem or FrictionalProblem
            The problem, kept until the batch ends.
        """
        if path not in self._problems:
            self._problems[path] = files.load(path)
        return self._problems[path]

    def spec(self, key: str) -> SolverSpec:
        """Resolve a solver key once per process.

        Parameters
        ----------
        key : str
            ``NAME/FORMULATION`` of the pair.

        Returns
        -------
        SolverSpec
            The pair's solver.
        """
        if key not in self._specs:
            self._specs[key] = resolve([key])[0]
        return self._specs[key]

    def warm_up(self, spec: SolverSpec, problem: ImpactProblem | FrictionalProblem,
                accuracy: float, warm_start: np.ndarray | None, problem_file: str = "",
                cell_index: int = 0) -> None:
        """Solve ``problem`` once untimed, the first time this process meets the pair on the file.

        The solve is exactly as the timed solves will be (a blind copy posed in the solver's
        formulation, the same warm start); its answer and its time are discarded. The first call
        fills the caches and does the lazy set-up (a backend's imports and code paths, the
        problem's own arrays) that every later call finds done, so every timed level of the pair
        sees the same state. The runner's wall-clock limit applies to it as to a timed solve
        (announced for the batch's ``cell_index``-th cell).

        Parameters
        ----------
        spec : SolverSpec
            The solver.
        problem : ImpactProblem or FrictionalProblem
            The problem.
        accuracy : float
            The accuracy level of the solve.
        warm_start : numpy.ndarray or None
            The warm start of the timed solves; None for a cold start.
        problem_file : str, optional
            The problem's file, which with the solver's key identifies the pair; ``""`` by default.
        cell_index : int, optional
            The index in the batch of the cell announced; 0 by default.
        """
        if (problem_file, spec.key) in self._warmed:
            return
        self._warmed.add((problem_file, spec.key))
        self.say("begin", cell=cell_index, warm_up=True, memory_limit_mb=self.memory_limit_mb)
        call_solver(spec, problem, accuracy, warm_start)
        self.say("end", cell=cell_index, warm_up=True)

    def solve_batch(self, cells: Sequence[Cell], limits: Limits
                    ) -> Iterator[tuple[int, dict[str, Any] | Exception]]:
        """Solve a batch of cells under the timing protocol, each outcome as it comes.

        Each cell's problem is loaded and its solver resolved (announced as ``load``), then
        a :class:`~qpbench.bench.schedule.Schedule` of the cells, with units (problem file,
        solver key), orders the calls: round 0 warms up each unit not yet warmed in this
        process on its first cell, at that cell's level and warm start; each later round
        times every cell still running once, announced as ``begin`` / ``end`` with the
        cell's index and repeat. A cell is done, and judged, after ``limits.repeats`` timed
        solves, or fewer once they have taken ``limits.repeat_budget_s`` in all, or after a
        failed solve (never repeated). Its row judges the first timed answer; ``time_s`` is
        the minimum over its interleaved repeats, ``time_median_s`` their median.

        Parameters
        ----------
        cells : sequence of Cell
            The batch's cells.
        limits : Limits
            The repeats and repeat budget of each cell.

        Yields
        ------
        tuple of (int, dict or Exception)
            The index in ``cells`` and the cell's row, or the exception of a cell that could not
            be set up or judged.
        """
        ready: dict[int, tuple[SolverSpec, ImpactProblem | FrictionalProblem,
                               np.ndarray | None, str]] = {}
        try:
            for index, cell in enumerate(cells):
                self.say("load", cell=index)
                try:
                    problem = self.problem(cell.problem_file)
                    spec = self.spec(cell.solver_key)
                except Exception as error:  # MemoryError included: the caller says which
                    yield index, error
                    continue
                warm_start, warm_source = (None, "cold")
                if cell.mode == "warm":
                    warm_start, warm_source = warm_start_for(problem)
                ready[index] = (spec, problem, warm_start, warm_source)
            yield from self._timed(cells, limits, ready)
        finally:
            self._problems.clear()

    def _timed(self, cells: Sequence[Cell], limits: Limits,
               ready: dict[int, tuple[SolverSpec, ImpactProblem | FrictionalProblem,
                                      np.ndarray | None, str]]
               ) -> Iterator[tuple[int, dict[str, Any] | Exception]]:
        """The schedule of :meth:`solve_batch` over the cells set up (``ready``)."""
        schedule = Schedule(sorted(ready), limits.repeats, warm_up=True,
                            unit=lambda index: (cells[index].problem_file,
                                                cells[index].solver_key))
        outputs: dict[int, list[SolverOutput]] = {index: [] for index in ready}
        for call in schedule:
            index = call.item
            cell = cells[index]
            spec, problem, warm_start, warm_source = ready[index]
            if not call.timed:
                self.warm_up(spec, problem, cell.accuracy, warm_start, cell.problem_file, index)
                continue
            done = outputs[index]
            # the runner's clock for --timeout starts
            self.say("begin", cell=index, repeat=len(done), memory_limit_mb=self.memory_limit_mb)
            output = call_solver(spec, problem, cell.accuracy, warm_start)
            self.say("end", cell=index, repeat=len(done))
            done.append(output)
            if (output.impulses is None  # a failed solve is not repeated
                    or len(done) >= limits.repeats
                    or sum(one.time_s for one in done) >= limits.repeat_budget_s):
                schedule.retire(call.index)
                try:
                    yield index, self.row(cell, spec, problem, outputs.pop(index), warm_start,
                                          warm_source)
                except Exception as error:  # judging failed (MemoryError included)
                    yield index, error

    def row(self, cell: Cell, spec: SolverSpec, problem: ImpactProblem | FrictionalProblem,
            outputs: list[SolverOutput], warm_start: np.ndarray | None, warm_source: str
            ) -> dict[str, Any]:
        """Make the row of a cell from its timed ``outputs``.

        The row is qpbench's judgement of the first answer and the times of all (``time_s`` their
        minimum, ``time_median_s`` their median, ``time_max_s`` their maximum; the formulation and
        backend times their minima), with the warm start, the repeats, the memory cap and the
        provenance. A MemoryError under the memory cap becomes ``out-of-memory``.

        Parameters
        ----------
        cell : Cell
            The cell.
        spec : SolverSpec
            The cell's solver.
        problem : ImpactProblem or FrictionalProblem
            The cell's problem.
        outputs : list of SolverOutput
            The outputs of the cell's timed solves (at least one).
        warm_start : numpy.ndarray or None
            The warm start handed to the solver; None for a cold start.
        warm_source : str
            Where the warm start came from (``previous``, ``none``, or ``cold``).

        Returns
        -------
        dict
            The cell's results row.
        """
        row = judge(spec, problem, outputs[0], cell.accuracy)
        if (self.memory_limit_mb > 0
                and str(row.get("solver_status", "")).startswith("error: MemoryError")):
            row["status"] = OUT_OF_MEMORY  # the allocation failed under the cap
        time_s, time_median_s = fastest([output.time_s for output in outputs])
        row.update({
            "mode": cell.mode,
            "warm_start_source": warm_source,
            "warm_start_used": bool(warm_start is not None and spec.warm_start),
            "repeats": len(outputs),
            "time_s": time_s,
            "time_median_s": time_median_s,
            "time_max_s": max(_finite([output.time_s for output in outputs]),
                              default=math.nan),
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

    def solve(self, cell: Cell, limits: Limits) -> dict[str, Any]:
        """Solve ``cell`` alone (a batch of one).

        Its repeats then follow one another, as nothing else is there to run between them.

        Parameters
        ----------
        cell : Cell
            The cell.
        limits : Limits
            The repeats and repeat budget of the cell.

        Returns
        -------
        dict
            The cell's results row.

        Raises
        ------
        Exception
            The exception of a cell that could not be set up or judged.
        """
        [(_, outcome)] = list(self.solve_batch([cell], limits))
        if isinstance(outcome, Exception):
            raise outcome
        return outcome


def serve(receive: Callable[[], dict[str, Any] | None],
          send: Callable[[dict[str, Any]], None]) -> None:
    """Answer the runner's requests until ``receive`` gives None.

    Each request ``{"cells": [...], "limits": ...}`` (or ``{"cell": ...}``, a batch of one) is
    answered with ``load`` and ``begin``/``end`` events and one ``row`` per cell (or
    ``{"event": "error"}`` for a cell that could not be set up), each naming the cell's index
    in the batch. Every backend is imported and prepared, and ``ready`` sent, before the first
    request; the memory cap is applied at the first request that sets one. A message that
    cannot be sent (the runner closed its end: it stopped or was interrupted) ends the process
    quietly (SystemExit 0), with no traceback in its log.

    Parameters
    ----------
    receive : callable
        Gives the next request, or None when the runner has no more.
    send : callable
        Sends one message to the runner.
    """

    def send_or_leave(message: dict[str, Any]) -> None:
        try:
            send(message)
        except (OSError, EOFError, ValueError):  # BrokenPipeError, a closed connection
            raise SystemExit(0) from None

    solver = CellSolver(announce=send_or_leave)
    prepare_solvers()  # every backend imported and prepared before the memory cap and timing
    solver.say("ready", pid=os.getpid())
    while (request := receive()) is not None:
        cells = [Cell(**cell) for cell in request.get("cells", [request.get("cell")])]
        limits = Limits(**request["limits"])
        if not solver.memory_limit_mb and limits.memory_limit_mb:
            solver.memory_limit_mb = limit_memory(limits.memory_limit_mb)
        answered: set[int] = set()
        try:
            for index, outcome in solver.solve_batch(cells, limits):
                answered.add(index)
                report(solver, index, outcome)
        except Exception as error:  # outside any one cell: every cell not answered yet
            for index in range(len(cells)):
                if index not in answered:
                    report(solver, index, error)


def report(solver: CellSolver, index: int, outcome: dict[str, Any] | Exception) -> None:
    """Send the outcome of the batch's ``index``-th cell to the runner.

    A row is sent as it is; an exception becomes the row of an allocation that failed under
    the memory cap (``out-of-memory``) or an ``error`` event.

    Parameters
    ----------
    solver : CellSolver
        The solver whose ``say`` sends the message.
    index : int
        The cell's index in the batch.
    outcome : dict or Exception
        The cell's row, or the exception of a cell that could not be set up or judged.
    """
    if isinstance(outcome, dict):
        solver.say("row", cell=index, row=outcome)
    elif isinstance(outcome, MemoryError) and solver.memory_limit_mb > 0:
        # outside the solver call: loading the problem or judging
        solver.say("row", cell=index, row={"status": OUT_OF_MEMORY,
                                           "solver_status": "MemoryError",
                                           "memory_limit_mb": solver.memory_limit_mb})
    elif isinstance(outcome, MemoryError):
        solver.say("error", cell=index, message="MemoryError (no memory cap set)")
    else:  # a problem file or solver that cannot be set up
        solver.say("error", cell=index, message=f"{type(outcome).__name__}: {outcome}")


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
    """Run a worker forked by the multiprocessing fork server.

    Messages go over ``connection``; stdout and stderr go to ``log_path``, whose name is
    removed once opened; the runner's current $QPBENCH_EXTRA_SOLVERS and module search path
    are taken over.

    Parameters
    ----------
    connection : multiprocessing.connection.Connection
        The worker's end of the pipe to the runner.
    log_path : str
        The log file the runner created; when it is gone the worker exits at once.
    extra_solvers : str, optional
        The runner's $QPBENCH_EXTRA_SOLVERS; ``""`` (unset) by default.
    search_path : list of str, optional
        The runner's module search path, appended to this process's; None adds nothing.
    """
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
