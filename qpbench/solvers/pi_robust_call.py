"""How pi-robust calls its compiled kernel: the accuracy table's row split by who reads it,
and the calls themselves.

:func:`settings_for` reads pi-robust's row of the accuracy table once per level and packs
the kernel's options; :func:`kernel_into` is the call :func:`qpbench.solvers.pi_robust.solve`
makes inside the stopwatch (the kernel's narrow entry ``pi_robust_into``, reached through
``pi_robust_kernel.call``), :func:`kernel_call` the wider one the relaxed frictional solve
makes. Both touch as little Python as they can: on a problem of a few contacts, what the call
itself costs is much of the solve (docs/notes/pi-robust.md, section "The call boundary").
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.pi_robust_kernel import call as kernel_calls
from qpbench.solvers.pi_robust_kernel import entry as kernel_entry

NAME = "pi-robust"  # its row of the accuracy table
ORDERING_ABOVE = 64  # contacts; fewer are factored in their own order
NO_START = np.empty(0)  # the kernel's "start from zero"


def csc_arrays(Q: sp.spmatrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indptr, indices, data) of the problem's own CSC Q, the matrix qpbench's residual uses.

    Indices are 32-bit integers, as SciPy stores them (no copy then), for the kernel.

    Parameters
    ----------
    Q : sp.spmatrix
        The matrix; converted to CSC when it is in another format.

    Returns
    -------
    indptr, indices : np.ndarray
        The column starts and row indices, int32 (the CSC matrix's own arrays when they are
        int32 already).
    data : np.ndarray
        The entries, column by column (the CSC matrix's own array, not a copy).
    """
    Q = Q if sp.isspmatrix_csc(Q) else sp.csc_matrix(Q)
    return (Q.indptr.astype(np.int32, copy=False), Q.indices.astype(np.int32, copy=False),
            Q.data)


class Settings(NamedTuple):
    """pi-robust's accuracy-table row at one level, split by who reads it."""

    kernel: np.ndarray  # the compiled path's options, packed (pi_robust_kernel.entry.options_of)
    # pi_robust_into's (entry.call_options_of): ORDERING_ABOVE, compiled_work_limit, whether
    # to start from zero, then ``kernel``; from the start its caller writes into ``out``, and
    # from zero
    call_options: np.ndarray
    call_options_from_zero: np.ndarray
    python: dict  # the Python path's keyword arguments (without tol's scale: it is relative)
    dense_limit: int
    compiled_limit: int
    compiled_work_limit: float


@functools.lru_cache(maxsize=64)
def settings_for(eps: float) -> Settings:
    """The accuracy table's row for level ``eps``, read once per level.

    Tolerances here are relative to the problem's scale, so they do not depend on it.

    Parameters
    ----------
    eps : float
        qpbench's accuracy level, a bound on the relative residual.

    Returns
    -------
    Settings
        The row split into the kernel's packed options (and, in front of them, the narrow
        entry's call options from the start and from zero), the Python path's keyword
        arguments (without ``start_sweeps`` and the limits) and the three limits. Cached:
        callers must not change it.
    """
    options = accuracy.options_for(NAME, eps, 1.0)
    limits = {key: options.pop(key) for key in ("dense_limit", "compiled_limit",
                                                "compiled_work_limit")}
    kernel = kernel_entry.options_of(options)
    options.pop("start_sweeps")  # the compiled path's alone
    work_limit = float(limits["compiled_work_limit"])
    return Settings(kernel=kernel,
                    call_options=kernel_entry.call_options_of(ORDERING_ABOVE, work_limit, kernel),
                    call_options_from_zero=kernel_entry.call_options_of(
                        ORDERING_ABOVE, work_limit, kernel, from_zero=True),
                    python=options, dense_limit=int(limits["dense_limit"]),
                    compiled_limit=int(limits["compiled_limit"]),
                    compiled_work_limit=work_limit)


def kernel_call(kernel: Callable[..., tuple], problem: ImpactProblem, settings: Settings,
                warm_start: np.ndarray | None, *after_start: np.ndarray) -> tuple:
    """Call a compiled entry point of the kernel on ``problem``.

    ``kernel`` gets Q's CSC arrays, b, diag(Q), the start (empty: from zero),
    ``after_start``, the ordering threshold, the work limit and the packed options.

    The relaxed solve runs this inside the stopwatch, so it touches as little Python as it
    can: Q is CSC by construction (``ImpactProblem.Q``), b and diag(Q) float arrays, and Q's
    index arrays go as SciPy made them (32-bit at these sizes, the type pi-robust's ``prepare``
    compiles the kernel for). pi-robust's ``solve`` calls the narrower :func:`kernel_into`.

    Parameters
    ----------
    kernel : Callable[..., tuple]
        The entry point, ``pi_robust_kernel.entry.envelope_pi_robust`` or
        ``relaxed_pi_robust``.
    problem : ImpactProblem
        The posed problem (for the relaxed entry, ``FrictionalProblem.relaxed()``).
    settings : Settings
        The accuracy level's row (:func:`settings_for`): its work limit and packed options.
    warm_start : np.ndarray or None
        A start, flattened to float; None starts from zero.
    *after_start : np.ndarray
        Arguments the entry point takes after the start (the relaxed entry's friction
        coefficients mu).

    Returns
    -------
    tuple
        The entry point's answer: for ``envelope_pi_robust`` (l, converged, path, solves,
        interior iterations, factorizations, certified); ``relaxed_pi_robust`` puts r first.

    Raises
    ------
    np.linalg.LinAlgError
        When a factor fails in the kernel.
    """
    Q = problem.Q
    return kernel(Q.indptr, Q.indices, Q.data, problem.b, problem.diag_Q,
                  NO_START if warm_start is None else np.asarray(warm_start, dtype=float).ravel(),
                  *after_start, ORDERING_ABOVE, settings.compiled_work_limit, settings.kernel)


def kernel_into(problem: ImpactProblem, settings: Settings, warm_start: np.ndarray | None
                ) -> tuple[np.ndarray, tuple]:
    """Solve ``problem`` by the compiled kernel through its narrow entry ``pi_robust_into``
    (``pi_robust_kernel.call``: past numba's dispatcher where the arrays allow), as
    :func:`qpbench.solvers.pi_robust.solve` does inside the stopwatch; l is written into an
    array made here, which first holds the start, if any.

    Parameters
    ----------
    problem : ImpactProblem
        The posed problem.
    settings : Settings
        The accuracy level's row (:func:`settings_for`): its call options.
    warm_start : np.ndarray or None
        A start; None, or one not of one entry a contact, starts from zero (``Lcp.start``).

    Returns
    -------
    tuple
        l, and ``pi_robust_into``'s scalars (converged, path, solves, interior iterations,
        factorizations, certified).

    Raises
    ------
    np.linalg.LinAlgError
        When a factor fails in the kernel.
    """
    b = problem.b
    n = b.size
    impulses = np.empty(n)
    options = settings.call_options_from_zero
    if warm_start is not None:
        start = warm_start if type(warm_start) is np.ndarray else np.asarray(warm_start)
        if start.size == n:
            impulses[:] = start.ravel()
            options = settings.call_options
    Q = problem.Q
    return impulses, kernel_calls.call_pi_robust_into(Q.indptr, Q.indices, Q.data, b,
                                                      impulses, options)
