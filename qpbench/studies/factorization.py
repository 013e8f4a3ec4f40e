"""One sparse factorization of a shifted block of Q, timed: what pi-robust is held against.

The block is ``Q_FF + eps I`` over a set F of contacts (all of a problem's, or the active
ones, l > 0, of an answer), with ``eps = FACTOR_SHIFT * max(diag Q)`` over the whole
problem, since ``Q_FF`` may be singular. It is factored by each of :data:`METHODS`:

* ``CHOLMOD/AMD``: CHOLMOD's simplicial LDL^T in approximate-minimum-degree order
  (``qpbench.solvers.sparse_cholesky.symmetric_factor``, as pi-robust's sparse path factors
  its blocks), when scikit-sparse imports;
* ``SuperLU/MMD_AT_PLUS_A``: SuperLU's LU with a minimum-degree order on A^T + A and
  diagonal pivots (``sparse_cholesky.symmetric_splu``).

Each is timed under the timing protocol of docs/design.md section 7
(``qpbench.bench.schedule.Schedule``): one untimed call each, then rounds of one call each in
a rotated order; the matrix is built outside the clock, the minimum over the rounds kept, and
the fastest method is "one sparse factorization". A method that fails (a pivot not
numerically positive) has no time and is not a candidate.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.bench.schedule import Schedule
from qpbench.problem import metrics
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import sparse_cholesky

FACTOR_SHIFT = 1e-8
REPEATS = 5
CHOLMOD = f"CHOLMOD/{sparse_cholesky.CHOLMOD_ORDERING.upper()}"
SUPERLU = "SuperLU/MMD_AT_PLUS_A"
# method -> the call that factors a matrix; CHOLMOD only when scikit-sparse imports (else
# symmetric_factor would be SuperLU again)
Factorize = Callable[[sp.csc_matrix], object]
METHODS: dict[str, Factorize] = {SUPERLU: sparse_cholesky.symmetric_splu}
if sparse_cholesky.LIBRARY == "CHOLMOD":
    METHODS = {CHOLMOD: sparse_cholesky.symmetric_factor, **METHODS}


def library(method: str) -> str:
    """The library of a method name (``CHOLMOD/AMD`` -> ``CHOLMOD``).

    Parameters
    ----------
    method : str
        A method: the library, then ``/`` and its ordering.

    Returns
    -------
    str
        The part before the ``/``.
    """
    return method.split("/")[0]


def shifted_block(problem: ImpactProblem, contacts: np.ndarray | None = None) -> sp.csc_matrix:
    """``Q_FF + eps I`` with ``eps = FACTOR_SHIFT * max(diag Q)``, in CSC.

    Parameters
    ----------
    problem : ImpactProblem
        The problem whose Q is taken.
    contacts : np.ndarray or None, optional
        F, the contact indices of the block; None (default) for all of them.

    Returns
    -------
    sp.csc_matrix
        The shifted block, (len(F), len(F)), both triangles stored.
    """
    shift = FACTOR_SHIFT * metrics.vector_scale(problem.diag_Q)
    block = problem.Q if contacts is None else problem.Q[contacts][:, contacts]
    return sp.csc_matrix(block + shift * sp.identity(block.shape[0], format="csc"))


def time_once(matrix: sp.csc_matrix, factorize: Factorize) -> float:
    """Wall seconds of one factorization of ``matrix``; NaN when it fails.

    Parameters
    ----------
    matrix : sp.csc_matrix
        The matrix, built beforehand.
    factorize : Factorize
        The call that factors it (a value of METHODS).

    Returns
    -------
    float
        The seconds, or NaN when the matrix is not numerically positive definite for it.
    """
    start = time.perf_counter()
    try:
        factorize(matrix)
    except np.linalg.LinAlgError:
        return math.nan
    return time.perf_counter() - start


def fastest(seconds: Mapping[str, Sequence[float]]) -> dict[str, Any]:
    """The fastest method from the timed calls of each: its time, name and library.

    Parameters
    ----------
    seconds : mapping of str to sequence of float
        Per method, the seconds of its timed calls (NaN for a failed call).

    Returns
    -------
    dict
        ``factorization_s`` (the minimum over every method's successful calls, None when none
        succeeded), ``factorization_method`` and ``factorization_library`` (None with it), and
        ``factorization_s_by_method`` (each method's minimum, None when it always failed).
    """
    by_method: dict[str, float | None] = {}
    for method, times in seconds.items():
        finite = [value for value in times if math.isfinite(value)]
        by_method[method] = min(finite) if finite else None
    timed = {method: value for method, value in by_method.items() if value is not None}
    best = min(timed, key=timed.__getitem__) if timed else None
    return {"factorization_s": None if best is None else timed[best],
            "factorization_method": best,
            "factorization_library": None if best is None else library(best),
            "factorization_s_by_method": by_method}


def time_factorizations(matrix: sp.csc_matrix, repeats: int = REPEATS,
                        methods: Mapping[str, Factorize] | None = None) -> dict[str, Any]:
    """Every method timed on one matrix under the timing protocol, the fastest kept.

    Parameters
    ----------
    matrix : sp.csc_matrix
        The matrix (:func:`shifted_block`), built before any call.
    repeats : int, optional
        Timed calls per method; REPEATS by default.
    methods : mapping of str to Factorize, or None, optional
        The methods; None (default) for METHODS.

    Returns
    -------
    dict
        The fields of :func:`fastest`.
    """
    chosen = dict(METHODS if methods is None else methods)
    seconds: dict[str, list[float]] = {method: [] for method in chosen}
    for call in Schedule(list(chosen), repeats, unit=lambda method: method, warm_up=True):
        elapsed = time_once(matrix, chosen[call.item])
        if call.timed:
            seconds[call.item].append(elapsed)
    return fastest(seconds)


def active_block_factorization(problem: ImpactProblem, impulses: np.ndarray,
                               repeats: int = REPEATS) -> dict[str, Any]:
    """One sparse factorization of the active block of an answer, timed.

    F = the contacts with ``impulses > 0``; the block is :func:`shifted_block` over F, timed
    by :func:`time_factorizations`.

    Parameters
    ----------
    problem : ImpactProblem
        The impact problem the answer solves.
    impulses : np.ndarray
        The answer l, one impulse per contact.
    repeats : int, optional
        Timed calls per method; REPEATS by default.

    Returns
    -------
    dict
        ``active_contacts`` (len(F)), ``active_nonzeros`` (nonzeros of the block),
        ``factor_shift`` (FACTOR_SHIFT) and the fields of :func:`fastest` (no time, None,
        when F is empty).
    """
    active = np.flatnonzero(np.asarray(impulses) > 0)
    block = {"active_contacts": int(active.size), "factor_shift": FACTOR_SHIFT}
    if not active.size:
        return {**block, "active_nonzeros": 0, **fastest({method: [] for method in METHODS})}
    matrix = shifted_block(problem, active)
    return {**block, "active_nonzeros": int(matrix.nnz), **time_factorizations(matrix, repeats)}
