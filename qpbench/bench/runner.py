"""The runner: the whole matrix of cells driven through an executor (serial, local processes
or Dask; each cell solved in an isolated worker, ``qpbench.bench.isolation``), its rows
written to the resumable result store as they arrive, and the checks that a resumed table
belongs to the same problems and the same package lock.

An interrupt (Ctrl-C, SIGINT; or SIGTERM, which a run takes as one) stops the workers, writes
the rows received so far and compacts every part into the named table (atomically, with
further interrupts held off until it is written), then leaves as KeyboardInterrupt, which the
command line turns into exit status 130. A resume skips the cells stored; the cell that was
under way is solved again.
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from qpbench.bench.isolation import IsolatedWorker
from qpbench.bench.lock import lock_label
from qpbench.bench.provenance import provenance
from qpbench.bench.results import ResultStore
from qpbench.bench.settings import RETRIED_ON_RESUME, Cell, Limits, RunSettings, cells
from qpbench.errors import InputError, QpbenchError
from qpbench.interrupts import interrupts_held, terminate_as_interrupt
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem, kind_of
from qpbench.problem.impact import ImpactProblem


def complete_row(row: dict[str, Any], cell: Cell, summary: dict[str, Any], limits: Limits,
                 solver: dict[str, str] | None = None) -> dict[str, Any]:
    """Complete a solve's results row with its cell, problem, solver, limits and provenance.

    Adds the cell key, the problem's summary, the solver's backend and version (``solver``,
    for rows of dead workers), the limits, and (for rows of dead workers) this process's
    provenance to a row; the row's own columns win over the summary and provenance.

    Parameters
    ----------
    row : dict
        The columns the worker (or the harness, for a dead worker) wrote for the cell.
    cell : Cell
        The cell the row belongs to.
    summary : dict
        The problem's ``summary()`` with its ``problem_hash``.
    limits : Limits
        The limits the cell was solved under.
    solver : dict of str to str, optional
        ``backend`` and ``solver_version`` of the cell's solver; None adds nothing.

    Returns
    -------
    dict
        The complete row, as stored in the results table.
    """
    return {
        **provenance(),
        **summary,
        "problem_file": cell.problem_file,
        **(solver or {}),
        **row,
        "problem": cell.problem,
        "solver": cell.solver,
        "formulation": cell.formulation,
        "accuracy": float(cell.accuracy),
        "mode": cell.mode,
        "time_limit_s": limits.timeout_s,
        "repeats_requested": limits.repeats,
        "repeat_budget_s": limits.repeat_budget_s,
    }


# --- the problem set ---------------------------------------------------------------------
def fingerprint(problem: ImpactProblem | FrictionalProblem) -> str:
    """Hash the numbers that define a problem.

    A short SHA-256 of G, M^-1, v-, c, nrel (and T, mu, d_rel of a frictional one): results of
    a problem are only resumed for the same numbers.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to hash.

    Returns
    -------
    str
        The first 16 hex digits of the digest.
    """
    digest = hashlib.sha256()
    normal = problem.normal if isinstance(problem, FrictionalProblem) else problem
    G = normal.G.tocsc()
    arrays = [np.asarray(G.shape), G.data, G.indices, G.indptr, normal.m_inv,
              normal.v_minus, normal.restitution, normal.n_rel]
    if isinstance(problem, FrictionalProblem):
        T = problem.T.tocsc()
        arrays += [T.data, T.indices, T.indptr, problem.mu, problem.d_rel]
    for array in arrays:
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()[:16]



def problem_index(paths: Iterable[str | os.PathLike[str]]
                  ) -> list[tuple[str, str, str, str]]:
    """Index every problem file named or found under ``paths``.

    Each file is loaded to read its name, fingerprint and kind.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Problem files and directories holding them.

    Returns
    -------
    list of tuple of (str, str, str, str)
        (file, problem name, fingerprint, kind) of each problem, in the order found.

    Raises
    ------
    InputError
        On a problem name used twice (names identify rows).
    """
    index: list[tuple[str, str, str, str]] = []
    seen: dict[str, str] = {}
    for path in files.find(paths):
        problem = files.load(path)
        if problem.name in seen:
            raise InputError(str(path), f"problem name '{problem.name}' is also used by "
                             f"{seen[problem.name]}; names identify results, so they must be "
                             "unique", attribute="name")
        seen[problem.name] = str(path)
        index.append((str(path), problem.name, fingerprint(problem), kind_of(problem)))
    return index


def changed_problems(index: list[tuple[str, str, str, str]], stored: Any) -> set[str]:
    """Find the problems stored with other numbers than those of the index.

    A problem stored under another fingerprint was rebuilt by other code, or captured from a
    scene on another CPU, whose rounding moves a long simulation's trajectory in the last bits.

    Parameters
    ----------
    index : list of tuple of (str, str, str, str)
        (file, name, fingerprint, kind) of each problem, from :func:`problem_index`.
    stored : pandas.DataFrame
        The stored results' ``problem`` and ``problem_hash`` columns (possibly empty).

    Returns
    -------
    set of str
        The names of the problems of ``index`` stored with another fingerprint.
    """
    if stored.empty or "problem_hash" not in stored:
        return set()
    known: dict[str, set[str]] = {}
    for name, digest in zip(stored["problem"].astype(str), stored["problem_hash"],
                            strict=True):
        known.setdefault(name, set()).add(str(digest))
    return {name for _, name, digest, _ in index
            if name in known and known[name] != {digest}}


def check_same_lock(stored: Any, output: Path) -> None:
    """Refuse to resume a table made with another set of package versions.

    One table must compare like with like, so rows of another ``lock_hash`` stop the run.

    Parameters
    ----------
    stored : pandas.DataFrame
        The stored results' ``lock_hash`` column (possibly empty).
    output : pathlib.Path
        The results table, named in the error.

    Raises
    ------
    InputError
        When a stored row has a lock hash other than this environment's.
    """
    if stored.empty or "lock_hash" not in stored:
        return
    current = lock_label()
    previous = sorted({str(value) for value in stored["lock_hash"].dropna()} - {current})
    if previous:
        raise InputError(str(output), f"its rows were made with the packages of lock "
                         f"{previous[0]}, this environment is lock {current}; write the "
                         "results to a new file, or run `make clean-results` to start afresh",
                         attribute="lock_hash")


def summaries(problem_files: Iterable[str]) -> dict[str, dict[str, Any]]:
    """Load each problem file and summarise it.

    Parameters
    ----------
    problem_files : iterable of str
        The problem files.

    Returns
    -------
    dict of str to dict
        problem file -> ``problem.summary()`` (name, family, source, sizes, rank deficiency).
    """
    return {path: files.load(path).summary() for path in problem_files}


# --- the whole run -------------------------------------------------------------------------
def run(problem_paths: list[str], settings: RunSettings, output: str | os.PathLike[str],
        executor: Any, progress: bool = True, batch_rows: int = 20,
        batch_seconds: float = 10.0, retry: Iterable[str] = ()) -> dict[str, int]:
    """Run every pending cell of the matrix and store its row in ``output``.

    Runs every cell not yet in ``output`` (or stored with a status of RETRIED_ON_RESUME,
    ``killed``, or of ``retry``, e.g. ``timeout`` after raising the limit) and stores its row.
    Problems stored with another fingerprint are solved again; a table of another package lock
    is refused.

    Rows are written in batches (``batch_rows`` rows or ``batch_seconds``), each batch one
    atomically renamed part file; when the cells are done, and also when the run ends early
    (an interrupt, SIGTERM, an error), the workers are stopped, the rows received are written
    and the parts compacted into ``output``, with interrupts held off meanwhile; an interrupt
    then propagates as KeyboardInterrupt.

    Parameters
    ----------
    problem_paths : list of str
        Problem files and directories holding them.
    settings : RunSettings
        The solvers, accuracy levels, modes, kinds and limits of the matrix.
    output : str or os.PathLike
        The results table (Parquet), read to resume and written at the end.
    executor : Executor
        Where the cells run (:func:`qpbench.bench.executors.make_executor`).
    progress : bool, optional
        Show a progress bar on stderr; True by default.
    batch_rows : int, optional
        Rows per part file; 20 by default.
    batch_seconds : float, optional
        Seconds after which a part file is written however few its rows; 10 by default.
    retry : iterable of str, optional
        Stored statuses whose cells are solved again; none by default.

    Returns
    -------
    dict of str to int
        ``cells`` (the matrix), ``skipped`` (already stored), ``run``, and one count per status
        of the cells run.

    Raises
    ------
    QpbenchError
        When no problem file is found, a solver is unknown or unusable, the problems' names clash
        (InputError) or the stored table was made with another package lock (InputError).
    """
    # imports every solver backend: not at module level, so that qpbench.cli.run starts the
    # fork server first and its imports overlap with this process's
    from qpbench.solvers.registry import resolve

    store = ResultStore(Path(output))
    index = problem_index(problem_paths)
    if not index:
        raise QpbenchError("no problem files found in " + ", ".join(problem_paths))
    kinds = {path: kind for path, _, _, kind in index}
    specs = resolve(list(settings.solvers))
    takes = {spec.key: spec.kinds for spec in specs}
    matrix = [cell for cell in cells([(path, name) for path, name, _, _ in index],
                                     list(settings.solvers), settings)
              if kinds[cell.problem_file] in takes[cell.solver_key]
              and kinds[cell.problem_file] in settings.kinds]
    digests = {path: digest for path, _, digest, _ in index}
    solver_columns = {spec.key: {"backend": spec.backend, "solver_version": spec.version}
                      for spec in specs}
    with store.exclusive(), terminate_as_interrupt():
        check_same_lock(store.read(["lock_hash"]), store.path)
        changed = changed_problems(index, store.read(["problem", "problem_hash"]).dropna())
        if changed:
            print(f"qpbench run: {len(changed)} problems differ from those of the same names "
                  f"in {store.path} (rebuilt by other code, or captured on another CPU): "
                  f"solving them again, e.g. {sorted(changed)[0]}", file=sys.stderr)
        done = store.finished_keys({*RETRIED_ON_RESUME, *retry})
        pending = [cell for cell in matrix
                   if cell.key not in done or cell.problem in changed]
        problem_summaries = {path: {**summary, "problem_hash": digests[path]} for path, summary
                             in summaries(sorted({cell.problem_file for cell in pending})).items()}
        counts = {"cells": len(matrix), "skipped": len(matrix) - len(pending), "run": 0}
        bar = tqdm(total=len(matrix), initial=counts["skipped"], disable=not progress,
                   unit="solve", file=sys.stderr, dynamic_ncols=True)
        writer = store.writer(batch_rows=batch_rows, batch_seconds=batch_seconds)
        results = executor.map(pending, settings.limits)
        try:
            for cell, row in results:
                writer.add(complete_row(row, cell, problem_summaries[cell.problem_file],
                                        settings.limits, solver_columns.get(cell.solver_key)))
                counts["run"] += 1
                status = str(row.get("status", "?"))
                counts[status] = counts.get(status, 0) + 1
                bar.set_postfix_str(f"{cell.solver_key} {status}", refresh=False)
                bar.update(1)
        finally:  # also on Ctrl-C, SIGTERM or an error: every finished row is kept, readable
            with interrupts_held():
                if hasattr(results, "close"):
                    results.close()  # the executor stops its workers
                bar.close()
                writer.flush()
                store.compact()
    return counts


# problems per batch a worker runs under the timing protocol (docs/design.md section 7):
# enough that the repeats of a cell are separated by other problems' solves as well as other
# pairs', few enough that a worker holds few problems and a batch cut short by a timeout or
# a crash costs little to run again
BATCH_PROBLEMS = 3


def batches(cells_to_run: Iterable[Cell], problems: int = BATCH_PROBLEMS) -> list[list[Cell]]:
    """Split the cells into consecutive batches of at most ``problems`` problem files each.

    Cells come problem-major, so a batch holds every pending cell of its problems: all their
    pairs and levels.

    Parameters
    ----------
    cells_to_run : iterable of Cell
        The cells, problem-major.
    problems : int, optional
        Problem files per batch; BATCH_PROBLEMS by default.

    Returns
    -------
    list of list of Cell
        The batches, in the cells' order.
    """
    grouped: list[list[Cell]] = []
    files_in_batch: set[str] = set()
    for cell in cells_to_run:
        if not grouped or (cell.problem_file not in files_in_batch
                           and len(files_in_batch) >= problems):
            grouped.append([])
            files_in_batch = set()
        grouped[-1].append(cell)
        files_in_batch.add(cell.problem_file)
    return grouped


def solve_serially(cells_to_run: Iterable[Cell], limits: Limits,
                   worker: IsolatedWorker | None = None) -> Iterator[tuple[Cell, dict[str, Any]]]:
    """Solve the cells batch after batch on one isolated worker.

    The worker interleaves each batch's timed solves (docs/design.md section 7). A worker of
    its own is closed at the end and killed at once when the caller stops early (an
    interrupt); a worker handed in is killed only then.

    Parameters
    ----------
    cells_to_run : iterable of Cell
        The cells, problem-major.
    limits : Limits
        The wall-clock, memory and repeat limits of each solve.
    worker : IsolatedWorker, optional
        The worker to use; None starts one of its own.

    Yields
    ------
    tuple of (Cell, dict)
        Each cell and its results row as it finishes.
    """
    own = worker is None
    worker = worker or IsolatedWorker()
    try:
        for batch in batches(cells_to_run):
            yield from worker.solve_batch(batch, limits)
    except BaseException:  # an interrupt, or the caller closing this generator early
        worker.stop()
        raise
    if own:
        worker.close()
