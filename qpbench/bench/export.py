"""Our problem sets in forms other QP benchmarks read.

* ``parquet``: qpbenchmark's problem list, one row per problem with columns
  ``P, q, G, h, A, b, lb, ub, name``; matrices dense and flattened row by row, absent
  entries null (as qpbenchmark's ParquetTestSet reads them). Note that qpbenchmark's
  ``b`` is the right-hand side of equality constraints, not our ``b``.
* ``mat``: one MATLAB file per problem (scipy.io.savemat) with sparse ``P``, ``q``,
  ``lb`` (dual) or ``P, q, G, h`` (primal), plus ``name``.

Formulations (docs/design.md section 1), both as ``min 1/2 x^T P x + q^T x``:

* ``dual``: ``P = Q``, ``q = b``, ``lb = 0`` (x = l, the impulses);
* ``primal``: ``P = diag(M_free)``, ``q = -M_free v-_free``, ``G x <= h`` with
  ``G = -G_free^T``, ``h = -lower`` (x = v+ on the degrees of freedom with finite mass).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.io
import scipy.sparse as sp

from qpbench.atomic import atomic_path
from qpbench.errors import QpbenchError, UnsupportedError
from qpbench.problem import files
from qpbench.problem.formulations import primal_qp
from qpbench.problem.impact import ImpactProblem

FORMATS = ("parquet", "mat")
FORMULATIONS = ("dual", "primal")
QPBENCHMARK_KEYS = ("P", "q", "G", "h", "A", "b", "lb", "ub", "name")
MAX_DENSE_ENTRIES = 50_000_000  # 400 MB of float64 per dense matrix in the Parquet list


def qp_matrices(problem: ImpactProblem, formulation: str) -> dict[str, Any]:
    """The QP of ``problem`` as qpbenchmark names it: P, q and G, h or lb (sparse P, G)."""
    if formulation == "dual":
        return {"P": sp.csc_matrix(problem.Q), "q": np.asarray(problem.b, dtype=float),
                "lb": np.zeros(problem.n_contacts)}
    if formulation == "primal":
        qp = primal_qp(problem)
        return {"P": sp.csc_matrix(qp.P), "q": np.asarray(qp.q, dtype=float),
                "G": sp.csc_matrix(-qp.A), "h": -np.asarray(qp.lower, dtype=float)}
    raise QpbenchError(f"--formulation: unknown '{formulation}' (known: {', '.join(FORMULATIONS)})")


def _dense_flat(matrix: sp.spmatrix, problem: ImpactProblem) -> np.ndarray:
    if matrix.shape[0] * matrix.shape[1] > MAX_DENSE_ENTRIES:
        raise UnsupportedError(f"{problem.source or problem.name}: a {matrix.shape} matrix is too "
                               "large for qpbenchmark's dense Parquet list; use --format mat")
    return np.asarray(matrix.toarray(), dtype=float).ravel()


def export_parquet(problems: Iterable[ImpactProblem], path: Path, formulation: str) -> int:
    """Writes qpbenchmark's problem list to ``path``; returns the number of problems."""
    columns: dict[str, list[Any]] = {key: [] for key in QPBENCHMARK_KEYS}
    for problem in problems:
        qp = qp_matrices(problem, formulation)
        for key in QPBENCHMARK_KEYS:
            value = qp.get(key)
            if sp.issparse(value):
                value = _dense_flat(value, problem)
            columns[key].append(problem.name if key == "name" else value)
    if not columns["name"]:
        raise QpbenchError("no problems to export")
    frame = pd.DataFrame(columns)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temporary:
        frame.to_parquet(temporary, engine="pyarrow", index=False)
    return len(frame)


def export_mat(problems: Iterable[ImpactProblem], folder: Path, formulation: str) -> int:
    """Writes ``folder/<name>.mat`` per problem; returns the number written."""
    folder.mkdir(parents=True, exist_ok=True)
    count = 0
    for problem in problems:
        content = {**qp_matrices(problem, formulation), "name": problem.name}
        target = folder / f"{problem.name}.mat"
        with atomic_path(target) as temporary:
            scipy.io.savemat(str(temporary), content, do_compression=True)
        count += 1
    if not count:
        raise QpbenchError("no problems to export")
    return count


def export(paths: Iterable[str | os.PathLike[str]], output: str | os.PathLike[str],
           fmt: str = "parquet", formulation: str = "dual") -> int:
    """Exports every problem file named or found in ``paths``; returns the number exported."""
    if fmt not in FORMATS:
        raise QpbenchError(f"--format: unknown '{fmt}' (known: {', '.join(FORMATS)})")
    if formulation not in FORMULATIONS:
        raise QpbenchError(f"--formulation: unknown '{formulation}' "
                           f"(known: {', '.join(FORMULATIONS)})")
    problems = files.load_all(paths)
    if fmt == "parquet":
        return export_parquet(problems, Path(output), formulation)
    return export_mat(problems, Path(output), formulation)
