"""Process isolation: each cell solved in a worker process, whatever happens to it.

An :class:`IsolatedWorker` is a child process (see ``qpbench.bench.worker``) that lives
across batches of cells and is replaced when it dies (the rest of a batch then runs again in
the new process). How it died is the row's status
(:func:`classify_death`, :func:`failure_row`), named by what happened:

* ``timeout``: the runner killed it at the wall-clock limit (and the cells of the same
  problem, pair and mode at tighter levels are not started: :func:`tighter_levels`);
* ``out-of-memory``: only on evidence: an allocation failure (MemoryError, ``bad_alloc``)
  reported under the address-space cap, or the kernel's OOM killer having killed a process
  while the cell ran (its ``oom_kill`` count in /proc/vmstat rose) when the worker died of
  SIGKILL;
* ``killed``: a signal that comes from outside (SIGKILL, SIGTERM, SIGINT, SIGHUP, SIGQUIT:
  a user or another process) with no such evidence; a resume solves the cell again;
* ``crashed``: any other signal (SIGSEGV, SIGABRT, ...) or an exit code, named in the row.

Its log (the worker's stdout and stderr, read for the row of a death) is a temporary file
whose name is removed as soon as the worker has opened it (by the worker itself, or at the
latest once it is ready) and which is read through the descriptor kept open, so no log
outlives the run, however the run ends.

Workers are forked by a multiprocessing fork server, so, as with any multiprocessing
program, a Python script that starts one must do so under ``if __name__ == "__main__":``
(the ``qpbench`` command and pytest need nothing). A new worker after a crash is forked from
the server's preloaded process, not started afresh; what the harness adds per cell (messages,
judging) falls outside every solver's stopwatch.
"""

from __future__ import annotations

import contextlib
import datetime
import json
import math
import multiprocessing
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Generator, Iterator, Sequence
from dataclasses import asdict
from typing import Any

from qpbench import EXTRA_SOLVERS_ENV, SINGLE_THREAD_ENV
from qpbench.bench.settings import (
    CRASHED,
    ERROR,
    KILLED,
    OUT_OF_MEMORY,
    TIMEOUT,
    Cell,
    Limits,
)
from qpbench.errors import QpbenchError

STARTUP_TIMEOUT_S = 300.0
# allowance for the parts of a cell that are not the solver call (loading the problem, judging)
OUTSIDE_SOLVE_ALLOWANCE_S = 120.0


# signals that a user or another process sends; the runner's own kills are timeouts
OUTSIDE_SIGNALS = (signal.SIGKILL, signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT)
# what an allocation failure leaves on a worker's stderr (Python, C++, C libraries)
ALLOCATION_FAILURES = ("MemoryError", "bad_alloc", "Cannot allocate memory", "out of memory")


class WorkerDied(Exception):
    """The worker process ended (exit code or signal) while a cell was running."""

    def __init__(self, returncode: int | None) -> None:
        self.returncode = returncode
        super().__init__(f"worker exited with {returncode}")


class WorkerRetired(QpbenchError):
    """The worker was retired (the run is ending) and starts no new process."""


def oom_kill_count() -> int | None:
    """Count the processes the kernel's OOM killer has killed since boot.

    Read from ``oom_kill`` of /proc/vmstat, which counts system-wide and cgroup kills.

    Returns
    -------
    int or None
        The count; None where it is not reported.
    """
    try:
        with open("/proc/vmstat", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("oom_kill "):
                    return int(line.split()[1])
    except (OSError, ValueError):
        return None
    return None


_FORK_SERVER: Any = None
_FORK_SERVER_LOCK = threading.Lock()


def fork_server() -> Any:
    """Give the multiprocessing context that forks workers from a preloaded server.

    The server has imported qpbench's solver backends once (``qpbench.bench.preload``), so a
    new worker is ready in milliseconds. Its numerical libraries are limited to one thread
    (SINGLE_THREAD_ENV). The server is (re)started when it is not running.

    Returns
    -------
    multiprocessing.context.ForkServerContext
        The ``forkserver`` context, the same one on every call.
    """
    global _FORK_SERVER
    with _FORK_SERVER_LOCK:
        if _FORK_SERVER is None:
            context = multiprocessing.get_context("forkserver")
            context.set_forkserver_preload(["qpbench.bench.preload"])
            _FORK_SERVER = context
        _ensure_running()
        return _FORK_SERVER


def _ensure_running() -> None:
    """(Re)starts the fork server process, with SINGLE_THREAD_ENV in its environment only."""
    from multiprocessing import forkserver

    saved = {name: os.environ.get(name) for name in SINGLE_THREAD_ENV}
    os.environ.update(SINGLE_THREAD_ENV)
    try:
        forkserver.ensure_running()
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def start_fork_server() -> None:
    """Starts the fork server now, so its imports overlap with the caller's own set-up."""
    if can_have_children():
        fork_server()


def can_have_children() -> bool:
    """Tell whether this process may fork workers.

    Returns
    -------
    bool
        False in a daemonic multiprocessing process (e.g. a Dask worker), which may not fork.
    """
    return not multiprocessing.current_process().daemon


class IsolatedWorker:
    """A child process that solves cells; restarted after a crash or a timeout.

    Forked from the fork server where possible; otherwise (``program=True`` or inside a
    daemonic process) started as ``python -m qpbench.bench.worker``.
    """

    def __init__(self, program: bool | None = None) -> None:
        self.program = (not can_have_children()) if program is None else program
        self.process: Any = None  # subprocess.Popen or multiprocessing.Process
        self.connection: Any = None  # multiprocessing Connection (forked worker)
        self._buffer = b""
        self._log_descriptor: int | None = None  # the worker's log, open for reading
        self._log_path: str | None = None  # its name, until the worker has opened it
        self._memory_cap_mb = 0  # the address-space cap the worker reported applying
        self._retired = False
        # start and stop may be called from the thread that feeds the worker and from the
        # thread that ends the run; process, connection and log change under this lock
        self._life = threading.RLock()

    # --- process life --------------------------------------------------------------
    def start(self) -> None:
        """Starts the process and waits for it to say it is ready (WorkerRetired once
        :meth:`retire` was called: a run that is ending starts no worker)."""
        with self._life:
            if self._retired:
                raise WorkerRetired("the run is ending")
            self._log_descriptor, self._log_path = tempfile.mkstemp(prefix="qpbench-worker-",
                                                                    suffix=".log")
            self._memory_cap_mb = 0
            if self.program:
                search_path = os.pathsep.join(entry for entry in sys.path if entry)
                env = {**os.environ, **SINGLE_THREAD_ENV, "PYTHONUNBUFFERED": "1",
                       "PYTHONPATH": search_path}  # the modules this process can import
                self.process = subprocess.Popen(
                    [sys.executable, "-m", "qpbench.bench.worker"],
                    stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                    stderr=self._log_descriptor, env=env,
                    start_new_session=True,  # a Ctrl-C in the terminal reaches the runner only
                )
                self._buffer = b""
                self._forget_log_name()  # the process has it open already
            else:
                # imports every solver backend: not before the fork server has started (its
                # imports then overlap with this process's), see qpbench.cli.run
                from qpbench.bench.worker import child_main

                context = fork_server()
                ours, theirs = context.Pipe(duplex=True)
                # the fork server was started earlier: hand over what may have changed since
                extra_solvers = os.environ.get(EXTRA_SOLVERS_ENV, "")
                self.process = context.Process(
                    target=child_main,
                    args=(theirs, self._log_path, extra_solvers, list(sys.path)),
                    name="qpbench-worker", daemon=True)
                self.process.start()
                theirs.close()
                self.connection = ours
        try:
            message = self._next_message(time.monotonic() + STARTUP_TIMEOUT_S)
        except (WorkerDied, OSError, EOFError) as died:
            tail = self.stderr_tail()
            self.stop()
            if self._retired:
                raise WorkerRetired("the run is ending") from died
            raise QpbenchError(f"the worker process could not start ({died}): "
                               f"{tail or 'no message'}") from died
        if message is None or message.get("event") != "ready":
            self.stop()
            raise QpbenchError("the worker process did not start within "
                               f"{STARTUP_TIMEOUT_S:.0f} s")
        self._forget_log_name()  # the worker has opened its log: only descriptors remain

    def _forget_log_name(self) -> None:
        """Unlinks the log's name; the file lives on through the open descriptors."""
        with self._life:
            if self._log_path is not None:
                with contextlib.suppress(OSError):
                    os.unlink(self._log_path)
                self._log_path = None

    def alive(self) -> bool:
        """Tell whether the worker process is running.

        Returns
        -------
        bool
            True while a started process has not ended.
        """
        if self.process is None:
            return False
        if self.program:
            return self.process.poll() is None
        return self.process.is_alive()

    def returncode(self) -> int | None:
        """Wait for the process to end and give its exit code.

        A process still running 10 s after closing its end of the messages is killed first.

        Returns
        -------
        int or None
            The exit code (negative: the signal); None when no process was started.
        """
        with self._life:
            process = self.process
            if process is None:
                return None
            if self.program:
                try:
                    return process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    process.kill()
                    return process.wait()
            process.join(timeout=10)
            if process.exitcode is None:
                process.kill()
                process.join()
            return process.exitcode

    def stop(self) -> None:
        """Kills the process (if running) and forgets it and its log."""
        with self._life:
            if self.process is not None:
                if self.alive():
                    self.process.kill()
                if self.program:
                    self.process.wait()
                    for stream in (self.process.stdin, self.process.stdout):
                        if stream is not None:
                            stream.close()
                else:
                    self.process.join()
                    self.process.close()
                self.process = None
            if self.connection is not None:
                self.connection.close()
                self.connection = None
            self._forget_log_name()
            if self._log_descriptor is not None:
                os.close(self._log_descriptor)
                self._log_descriptor = None

    def retire(self) -> None:
        """Kills the process now and starts no other: the run is ending (an interrupt)."""
        with self._life:
            self._retired = True
            self.stop()

    def close(self) -> None:
        """Asks the process to finish (end of input), then makes sure it is gone."""
        with self._life:
            process = self.process
            try:
                if process is not None and self.program and process.stdin is not None:
                    process.stdin.close()
                elif self.connection is not None:
                    self.connection.close()
                    self.connection = None
            except OSError:
                pass
        if process is not None:
            try:  # outside the lock: another thread may retire the worker meanwhile
                if self.program:
                    process.wait(timeout=5)
                else:
                    process.join(timeout=5)
            except (OSError, ValueError, subprocess.TimeoutExpired):
                pass
        self.stop()

    def stderr_tail(self, lines: int = 3) -> str:
        """Read the last lines the process wrote to its log (solver messages, fatal errors).

        Parameters
        ----------
        lines : int, optional
            How many lines, from the last 4 KiB of the log; 3 by default.

        Returns
        -------
        str
            The lines, stripped and joined by `` | ``; ``""`` without a log.
        """
        with self._life:
            if self._log_descriptor is None:
                return ""
            try:
                size = os.fstat(self._log_descriptor).st_size
                data = os.pread(self._log_descriptor, 4096, max(0, size - 4096))
            except OSError:
                return ""
        text = data.decode("utf-8", "replace")
        return " | ".join(line.strip() for line in text.strip().splitlines()[-lines:])

    # --- messages --------------------------------------------------------------------
    def _send(self, message: dict[str, Any]) -> None:
        if self.program:
            assert self.process is not None and self.process.stdin is not None
            self.process.stdin.write((json.dumps(message) + "\n").encode())
            self.process.stdin.flush()
        else:
            self.connection.send(message)

    def _next_message(self, deadline: float) -> dict[str, Any] | None:
        """The next message from the process; None at the deadline; WorkerDied on exit (or
        once another thread has stopped the worker)."""
        if not self.program:
            connection = self.connection
            if connection is None:
                raise WorkerDied(None)
            try:
                if not connection.poll(max(0.0, deadline - time.monotonic())):
                    return None
                return connection.recv()
            except (EOFError, OSError) as error:
                raise WorkerDied(self.returncode()) from error
        process = self.process
        if process is None or process.stdout is None or process.stdout.closed:
            raise WorkerDied(None)
        descriptor = process.stdout.fileno()
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            try:
                ready, _, _ = select.select([descriptor], [], [], remaining)
                if not ready:
                    return None
                chunk = os.read(descriptor, 65536)
            except (OSError, ValueError) as error:  # closed by another thread's stop
                raise WorkerDied(None) from error
            if not chunk:
                raise WorkerDied(self.returncode())
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def solve(self, cell: Cell, limits: Limits) -> dict[str, Any]:
        """Solve ``cell`` alone (:meth:`solve_batch` of one cell).

        Parameters
        ----------
        cell : Cell
            The cell to solve.
        limits : Limits
            The wall-clock, memory and repeat limits of the solve.

        Returns
        -------
        dict
            The cell's results row.
        """
        [(_, row)] = list(self.solve_batch([cell], limits))
        return row

    def solve_batch(self, cells: Sequence[Cell], limits: Limits
                    ) -> Iterator[tuple[Cell, dict[str, Any]]]:
        """Solve a batch of cells, yielding each cell's row as it finishes.

        Each row comes from the worker, which runs the batch under the timing protocol
        (``qpbench.bench.worker``), or, for a cell whose worker died or hung, is a row saying how.

        The wall-clock limit applies to each solver call the worker announces (``begin`` ...
        ``end``: the warm-up and every timed repeat), OUTSIDE_SOLVE_ALLOWANCE_S to the rest.
        A death or a timeout is the row of the cell that was running (the one whose set-up,
        solver call or judging was under way); the rows received before are kept, and the
        batch's other unfinished cells run again, from their warm-up, in a new worker
        process. A solver call (warm-up or timed) that ran past the limit also ends the
        batch's cells of the same problem, pair and mode at tighter levels without starting
        them (:func:`tighter_levels`, :func:`not_started_row`). A caller that stops early
        (closing the iterator) kills the worker.

        Parameters
        ----------
        cells : sequence of Cell
            The batch's cells.
        limits : Limits
            The wall-clock, memory and repeat limits of each solve.

        Yields
        ------
        tuple of (Cell, dict)
            A cell and its results row.

        Raises
        ------
        QpbenchError
            When a worker process cannot start (WorkerRetired once the run is ending).
        """
        pending = list(cells)
        try:
            while pending:
                answered, overran = yield from self._one_process(pending, limits)
                pending = [cell for number, cell in enumerate(pending) if number not in answered]
                if overran is not None:
                    skipped = tighter_levels(overran, pending)
                    for cell in skipped:
                        yield cell, not_started_row(cell, overran, limits)
                    pending = [cell for cell in pending if cell not in skipped]
        except BaseException:  # an interrupt, or the caller closing this iterator early
            self.stop()
            raise

    def _one_process(self, cells: Sequence[Cell], limits: Limits
                     ) -> Generator[tuple[Cell, dict[str, Any]], None,
                                    tuple[set[int], Cell | None]]:
        """:meth:`solve_batch` in one worker process, until the batch is done or the process
        died or was killed at the limit; returns the indices of the cells answered and the
        cell whose solver call ran past the limit (None when none did)."""
        if not self.alive():
            self.stop()
            self.start()
        request = {"cells": [cell.as_dict() for cell in cells], "limits": asdict(limits)}
        answered: set[int] = set()
        running = 0  # the cell whose set-up, solver call or judging is under way
        call_started = time.monotonic()
        wall = dict.fromkeys(range(len(cells)), 0.0)
        oom_kills_before = oom_kill_count()
        cap = self._memory_cap_mb or limits.memory_limit_mb  # the worker reports what it applied

        def victim() -> int:
            """The cell a death or a timeout is charged to."""
            if running not in answered:
                return running
            return min(set(range(len(cells))) - answered)

        try:
            self._send(request)
            phase = ""  # the solver call under way, "" between calls
            while len(answered) < len(cells):
                allowance = limits.timeout_s if phase else OUTSIDE_SOLVE_ALLOWANCE_S
                message = self._next_message(time.monotonic() + allowance)
                if message is None:
                    self.stop()
                    charged = victim()
                    answered.add(charged)
                    yield cells[charged], failure_row(
                        cells[charged], TIMEOUT,
                        f"killed after {allowance:g} s in {phase or 'setup or judging'}",
                        time_s=limits.timeout_s if phase else math.nan, memory_limit_mb=cap)
                    return answered, (cells[charged] if phase else None)
                event = message.get("event")
                index = int(message.get("cell", 0))
                if event == "load":
                    running = index
                elif event == "begin":
                    running = index
                    phase = "warm-up solve" if message.get("warm_up") else "solver call"
                    call_started = time.monotonic()
                    self._memory_cap_mb = int(message.get("memory_limit_mb", cap) or 0)
                    cap = self._memory_cap_mb
                elif event == "end":
                    phase = ""
                    wall[index] += time.monotonic() - call_started
                elif event == "row":
                    row = message["row"]
                    row["cell_wall_s"] = wall[index]
                    answered.add(index)
                    yield cells[index], row
                elif event == "error":  # the cell could not be set up or judged
                    answered.add(index)
                    yield cells[index], failure_row(cells[index], ERROR,
                                                    str(message.get("message"))[:500],
                                                    memory_limit_mb=cap)
        except (WorkerDied, BrokenPipeError, ConnectionError) as error:
            code = error.returncode if isinstance(error, WorkerDied) else self.returncode()
            tail = self.stderr_tail()
            self.stop()
            oom_kills_after = oom_kill_count()
            oom_killer_ran = (oom_kills_before is not None and oom_kills_after is not None
                              and oom_kills_after > oom_kills_before)
            charged = victim()
            answered.add(charged)
            yield cells[charged], failure_row(
                cells[charged], *classify_death(code, tail, cap, oom_killer_ran),
                memory_limit_mb=cap)
        return answered, None


# --- a pair past the limit is not started again at a tighter level ------------------------
NOT_STARTED = "not started: "  # how the solver_status of such a row begins


def tighter_levels(overran: Cell, cells: Sequence[Cell]) -> list[Cell]:
    """Select the cells a solver call past the time limit ends without starting them.

    A solver that could not reach a level within the limit is not started at a tighter level
    of the same problem: those are the cells of ``cells`` of ``overran``'s problem file,
    solver, formulation and mode at a smaller accuracy.

    Parameters
    ----------
    overran : Cell
        The cell whose solver call (warm-up or timed) was killed at the limit.
    cells : sequence of Cell
        The cells not yet answered.

    Returns
    -------
    list of Cell
        Those cells, in the order of ``cells``.
    """
    return [cell for cell in cells
            if (cell.problem_file, cell.solver, cell.formulation, cell.mode)
            == (overran.problem_file, overran.solver, overran.formulation, overran.mode)
            and cell.accuracy < overran.accuracy]


def not_started_row(cell: Cell, overran: Cell, limits: Limits) -> dict[str, Any]:
    """Make the row of a cell ended by :func:`tighter_levels`: a ``timeout`` never started.

    Parameters
    ----------
    cell : Cell
        The cell not started.
    overran : Cell
        The cell of the same pair whose solver call ran past the limit at a looser level.
    limits : Limits
        The run's limits (the time limit is named in the row).

    Returns
    -------
    dict
        A :func:`failure_row` of status ``timeout``, ``time_s`` NaN (nothing was timed) and a
        ``solver_status`` beginning with NOT_STARTED that names the looser level.
    """
    return failure_row(cell, TIMEOUT, f"{NOT_STARTED}the pair ran past {limits.timeout_s:g} s "
                       f"at the looser level {overran.accuracy:.0e} of this problem",
                       memory_limit_mb=limits.memory_limit_mb)


def signal_name(number: int) -> str:
    """Name a signal number: ``SIGSEGV`` for 11.

    Parameters
    ----------
    number : int
        The signal number.

    Returns
    -------
    str
        The signal's name, or ``signal N`` for a number without a name.
    """
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def classify_death(returncode: int | None, stderr_tail: str, memory_cap_mb: int = 0,
                   oom_killer_ran: bool = False) -> tuple[str, str]:
    """Classify the death of a worker the runner did not kill while it solved a cell.

    * ``out-of-memory`` only on evidence: the log reports an allocation failure
      (ALLOCATION_FAILURES) and an address-space cap was set (``memory_cap_mb`` > 0), or the
      worker died of SIGKILL while the kernel's OOM killer ran (``oom_killer_ran``);
    * ``killed``: any other death by a signal of OUTSIDE_SIGNALS (a user, another process);
    * ``crashed``: any other signal or exit code.

    The message names the signal or the exit code, then the log's last lines.

    Parameters
    ----------
    returncode : int or None
        The worker's exit code (negative: the signal); None when unknown.
    stderr_tail : str
        The last lines of the worker's log (:meth:`IsolatedWorker.stderr_tail`).
    memory_cap_mb : int, optional
        The worker's address-space cap in MiB; 0 (none) by default.
    oom_killer_ran : bool, optional
        Whether the kernel's OOM kill count rose while the cell ran; False by default.

    Returns
    -------
    tuple of (str, str)
        (status, message), the message cut to 500 characters.
    """
    number = -returncode if returncode is not None and returncode < 0 else None
    cause = f"exit code {returncode}" if number is None else f"killed by {signal_name(number)}"
    allocation_failed = any(word in stderr_tail for word in ALLOCATION_FAILURES)
    if number == signal.SIGKILL and oom_killer_ran:
        status = OUT_OF_MEMORY
        cause += " while the kernel's OOM killer ran (oom_kill in /proc/vmstat rose)"
    elif allocation_failed and memory_cap_mb > 0:
        status = OUT_OF_MEMORY
        cause += f" after an allocation failed under the {memory_cap_mb} MiB cap"
    elif number in OUTSIDE_SIGNALS:
        status = KILLED
        cause += ", a signal qpbench did not send (a user or another process)"
    else:
        status = CRASHED
    message = f"worker died: {cause}" + (f" ({stderr_tail})" if stderr_tail else "")
    return status, message[:500]


def failure_row(cell: Cell, status: str, message: str, time_s: float = math.nan,
                memory_limit_mb: int = 0) -> dict[str, Any]:
    """Make the row of a cell whose worker died, hung or could not set it up: no answer.

    Parameters
    ----------
    cell : Cell
        The cell.
    status : str
        ``timeout``, ``out-of-memory``, ``killed``, ``crashed`` or ``error``.
    message : str
        What happened, stored as ``solver_status``.
    time_s : float, optional
        The time charged to the cell; NaN by default.
    memory_limit_mb : int, optional
        The worker's address-space cap in MiB; 0 (none) by default.

    Returns
    -------
    dict
        The row: unsuccessful, no residuals, no repeats, dated now (UTC).
    """
    nan = math.nan
    return {
        "solver": cell.solver,
        "formulation": cell.formulation,
        "accuracy": cell.accuracy,
        "mode": cell.mode,
        "status": status,
        "solver_status": message,
        "claimed_success": False,
        "status_honest": None,  # no claim to judge
        "success": False,
        "residual": nan, "v_error": nan, "energy_gain": nan, "complementarity": nan,
        "infeasibility": nan, "energy_identity_gap": nan,
        "iterations": None,
        "time_s": time_s,
        "time_median_s": time_s,
        "repeats": 0,
        "memory_limit_mb": memory_limit_mb,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }
