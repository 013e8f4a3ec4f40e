"""Where the cells run: in order on one worker, on N local workers, or on a Dask cluster.

Every executor hands batches of cells (``qpbench.bench.runner.batches``: a few problems,
every pair and level of them) to an :class:`~qpbench.bench.isolation.IsolatedWorker`
(a child process), which interleaves each batch's timed solves (docs/design.md section 7),
so all three give the same rows; they differ only in how many batches run at once and on
which machine. ``map(cells, limits)`` yields ``(cell, row)`` as cells finish, in any order; when
the caller stops early (an interrupt, or closing the iterator) the local workers are killed
at once, and no new one is started.
"""

from __future__ import annotations

import atexit
import contextlib
import queue
import threading
from collections.abc import Iterator
from typing import Any, Protocol

from qpbench.bench.isolation import IsolatedWorker
from qpbench.bench.runner import batches, solve_serially
from qpbench.bench.settings import Cell, Limits
from qpbench.errors import QpbenchError

Result = tuple[Cell, dict[str, Any]]


class Executor(Protocol):
    name: str

    def map(self, cells: list[Cell], limits: Limits) -> Iterator[Result]:
        """Solve ``cells`` under ``limits`` and yield each cell's row as it finishes.

        Parameters
        ----------
        cells : list of Cell
            The cells to solve.
        limits : Limits
            The wall-clock, memory and repeat limits of each solve.

        Yields
        ------
        tuple of (Cell, dict)
            A cell and its results row, in any order.
        """


class SerialExecutor:
    """One worker process, batches in matrix order."""

    name = "serial"

    def map(self, cells: list[Cell], limits: Limits) -> Iterator[Result]:
        """Solve ``cells`` batch after batch on one isolated worker.

        See :func:`qpbench.bench.runner.solve_serially`.

        Parameters
        ----------
        cells : list of Cell
            The cells to solve, problem-major.
        limits : Limits
            The wall-clock, memory and repeat limits of each solve.

        Yields
        ------
        tuple of (Cell, dict)
            A cell and its results row, in matrix order.
        """
        yield from solve_serially(cells, limits)


class ProcessExecutor:
    """``workers`` worker processes on this machine, fed by as many threads (daemon threads,
    so that an interrupted run never waits for a solve to finish)."""

    # how long the end of a run waits for each feeding thread once its worker is killed
    THREAD_JOIN_S = 2.0

    name = "processes"

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise QpbenchError(f"--workers must be at least 1, got {workers}")
        self.workers = workers

    def map(self, cells: list[Cell], limits: Limits) -> Iterator[Result]:
        """Solve ``cells`` on ``workers`` isolated workers, one batch per worker at a time.

        Each feeding thread takes the next batch from a shared queue and passes its rows on; the
        first error a thread meets is raised here. When the caller stops early every worker is
        retired (killed and never restarted) and each thread joined for at most ``THREAD_JOIN_S``.

        Parameters
        ----------
        cells : list of Cell
            The cells to solve, problem-major.
        limits : Limits
            The wall-clock, memory and repeat limits of each solve.

        Yields
        ------
        tuple of (Cell, dict)
            A cell and its results row, as cells finish.
        """
        chunks: queue.Queue[list[Cell] | None] = queue.Queue()
        for chunk in batches(cells):
            chunks.put(chunk)
        results: queue.Queue[Result | BaseException | None] = queue.Queue()
        stop = threading.Event()
        workers = [IsolatedWorker() for _ in range(self.workers)]

        def serve(worker: IsolatedWorker) -> None:
            try:
                while not stop.is_set():
                    try:
                        chunk = chunks.get_nowait()
                    except queue.Empty:
                        break
                    for result in worker.solve_batch(chunk, limits):
                        if stop.is_set():
                            break  # closing the batch kills the worker
                        results.put(result)
            except BaseException as error:  # reported to the caller, which stops the run
                results.put(error)
            finally:
                worker.close()
                results.put(None)

        threads = [threading.Thread(target=serve, args=(worker,), daemon=True)
                   for worker in workers]
        for thread in threads:
            thread.start()
        finished = 0
        try:
            while finished < len(threads):
                item = results.get()
                if item is None:
                    finished += 1
                elif isinstance(item, BaseException):
                    raise item
                else:
                    yield item
        finally:
            stop.set()
            for worker in workers:
                worker.retire()  # killed now, and never restarted by its thread
            for thread in threads:
                thread.join(timeout=self.THREAD_JOIN_S)


