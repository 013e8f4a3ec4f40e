"""Process isolation: each cell solved in a worker process, whatever happens to it.

An :class:`IsolatedWorker` is a child process (see ``qpbench.bench.worker``) that lives
across cells and is replaced when it dies. A solver that segfaults or aborts kills only that
process (status ``crashed``); one that runs past the wall-clock limit is killed
(``timeout``); one that exceeds the address-space cap gets MemoryError, or is killed by
SIGKILL from the kernel (``out-of-memory``). Each becomes a row (:func:`failure_row`).

Workers are forked by a multiprocessing fork server, so, as with any multiprocessing
program, a Python script that starts one must do so under ``if __name__ == "__main__":``
(the ``qpbench`` command and pytest need nothing). Measured on the development machine: a
new worker after a crash is ready in about 0.15 s; the harness adds about 4 ms per cell
(messages, judging) to the solver's time.
"""

from __future__ import annotations

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
from dataclasses import asdict
from typing import Any

from qpbench import EXTRA_SOLVERS_ENV, SINGLE_THREAD_ENV
from qpbench.bench.settings import CRASHED, ERROR, OUT_OF_MEMORY, TIMEOUT, Cell, Limits
from qpbench.errors import QpbenchError

STARTUP_TIMEOUT_S = 300.0
# allowance for the parts of a cell that are not the solver call (loading the problem, judging)
OUTSIDE_SOLVE_ALLOWANCE_S = 120.0


class WorkerDied(Exception):
    """The worker process ended (exit code or signal) while a cell was running."""

    def __init__(self, returncode: int | None) -> None:
        self.returncode = returncode
        super().__init__(f"worker exited with {returncode}")


_FORK_SERVER: Any = None
_FORK_SERVER_LOCK = threading.Lock()


def fork_server() -> Any:
    """The multiprocessing context that forks workers from a server which has imported
    qpbench's solver backends once, so a new worker is ready in milliseconds. Its numerical
    libraries are limited to one thread (SINGLE_THREAD_ENV)."""
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
    """False in a daemonic multiprocessing process (e.g. a Dask worker), which may not fork."""
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
        self._log: Any = None

    # --- process life --------------------------------------------------------------
    def start(self) -> None:
        self._log = tempfile.NamedTemporaryFile(prefix="qpbench-worker-", suffix=".log")  # noqa: SIM115 (lives as long as the worker)
        if self.program:
            search_path = os.pathsep.join(entry for entry in sys.path if entry)
            env = {**os.environ, **SINGLE_THREAD_ENV, "PYTHONUNBUFFERED": "1",
                   "PYTHONPATH": search_path}  # the modules this process can import
            self.process = subprocess.Popen(
                [sys.executable, "-m", "qpbench.bench.worker"],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._log, env=env,
                start_new_session=True,  # a Ctrl-C in the terminal reaches the runner only
            )
            self._buffer = b""
        else:
            from qpbench.bench.worker import child_main

            context = fork_server()
            ours, theirs = context.Pipe(duplex=True)
            # the fork server was started earlier: hand over what may have changed since
            extra_solvers = os.environ.get(EXTRA_SOLVERS_ENV, "")
            self.process = context.Process(
                target=child_main, args=(theirs, self._log.name, extra_solvers, list(sys.path)),
                name="qpbench-worker", daemon=True)
            self.process.start()
            theirs.close()
            self.connection = ours
        try:
            message = self._next_message(time.monotonic() + STARTUP_TIMEOUT_S)
        except WorkerDied as died:
            tail = self.stderr_tail()
            self.stop()
            raise QpbenchError(f"the worker process could not start ({died}): "
                               f"{tail or 'no message'}") from died
        if message is None or message.get("event") != "ready":
            self.stop()
            raise QpbenchError("the worker process did not start within "
                               f"{STARTUP_TIMEOUT_S:.0f} s")

    def alive(self) -> bool:
        if self.process is None:
            return False
        if self.program:
            return self.process.poll() is None
        return self.process.is_alive()

    def returncode(self) -> int | None:
        """The exit code (negative: the signal) once the process has ended."""
        if self.process is None:
            return None
        if self.program:
            return self.process.wait()
        self.process.join()
        return self.process.exitcode

    def stop(self) -> None:
        """Kills the process (if running) and forgets it."""
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
        if self._log is not None:
            self._log.close()
            self._log = None

    def close(self) -> None:
        """Asks the process to finish (end of input), then makes sure it is gone."""
        if self.process is not None:
            try:
                if self.program and self.process.stdin is not None:
                    self.process.stdin.close()
                    self.process.wait(timeout=5)
                elif self.connection is not None:
                    self.connection.close()
                    self.connection = None
                    self.process.join(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                pass
        self.stop()

    def stderr_tail(self, lines: int = 3) -> str:
        """The last lines the process wrote to its log (solver messages, fatal errors)."""
        if self._log is None:
            return ""
        try:
            with open(self._log.name, "rb") as stream:
                stream.seek(0, os.SEEK_END)
                stream.seek(max(0, stream.tell() - 4096))
                text = stream.read().decode("utf-8", "replace")
        except OSError:
            return ""
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
        """The next message from the process; None at the deadline; WorkerDied on exit."""
        if not self.program:
            if not self.connection.poll(max(0.0, deadline - time.monotonic())):
                return None
            try:
                return self.connection.recv()
            except (EOFError, OSError) as error:
                raise WorkerDied(self.returncode()) from error
        assert self.process is not None and self.process.stdout is not None
        descriptor = self.process.stdout.fileno()
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            ready, _, _ = select.select([descriptor], [], [], remaining)
            if not ready:
                return None
            chunk = os.read(descriptor, 65536)
            if not chunk:
                raise WorkerDied(self.returncode())
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def solve(self, cell: Cell, limits: Limits) -> dict[str, Any]:
        """The row of ``cell``, from the worker or, when it failed, a row saying how."""
        if not self.alive():
            self.stop()
            self.start()
        request = {"cell": cell.as_dict(), "limits": asdict(limits)}
        started = time.monotonic()
        try:
            self._send(request)
            in_solve = False
            while True:
                allowance = limits.timeout_s if in_solve else OUTSIDE_SOLVE_ALLOWANCE_S
                message = self._next_message(time.monotonic() + allowance)
                if message is None:
                    self.stop()
                    phase = "solver call" if in_solve else "setup or judging"
                    return failure_row(cell, TIMEOUT, f"killed after {allowance:g} s in {phase}",
                                       time_s=limits.timeout_s if in_solve else math.nan)
                event = message.get("event")
                if event == "begin":
                    in_solve = True
                elif event == "end":
                    in_solve = False
                elif event == "row":
                    row = message["row"]
                    row["cell_wall_s"] = time.monotonic() - started
                    return row
                elif event == "error":  # the cell could not be set up or judged
                    return failure_row(cell, ERROR, str(message.get("message"))[:500])
        except (WorkerDied, BrokenPipeError, ConnectionError) as error:
            code = error.returncode if isinstance(error, WorkerDied) else self.returncode()
            tail = self.stderr_tail()
            self.stop()
            return failure_row(cell, *classify_death(code, tail))


def classify_death(returncode: int | None, stderr_tail: str) -> tuple[str, str]:
    """(status, message) for a worker that died: SIGKILL that the runner did not send, or a
    fatal allocation failure on stderr, is ``out-of-memory``; anything else ``crashed``."""
    if returncode is not None and returncode < 0:
        try:
            cause = signal.Signals(-returncode).name
        except ValueError:
            cause = f"signal {-returncode}"
    else:
        cause = f"exit code {returncode}"
    memory_words = ("MemoryError", "bad_alloc", "Cannot allocate memory", "out of memory")
    out_of_memory = returncode == -signal.SIGKILL or any(w in stderr_tail for w in memory_words)
    message = f"worker died: {cause}" + (f" ({stderr_tail})" if stderr_tail else "")
    return (OUT_OF_MEMORY if out_of_memory else CRASHED), message[:500]


def failure_row(cell: Cell, status: str, message: str, time_s: float = math.nan
                ) -> dict[str, Any]:
    """The row of a cell whose worker crashed, hung or ran out of memory: no answer."""
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
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }
