"""The results: one Parquet long table, one row per solve, safe against kill -9.

Layout beside ``FILE.parquet``: a folder ``FILE.parquet.parts/`` of part files,
each one batch of rows written to a temporary name, flushed to disk and renamed
(a reader sees a whole part or none). :meth:`ResultStore.compact` merges the main
file and the parts into a new main file (again by rename) and only then deletes
the parts. Readers take the main file and then every part in the order written and
keep the last row of each cell key, so a kill between the rename and the deletions
duplicates nothing, and a cell solved again (``run --retry``) replaces its old row.
Rows are collected in lists and turned into one table per batch: no per-row concat.
"""

from __future__ import annotations

import contextlib
import os
import time
import uuid
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow.parquet as pq

from qpbench.atomic import TEMPORARY_PREFIX, atomic_path
from qpbench.bench.settings import CELL_KEY
from qpbench.errors import InputError, QpbenchError
from qpbench.problem.reduced import FRICTIONAL_KINDS

# column order of the table, with the dtype each column is stored as
FLOAT_COLUMNS = (
    "accuracy", "residual", "v_error", "energy_gain", "complementarity", "infeasibility",
    "energy_identity_gap", "time_s", "time_median_s", "time_max_s", "formulation_time_s",
    "compile_time_s", "backend_setup_time_s", "backend_solve_time_s",
    "timer_overhead_s", "time_limit_s", "cell_wall_s", "mu_max", "coulomb_residual",
    "model_error",
)
INT_COLUMNS = (
    "bodies", "contacts", "nnz", "rank_deficiency", "iterations", "repeats", "repeats_requested",
    "memory_limit_mb", "outer_iterations",
)
BOOL_COLUMNS = ("success", "claimed_success", "status_honest", "warm_start_used")
COLUMNS = (
    "problem", "family", "source", "problem_file", "problem_hash", "bodies", "contacts", "nnz",
    "rank_deficiency", "solver", "formulation", "backend", "solver_version", "accuracy", "mode",
    "status", "solver_status", "claimed_success", "status_honest", "success", "residual",
    "v_error", "energy_gain", "complementarity", "infeasibility", "energy_identity_gap",
    "kind", "model", "mu_max", "coulomb_residual", "model_error", "outer_iterations",
    "iterations", "time_s", "time_median_s", "time_max_s", "repeats", "repeats_requested",
    "formulation_time_s", "compile_time_s", "backend_setup_time_s", "backend_solve_time_s",
    "warm_start_source", "warm_start_used", "time_limit_s", "memory_limit_mb",
    "timer_overhead_s", "cell_wall_s", "qpbench_version", "lock_hash", "python_version",
    "numpy_version", "platform", "cpu_model", "hostname", "date",
)


def table(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Turn rows into one DataFrame with the columns of COLUMNS (then any others) and fixed dtypes.

    Columns of FLOAT_COLUMNS become float64, of INT_COLUMNS nullable Int64, of BOOL_COLUMNS
    nullable boolean, every other column string; values that do not convert become missing.

    Parameters
    ----------
    rows : list of dict
        The results rows; a column a row lacks is missing there.

    Returns
    -------
    pandas.DataFrame
        One row per element of ``rows``.
    """
    frame = pd.DataFrame.from_records(rows)
    extra = [column for column in frame.columns if column not in COLUMNS]
    frame = frame.reindex(columns=[*COLUMNS, *extra])
    for column in FLOAT_COLUMNS:
        frame[column] = pd.to_numeric(frame[column], errors="coerce").astype("float64")
    for column in INT_COLUMNS:
        frame[column] = pd.to_numeric(frame[column], errors="coerce").astype("Int64")
    for column in BOOL_COLUMNS:
        frame[column] = frame[column].astype("boolean")
    for column in frame.columns:
        if column not in FLOAT_COLUMNS + INT_COLUMNS + BOOL_COLUMNS:
            frame[column] = frame[column].astype("string")
    return frame


def frictional_rows(frame: pd.DataFrame) -> pd.Series:
    """Which results rows are of frictional problems, full or reduced to their contacts
    (``reduced.FRICTIONAL_KINDS``); rows without a kind are frictionless.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows, with or without a ``kind`` column.

    Returns
    -------
    pandas.Series
        A boolean per row, on ``frame``'s index.
    """
    if "kind" not in frame:
        return pd.Series(False, index=frame.index)
    return frame["kind"].astype("string").isin(FRICTIONAL_KINDS).fillna(False).astype(bool)


def split_kinds(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Split results rows by problem kind (:func:`frictional_rows`).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows, with or without a ``kind`` column.

    Returns
    -------
    tuple of (pandas.DataFrame, pandas.DataFrame)
        (frictionless rows, frictional rows).
    """
    frictional = frictional_rows(frame)
    return frame[~frictional], frame[frictional]


def _check_dtypes(frame: pd.DataFrame, path: Path) -> None:
    """InputError naming the column when a column of numbers or of flags holds anything else
    (a column that is only missing values passes)."""
    expected = {**{column: "numbers" for column in FLOAT_COLUMNS + INT_COLUMNS},
                **{column: "true/false flags" for column in BOOL_COLUMNS}}
    for column, what in expected.items():
        if column not in frame.columns or frame[column].isna().all():
            continue
        kinds = "fiu" if what == "numbers" else "b"
        if frame[column].dtype.kind not in kinds:
            raise InputError(str(path), f"column '{column}' must hold {what}, not "
                             f"{frame[column].dtype}")


def _write_atomically(frame: pd.DataFrame, path: Path) -> None:
    """Writes ``frame`` to ``path`` through a synced temporary file and a rename."""
    with atomic_path(path, durable=True) as temporary:
        frame.to_parquet(temporary, engine="pyarrow", index=False)


class ResultStore:
    """The results of one run: ``path`` (compacted) plus ``path.parts/`` (batches since)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if self.path.is_dir():
            raise InputError(str(self.path), "is a folder; name a results file (.parquet)")
        self.parts = self.path.with_name(self.path.name + ".parts")

    @contextlib.contextmanager
    def exclusive(self) -> Iterator[None]:
        """Hold ``FILE.parquet.lock`` (flock) for one writing run.

        A second run on the same file is refused. The kernel releases the lock when the process
        dies, even by kill -9.

        Yields
        ------
        None
            Control to the block, with the lock held.

        Raises
        ------
        QpbenchError
            When another run holds the lock.
        """
        import fcntl

        self.path.parent.mkdir(parents=True, exist_ok=True)
        lock = self.path.with_name(self.path.name + ".lock")
        with open(lock, "a") as handle:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as error:
                raise QpbenchError(f"{self.path}: another qpbench run is writing these results "
                                   f"(lock {lock.name})") from error
            try:
                yield
            finally:
                fcntl.flock(handle.fileno(), fcntl.LOCK_UN)

    def part_files(self) -> list[Path]:
        """List the part files written since the last compaction.

        Returns
        -------
        list of pathlib.Path
            The parts in the order written (their names start with a nanosecond time).
        """
        if not self.parts.is_dir():
            return []
        return sorted(self.parts.glob("part-*.parquet"))

    def _read_file(self, path: Path, columns: Iterable[str] | None) -> pd.DataFrame:
        """One file's rows (``columns`` only, those it lacks as missing values; all of them
        when ``columns`` is None, and then every column of COLUMNS must be there)."""
        try:
            if columns is None:
                frame = pd.read_parquet(path, engine="pyarrow")
                missing = [column for column in COLUMNS if column not in frame.columns]
                if missing:
                    raise InputError(str(path), "not a results table of this qpbench: no "
                                     f"column {', '.join(missing[:5])}"
                                     f"{' ...' if len(missing) > 5 else ''}")
            else:
                wanted = list(columns)
                present = set(pq.read_schema(path).names)
                frame = pd.read_parquet(path, engine="pyarrow", columns=[
                    column for column in wanted if column in present]).reindex(columns=wanted)
        except (OSError, ValueError) as error:
            raise InputError(str(path), f"not a readable results file ({error})") from error
        _check_dtypes(frame, path)
        return frame

    def read(self, columns: Iterable[str] | None = None) -> pd.DataFrame:
        """Read every stored row, the last row of each cell key kept.

        The main file is read first, then the parts in the order written.

        Parameters
        ----------
        columns : iterable of str, optional
            The columns to read, those a file lacks as missing values; None reads all of them and
            requires every column of COLUMNS.

        Returns
        -------
        pandas.DataFrame
            The rows (``columns`` only when given); an empty table when nothing is stored.

        Raises
        ------
        InputError
            When a file is not a readable results table, or a column holds values of the wrong type.
        """
        sources = ([self.path] if self.path.exists() else []) + self.part_files()
        if not sources:
            return table([])
        wanted = None if columns is None else list(dict.fromkeys([*CELL_KEY, *columns]))
        frames = [self._read_file(path, wanted) for path in sources]
        frames = [frame for frame in frames if len(frame)]
        if not frames:
            return table([])
        frame = frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)
        keys = [column for column in CELL_KEY if column in frame.columns]
        frame = frame.drop_duplicates(subset=keys, keep="last").reset_index(drop=True)
        return frame if columns is None else frame[list(columns)]

    def finished_keys(self, retry: Iterable[str] = ()) -> set[tuple[str, str, str, float, str]]:
        """Collect the cell keys already stored, less those whose stored status is in ``retry``.

        Parameters
        ----------
        retry : iterable of str, optional
            Statuses whose cells count as not finished; none by default.

        Returns
        -------
        set of tuple of (str, str, str, float, str)
            (problem, solver, formulation, accuracy, mode) of each finished cell.
        """
        frame = self.read([*CELL_KEY, "status"])
        frame = frame[~frame["status"].astype(str).isin(list(retry))]
        return {
            (str(p), str(s), str(f), float(a), str(m))
            for p, s, f, a, m in frame[list(CELL_KEY)].itertuples(index=False, name=None)
        }

    def writer(self, batch_rows: int = 20, batch_seconds: float = 10.0) -> BatchWriter:
        """Make a writer that stores rows in this store's part files.

        Parameters
        ----------
        batch_rows : int, optional
            Rows per part file; 20 by default.
        batch_seconds : float, optional
            Seconds after which the rows collected are written however few; 10 by default.

        Returns
        -------
        BatchWriter
            A writer with no rows yet.
        """
        return BatchWriter(self, batch_rows, batch_seconds)

    def write_part(self, rows: list[dict[str, Any]]) -> Path:
        """Store ``rows`` as one new part file (atomically).

        Parameters
        ----------
        rows : list of dict
            The results rows (:func:`table`).

        Returns
        -------
        pathlib.Path
            The part file written.
        """
        self.parts.mkdir(parents=True, exist_ok=True)
        name = f"part-{time.time_ns():020d}-{os.getpid()}-{uuid.uuid4().hex[:8]}.parquet"
        path = self.parts / name
        _write_atomically(table(rows), path)
        return path

    def compact(self) -> int:
        """Merge the main file and the parts into the main file, then remove the parts.

        Temporary files that a kill left behind are removed too; the parts folder is removed when
        empty.

        Returns
        -------
        int
            The number of rows in the main file.
        """
        parts = self.part_files()
        if not parts and self.path.exists():
            return len(self._read_file(self.path, CELL_KEY))
        frame = self.read()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        _write_atomically(table(frame.to_dict("records")) if len(frame) else table([]),
                          self.path)
        for part in parts:
            part.unlink(missing_ok=True)
        for leftover in self.path.parent.glob(f"{TEMPORARY_PREFIX}*-{self.path.name}"):
            leftover.unlink(missing_ok=True)  # a write that a kill interrupted
        if self.parts.is_dir():
            for leftover in self.parts.glob(f"{TEMPORARY_PREFIX}*"):
                leftover.unlink(missing_ok=True)
            with contextlib.suppress(OSError):  # not empty: another writer's part arrived
                self.parts.rmdir()
        return len(frame)


class BatchWriter:
    """Collects rows and writes them as a part file every ``batch_rows`` rows or
    ``batch_seconds`` seconds (whichever comes first) and on :meth:`flush`."""

    def __init__(self, store: ResultStore, batch_rows: int, batch_seconds: float) -> None:
        self.store = store
        self.batch_rows = max(1, batch_rows)
        self.batch_seconds = batch_seconds
        self.rows: list[dict[str, Any]] = []
        self.last_flush = time.monotonic()

    def add(self, row: dict[str, Any]) -> None:
        """Collect one row, writing a part file when the batch is full or old enough.

        Parameters
        ----------
        row : dict
            One results row.
        """
        self.rows.append(row)
        if (len(self.rows) >= self.batch_rows
                or time.monotonic() - self.last_flush >= self.batch_seconds):
            self.flush()

    def flush(self) -> None:
        """Write the rows collected so far as one part file (nothing when there are none)."""
        if self.rows:
            self.store.write_part(self.rows)
            self.rows = []
        self.last_flush = time.monotonic()