# --- Dask ----------------------------------------------------------------------------------
_DASK_WORKERS: dict[int, IsolatedWorker] = {}
_DASK_LOCK = threading.Lock()


def _close_dask_workers() -> None:
    with _DASK_LOCK:
        for worker in _DASK_WORKERS.values():
            worker.close()
        _DASK_WORKERS.clear()


atexit.register(_close_dask_workers)


def solve_chunk(chunk: list[Cell], limits: Limits) -> list[Result]:
    """Solve one batch of cells as a Dask task.

    The batch runs on this thread's isolated worker, kept for the next task, so the worker
    process starts once per Dask worker thread.

    Parameters
    ----------
    chunk : list of Cell
        One batch of cells (:func:`qpbench.bench.runner.batches`).
    limits : Limits
        The wall-clock, memory and repeat limits of each solve.

    Returns
    -------
    list of tuple of (Cell, dict)
        Each cell of the batch with its results row.
    """
    key = threading.get_ident()
    with _DASK_LOCK:
        worker = _DASK_WORKERS.setdefault(key, IsolatedWorker())
    return list(solve_serially(chunk, limits, worker=worker))


class DaskExecutor:
    """One Dask task per batch of cells, on the scheduler at ``address``."""

    name = "dask"

    def __init__(self, address: str) -> None:
        self.address = address

    def client(self) -> Any:
        """Connect to the Dask scheduler at ``address`` (20 s timeout).

        Returns
        -------
        distributed.Client
            A client of the scheduler.

        Raises
        ------
        QpbenchError
            When dask.distributed is not installed or the scheduler cannot be reached.
        """
        try:
            from distributed import Client
        except ImportError as error:
            raise QpbenchError(f"--executor {self.address}: dask.distributed is not installed"
                               ) from error
        try:
            return Client(self.address, timeout="20s")
        except (OSError, TimeoutError, ValueError) as error:
            raise QpbenchError(f"--executor: cannot reach the Dask scheduler at {self.address}: "
                               f"{error}") from error

    def map(self, cells: list[Cell], limits: Limits) -> Iterator[Result]:
        """Submit one Dask task per batch of cells and yield the rows as tasks complete.

        The solving processes on every Dask worker are closed when the run ends, also when the
        caller stops early.

        Parameters
        ----------
        cells : list of Cell
            The cells to solve, problem-major.
        limits : Limits
            The wall-clock, memory and repeat limits of each solve.

        Yields
        ------
        tuple of (Cell, dict)
            A cell and its results row, a whole batch at a time, in order of completion.
        """
        from distributed import as_completed

        client = self.client()
        try:
            futures = [client.submit(solve_chunk, chunk, limits, pure=False)
                       for chunk in batches(cells)]
            for future in as_completed(futures):
                yield from future.result()
        finally:
            with contextlib.suppress(Exception):  # a lost worker has nothing left to close
                client.run(_close_dask_workers)  # end the solving processes on every worker
            client.close()


def make_executor(executor: str, workers: int = 1) -> Executor:
    """Make the executor a ``--executor`` value names.

    Parameters
    ----------
    executor : str
        ``serial``, ``processes``, ``dask://HOST:PORT`` (or a ``tcp://``, ``tls://`` or
        ``inproc://`` scheduler address); ``""`` or ``auto`` is ``processes`` when ``workers``
        exceeds 1, else ``serial``.
    workers : int, optional
        The number of local worker processes of ``processes``; 1 by default.

    Returns
    -------
    Executor
        A :class:`SerialExecutor`, :class:`ProcessExecutor` or :class:`DaskExecutor`.

    Raises
    ------
    QpbenchError
        On an unknown executor, ``serial`` with more than one worker, or fewer than one worker.
    """
    if executor in ("", "auto"):
        executor = "processes" if workers > 1 else "serial"
    if executor == "serial":
        if workers > 1:
            raise QpbenchError("--executor serial runs one worker; drop --workers or use "
                               "--executor processes")
        return SerialExecutor()
    if executor == "processes":
        return ProcessExecutor(workers)
    if executor.startswith("dask://"):
        return DaskExecutor("tcp://" + executor.removeprefix("dask://"))
    if executor.startswith(("tcp://", "tls://", "inproc://")):
        return DaskExecutor(executor)
    raise QpbenchError(f"--executor: unknown executor '{executor}' "
                       "(serial, processes or dask://HOST:PORT)")
