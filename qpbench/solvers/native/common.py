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
    """The pair's solver name: ``<solver>-native``.

    Parameters
    ----------
    solver : str
        The backend's name (``osqp``, ``piqp-dense``).

    Returns
    -------
    str
        The name qpbench lists the pair under.
    """
    return f"{solver}-native"


def package_version(package: str) -> str:
    """The installed version of ``package`` (empty when it has no metadata).

    Parameters
    ----------
    package : str
        The Python distribution's name (``proxsuite``).

    Returns
    -------
    str
        Its version, or '' when it has no metadata.
    """
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return ""


def register_missing(names: dict[str, tuple[str, ...]], error: ImportError) -> None:
    """Registers every pair of ``names`` as unusable, with the import error as the reason.

    Parameters
    ----------
    names : dict[str, tuple[str, ...]]
        Each solver name and its formulations.
    error : ImportError
        Why the backend's package could not be imported.
    """
    for name, formulations in names.items():
        register_unusable(name, formulations, BACKEND, f"import failed: {error}")


def register_pairs(name: str, solves: dict[str, SolveFunction], package: str,
                   warm_start: bool | Callable[[str], bool] = False,
                   refused: dict[str, str] | None = None,
                   prepare: Callable[[], None] | None = None) -> None:
    """Registers ``name`` in each formulation of ``solves``, and in each of ``refused``.

    The formulations of ``refused`` are registered as unusable, with their reason.

    Parameters
    ----------
    name : str
        The pair's solver name (``osqp-native``).
    solves : dict[str, SolveFunction]
        Each usable formulation and its solve function.
    package : str
        The distribution whose version the pairs carry and their description names.
    warm_start : bool or callable, optional
        Whether the pairs take warm starts: one flag for every formulation, or a function
        of the formulation; False by default.
    refused : dict[str, str] or None, optional
        Formulations that cannot run and why; None for none.
    prepare : callable or None, optional
        The backend's one-time set-up per process (``SolverSpec.prepare``); None for none.
    """
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
    """The lower triangle of a symmetric matrix as CSC (HiGHS's triangular Hessian).

    Parameters
    ----------
    matrix : sp.spmatrix
        A symmetric sparse matrix.

    Returns
    -------
    sp.csc_matrix
        Its lower triangle, diagonal included.
    """
    return sp.tril(matrix, format="csc")


def dense_symmetric(matrix: sp.spmatrix) -> np.ndarray:
    """A symmetric sparse matrix as a dense Fortran-ordered array.

    That is what Eigen-based backends take without a copy: the transpose of a C-ordered
    copy, equal to the matrix itself.

    Parameters
    ----------
    matrix : sp.spmatrix
        A symmetric sparse matrix.

    Returns
    -------
    np.ndarray
        The same matrix, dense, Fortran order.
    """
    return matrix.toarray().T


def dense_diagonal(diagonal: np.ndarray) -> np.ndarray:
    """A diagonal matrix as a dense Fortran-ordered array.

    ``diag(d)`` is symmetric, so this is its transposed C-ordered copy.

    Parameters
    ----------
    diagonal : np.ndarray
        d, shape (k,).

    Returns
    -------
    np.ndarray
        diag(d), shape (k, k), Fortran order.
    """
    return np.diag(diagonal).T


def dense_fortran(matrix: sp.spmatrix) -> np.ndarray:
    """A sparse matrix as a dense Fortran-ordered array.

    Parameters
    ----------
    matrix : sp.spmatrix
        Any sparse matrix.

    Returns
    -------
    np.ndarray
        The same matrix, dense, Fortran order.
    """
    return matrix.toarray(order="F")


def primal_start(problem: ImpactProblem, impulses: np.ndarray | None) -> np.ndarray | None:
    """A warm start for the primal: v+(l) on the free degrees of freedom.

    Parameters
    ----------
    problem : ImpactProblem
        The impact problem.
    impulses : np.ndarray or None
        A guess of l, shape (n,); None for none.

    Returns
    -------
    np.ndarray or None
        v+(l) on the degrees of freedom with ``m_inv > 0``; None without a guess.
    """
    if impulses is None:
        return None
    return problem.v_plus(np.asarray(impulses, dtype=float))[problem.m_inv > 0]


def factored_start(problem: ImpactProblem, impulses: np.ndarray | None) -> np.ndarray | None:
    """A warm start for the dual-factored form: ``x = (l, L l)``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact problem, for L = M^-1/2 G.
    impulses : np.ndarray or None
        A guess of l, shape (n,); None for none.

    Returns
    -------
    np.ndarray or None
        x = (l, y) with y = L l; None without a guess.
    """
    if impulses is None:
        return None
    impulses = np.asarray(impulses, dtype=float)
    return np.concatenate([impulses, factored_rows(problem) @ impulses])


def factored_rows_with_bounds(problem: ImpactProblem) -> tuple[sp.csc_matrix, int, int]:
    """``[[L, -I], [I, 0]]`` over ``x = (l, y)``, for backends without bounds.

    The k equality rows ``L l - y = 0`` first, then the n rows ``l`` of the bounds
    ``l >= 0``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact problem of n contacts.

    Returns
    -------
    rows : sp.csc_matrix
        The stacked rows, shape (k + n, n + k).
    k : int
        The number of equality rows (rows of L).
    n : int
        The number of contacts.
    """
    factored = factored_dual_qp(problem)
    n = factored.n_contacts
    k = factored.A.shape[0]
    bounds = sp.hstack([sp.identity(n, format="csc"), sp.csc_matrix((n, k))])
    return sp.vstack([factored.A, bounds], format="csc"), k, n


def bounds_only_rows(n: int) -> sp.csc_matrix:
    """The n x n identity as CSC: the rows ``I l`` of ``l >= 0`` for backends without bounds.

    Parameters
    ----------
    n : int
        The number of contacts.

    Returns
    -------
    sp.csc_matrix
        The identity, shape (n, n).
    """
    return sp.identity(n, format="csc")
