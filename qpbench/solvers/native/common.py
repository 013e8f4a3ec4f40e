"""What the native pairs share: their backend name, registration, versions, and the
formulations' data in the shapes backends take (dense, upper triangle, warm starts).

Every native pair poses the formulations of docs/design.md section 1:

* ``dual``: ``min 1/2 l^T Q l + b^T l`` with the bounds ``l >= 0`` (as bounds where the
  backend has them, else as the rows ``I l >= 0``);
* ``primal``: ``min 1/2 v^T M v - (M v-)^T v`` over the free dofs with ``G^T v >= lower``
  (``qpbench.problem.formulations.PrimalQP``); the impulses are the multipliers of those
  rows, read with each backend's sign convention;
* ``dual-factored``: ``min 1/2 y^T y + b^T l`` with ``L l - y = 0`` and ``l >= 0``
  (``FactoredDualQP``), for the sparse backends, where it keeps Q unformed; a dense backend
  would gain nothing from it.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import metadata

import numpy as np
import scipy.sparse as sp

from qpbench.problem.formulations import factored_dual_qp, factored_rows
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolveFunction, SolverSpec
from qpbench.solvers.registry import register, register_unusable

BACKEND = "native"


def native_name(solver: str) -> str:
    """The pair's solver name: ``<solver>-native``."""
    return f"{solver}-native"


def package_version(package: str) -> str:
    """The installed version of ``package`` (empty when it has no metadata)."""
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return ""


def register_missing(names: dict[str, tuple[str, ...]], error: ImportError) -> None:
    """Registers every pair of ``names`` (solver -> formulations) as unusable, with the import
    error as the reason."""
    for name, formulations in names.items():
        register_unusable(name, formulations, BACKEND, f"import failed: {error}")


def register_pairs(name: str, solves: dict[str, SolveFunction], package: str,
                   warm_start: bool | Callable[[str], bool] = False,
                   refused: dict[str, str] | None = None,
                   prepare: Callable[[], None] | None = None) -> None:
    """Registers ``name`` in each formulation of ``solves``, and in each of ``refused``
    (formulation -> why) as unusable with that reason. ``warm_start`` is one flag for every
    formulation or a function of the formulation; ``prepare`` is the backend's one-time
    set-up per process (``SolverSpec.prepare``)."""
    version = package_version(package)
    for formulation, solve in solves.items():
        warm = warm_start(formulation) if callable(warm_start) else warm_start
        register(SolverSpec(name=name, formulation=formulation, backend=BACKEND, solve=solve,
                            version=version, warm_start=warm, prepare=prepare,
                            description=f"{package} through its own Python API"))
    for formulation, reason in (refused or {}).items():
        register(SolverSpec(name=name, formulation=formulation, backend=BACKEND, solve=None,
                            version=version, reason=reason))


def lower_triangle(matrix: sp.spmatrix) -> sp.csc_matrix:
    """The lower triangle of a symmetric matrix as CSC (HiGHS's triangular Hessian)."""
    return sp.tril(matrix, format="csc")


def dense_symmetric(matrix: sp.spmatrix) -> np.ndarray:
    """A symmetric sparse matrix as a dense Fortran-ordered array (what Eigen-based backends
    take without a copy): the transpose of a C-ordered copy, equal to the matrix itself."""
    return matrix.toarray().T


def dense_diagonal(diagonal: np.ndarray) -> np.ndarray:
    """A diagonal matrix as a dense Fortran-ordered array (``diag(d)`` is symmetric, so
    its transposed C-ordered copy)."""
    return np.diag(diagonal).T


def dense_fortran(matrix: sp.spmatrix) -> np.ndarray:
    """A sparse matrix as a dense Fortran-ordered array."""
    return matrix.toarray(order="F")


def primal_start(problem: ImpactProblem, impulses: np.ndarray | None) -> np.ndarray | None:
    """A warm start for the primal: v+(l) on the free degrees of freedom."""
    if impulses is None:
        return None
    return problem.v_plus(np.asarray(impulses, dtype=float))[problem.m_inv > 0]


def factored_start(problem: ImpactProblem, impulses: np.ndarray | None) -> np.ndarray | None:
    """A warm start for the dual-factored form: ``x = (l, L l)``."""
    if impulses is None:
        return None
    impulses = np.asarray(impulses, dtype=float)
    return np.concatenate([impulses, factored_rows(problem) @ impulses])


def factored_rows_with_bounds(problem: ImpactProblem) -> tuple[sp.csc_matrix, int, int]:
    """``[[L, -I], [I, 0]]`` over ``x = (l, y)``: the k equality rows ``L l - y = 0`` first,
    then the n rows ``l`` of the bounds ``l >= 0``, for backends without bounds; with k and n."""
    factored = factored_dual_qp(problem)
    n = factored.n_contacts
    k = factored.A.shape[0]
    bounds = sp.hstack([sp.identity(n, format="csc"), sp.csc_matrix((n, k))])
    return sp.vstack([factored.A, bounds], format="csc"), k, n


def bounds_only_rows(n: int) -> sp.csc_matrix:
    """The n x n identity as CSC: the rows ``I l`` of ``l >= 0`` for backends without bounds."""
    return sp.identity(n, format="csc")
