"""Our problem sets in forms other QP benchmarks read.

* ``parquet``: qpbenchmark's problem list, one row per problem with columns
  ``P, q, G, h, A, b, lb, ub, name``; matrices dense and flattened row by row, absent
  entries null (as qpbenchmark's ParquetTestSet reads them). Note that qpbenchmark's
  ``b`` is the right-hand side of equality constraints, not our ``b``.
* ``mat``: one MATLAB file per problem (scipy.io.savemat) with sparse ``P``, ``q``,
  ``lb`` (dual) or ``P, q, G, h`` (primal), plus ``name`` and ``model``.

Formulations (docs/design.md section 1), both as ``min 1/2 x^T P x + q^T x``:

* ``dual``: ``P = Q``, ``q = b``, ``lb = 0`` (x = l, the impulses);
* ``primal``: ``P = diag(M_free)``, ``q = -M_free v-_free``, ``G x <= h`` with
  ``G = -G_free^T``, ``h = -lower`` (x = v+ on the degrees of freedom with finite mass).

A frictional problem is not a QP under Coulomb's law; both formats hold it as the QP of
Anitescu's convex relaxation (the ``ccp`` model, docs/design.md section 8), which in 2D is an
impact problem of 2n contacts with columns ``n + mu t`` and ``n - mu t``
(:meth:`FrictionalProblem.relaxed`): the dual's x is ``z = (z+, z-)``, whence
``l_N = z+ + z-`` and ``l_T = mu (z+ - z-)``; the primal's x is v+ as above. Its answer is the
``ccp`` model's, not Coulomb's. A ``.mat`` file says which in ``model`` (``impact`` or
``ccp``) and, for ``ccp``, holds ``mu``.

Nothing is half-written: the Parquet list is one atomic file, and the ``.mat`` files are
all written to temporary files first and renamed only once every problem has been written.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.io
import scipy.sparse as sp

from qpbench.atomic import atomic_path, checked_target
from qpbench.errors import InputError, OutputError, QpbenchError, UnsupportedError
from qpbench.problem import fclib, files
from qpbench.problem.files import AnyProblem
from qpbench.problem.formulations import primal_qp
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem

FORMATS = ("parquet", "mat", "fclib")
FORMULATIONS = ("dual", "primal")
QPBENCHMARK_KEYS = ("P", "q", "G", "h", "A", "b", "lb", "ub", "name")
MAX_DENSE_ENTRIES = 50_000_000  # 400 MB of float64 per dense matrix in the Parquet list
IMPACT_MODEL = "impact"
FRICTIONAL_MODEL = "ccp"


def exported_problem(problem: AnyProblem) -> ImpactProblem:
    """Give the impact problem whose QP is exported for ``problem``.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to export.

    Returns
    -------
    ImpactProblem
        ``problem`` itself, or for a frictional problem its ``ccp`` relaxation (2n contacts).
    """
    return problem.relaxed() if isinstance(problem, FrictionalProblem) else problem


def qp_matrices(problem: AnyProblem, formulation: str) -> dict[str, Any]:
    """Build the QP of ``problem`` as qpbenchmark names it.

    A frictional problem's QP is that of its ``ccp`` relaxation.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to export.
    formulation : str
        ``dual`` (``P = Q``, ``q = b``, ``lb = 0``) or ``primal`` (``P = diag(M_free)``,
        ``q = -M_free v-_free``, ``G = -G_free^T``, ``h = -lower``).

    Returns
    -------
    dict of str to Any
        ``P`` (sparse CSC), ``q`` and either ``lb`` (dual) or ``G`` (sparse CSC) and ``h``
        (primal).

    Raises
    ------
    QpbenchError
        On an unknown formulation.
    """
    impact = exported_problem(problem)
    if formulation == "dual":
        return {"P": sp.csc_matrix(impact.Q), "q": np.asarray(impact.b, dtype=float),
                "lb": np.zeros(impact.n_contacts)}
    if formulation == "primal":
        qp = primal_qp(impact)
        return {"P": sp.csc_matrix(qp.P), "q": np.asarray(qp.q, dtype=float),
                "G": sp.csc_matrix(-qp.A), "h": -np.asarray(qp.lower, dtype=float)}
    raise QpbenchError(f"--formulation: unknown '{formulation}' (known: {', '.join(FORMULATIONS)})")


def mat_content(problem: AnyProblem, formulation: str) -> dict[str, Any]:
    """Assemble what ``<name>.mat`` holds: the QP, ``name``, ``model`` and, for ``ccp``, ``mu``.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to export.
    formulation : str
        ``dual`` or ``primal`` (:func:`qp_matrices`).

    Returns
    -------
    dict of str to Any
        The variables of the MATLAB file; ``model`` is ``impact`` or ``ccp``.
    """
    content = {**qp_matrices(problem, formulation), "name": problem.name}
    if isinstance(problem, FrictionalProblem):
        return {**content, "model": FRICTIONAL_MODEL, "mu": np.asarray(problem.mu, dtype=float)}
    return {**content, "model": IMPACT_MODEL}


def _dense_flat(matrix: sp.spmatrix, problem: AnyProblem) -> np.ndarray:
    if matrix.shape[0] * matrix.shape[1] > MAX_DENSE_ENTRIES:
        raise UnsupportedError(f"{problem.source or problem.name}: a {matrix.shape} matrix is too "
                               "large for qpbenchmark's dense Parquet list; use --format mat")
    return np.asarray(matrix.toarray(), dtype=float).ravel()


def export_parquet(problems: Iterable[AnyProblem], path: Path, formulation: str) -> int:
    """Write qpbenchmark's problem list to ``path`` as one atomic Parquet file.

    Matrices are dense and flattened row by row; absent entries are null.

    Parameters
    ----------
    problems : iterable of ImpactProblem or FrictionalProblem
        The problems, one row each.
    path : pathlib.Path
        The Parquet file to write.
    formulation : str
        ``dual`` or ``primal`` (:func:`qp_matrices`).

    Returns
    -------
    int
        The number of problems written.

    Raises
    ------
    QpbenchError
        When there is no problem, or a matrix is too large to store dense (UnsupportedError).
    """
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
    with atomic_path(path) as temporary:
        frame.to_parquet(temporary, engine="pyarrow", index=False)
    return len(frame)


def export_files(problems: Iterable[AnyProblem], folder: Path, suffix: str,
                 write: Callable[[AnyProblem, Path], None]) -> int:
    """Write ``folder/<name><suffix>`` per problem with ``write(problem, path)``, all or none.

    Each file is written to a temporary file, and none is renamed into place before all are
    written, so an error on any problem leaves the folder as it was.

    Parameters
    ----------
    problems : iterable of ImpactProblem or FrictionalProblem
        The problems, one file each.
    folder : pathlib.Path
        The folder to write into.
    suffix : str
        The files' suffix, with its dot (``.mat``).
    write : callable
        ``write(problem, path)`` writes one problem to ``path`` (a temporary file).

    Returns
    -------
    int
        The number of files written.

    Raises
    ------
    InputError
        When two problems have one name (their files would be one).
    QpbenchError
        When there is no problem.
    """
    written: dict[str, str] = {}
    with ExitStack() as pending:
        for problem in problems:
            if problem.name in written:
                raise InputError(problem.source or problem.name, f"problem name "
                                 f"'{problem.name}' is also that of {written[problem.name]}; "
                                 f"each {suffix} file is named by its problem")
            written[problem.name] = problem.source or problem.name
            write(problem, pending.enter_context(atomic_path(folder / f"{problem.name}{suffix}")))
        if not written:
            raise QpbenchError("no problems to export")
    return len(written)


def export_mat(problems: Iterable[AnyProblem], folder: Path, formulation: str) -> int:
    """Write one MATLAB file per problem in ``folder`` (:func:`mat_content`), all or none.

    Parameters
    ----------
    problems : iterable of ImpactProblem or FrictionalProblem
        The problems, one file each.
    folder : pathlib.Path
        The folder to write into.
    formulation : str
        ``dual`` or ``primal`` (:func:`qp_matrices`).

    Returns
    -------
    int
        The number of files written.
    """
    return export_files(problems, folder, ".mat", lambda problem, path: scipy.io.savemat(
        str(path), mat_content(problem, formulation), do_compression=True))


def export_fclib(problems: Iterable[AnyProblem], folder: Path) -> int:
    """Write one HDF5 file per problem in ``folder`` in FCLIB's layout, all or none.

    See :mod:`qpbench.problem.fclib`.

    Parameters
    ----------
    problems : iterable of ImpactProblem or FrictionalProblem
        The problems, one file each.
    folder : pathlib.Path
        The folder to write into.

    Returns
    -------
    int
        The number of files written.
    """
    return export_files(problems, folder, fclib.SUFFIX, fclib.write)


def check_output(output: Path, fmt: str) -> None:
    """Check, before any problem is read, that ``output`` can take ``fmt``.

    Parameters
    ----------
    output : pathlib.Path
        The output path.
    fmt : str
        ``parquet`` needs a regular file or nothing (:func:`checked_target`); ``mat`` and
        ``fclib`` need a folder or nothing.

    Raises
    ------
    OutputError
        When ``output`` cannot take ``fmt``.
    """
    if fmt == "parquet":
        checked_target(output)
    elif checked_target(output, accept_folder=True).exists() and not output.is_dir():
        raise OutputError(output, f"is a file; --format {fmt} writes a folder of files")


def export(paths: Iterable[str | os.PathLike[str]], output: str | os.PathLike[str],
           fmt: str = "parquet", formulation: str = "dual") -> int:
    """Export every problem file named or found in ``paths``.

    Frictional problems are exported as their ``ccp`` relaxation.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Problem files and directories holding them.
    output : str or os.PathLike
        The Parquet file (``parquet``) or the folder (``mat``, ``fclib``) to write.
    fmt : str, optional
        ``parquet`` (default), ``mat`` or ``fclib``.
    formulation : str, optional
        ``dual`` (default) or ``primal``; ``fclib`` ignores it.

    Returns
    -------
    int
        The number of problems exported.

    Raises
    ------
    QpbenchError
        On an unknown format or formulation, an unusable output (OutputError), an unreadable
        problem file, or no problem at all.
    """
    if fmt not in FORMATS:
        raise QpbenchError(f"--format: unknown '{fmt}' (known: {', '.join(FORMATS)})")
    if formulation not in FORMULATIONS:
        raise QpbenchError(f"--formulation: unknown '{formulation}' "
                           f"(known: {', '.join(FORMULATIONS)})")
    output = Path(output)
    check_output(output, fmt)
    problems = files.load_all(paths)
    if fmt == "parquet":
        return export_parquet(problems, output, formulation)
    if fmt == "fclib":
        return export_fclib(problems, output)
    return export_mat(problems, output, formulation)
