"""The breakdown's floor in compiled code: LAPACK's Cholesky (``dpotrf`` dense, ``dpbtrf``
banded) and a CSC product ``Q l``, each repeated inside one compiled call, so that no Python
call overhead is counted (about a millisecond of repetitions per timed round).

The LAPACK routines are SciPy's own (``scipy.linalg.cython_lapack``), called from numba
through their addresses. A factorization overwrites its input, so every repetition first
copies the pristine matrix back; the time of the copies alone, measured the same way, is
subtracted. Times are per repetition, the fastest of the caller's rounds; ``*_rounds`` give one
round at a time, so that the caller can interleave them with its other timings.
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Callable

import numpy as np
from numba import njit
from numba.extending import get_cython_function_address

from qpbench.solvers.pi_robust_kernel.residual import matvec_into

# per timed round: repetitions inside the one compiled call, about ROUND_SECONDS of them
MAX_REPETITIONS = 100
ROUND_SECONDS = 1e-3
_LOWER = ord("L")  # uplo: the lower triangle


def _lapack(name: str, arguments: int) -> Callable[..., None]:
    """SciPy's LAPACK routine ``name`` as a ctypes function of ``arguments`` pointers (the
    Fortran convention: every argument by reference)."""
    address = get_cython_function_address("scipy.linalg.cython_lapack", name)
    return ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * arguments)(address)


_dpotrf = _lapack("dpotrf", 5)  # (uplo, n, a, lda, info)
_dpbtrf = _lapack("dpbtrf", 6)  # (uplo, n, kd, ab, ldab, info)


@njit  # not cached: numba cannot cache a call through a ctypes address
def _repeat_cholesky(pristine: np.ndarray, work: np.ndarray, count: int, factor: bool,
                     banded: bool) -> int:
    """``count`` times: copy ``pristine`` (Fortran order) into ``work`` and, when ``factor``,
    factor it in LAPACK: ``dpotrf('L')`` on a dense n x n matrix, or when ``banded``
    ``dpbtrf('L')`` on a lower band (``(kd + 1) x n``: ``band[i - j, j] = A_ij``); LAPACK's
    info of the last factorization (0: positive definite)."""
    lower = np.array([_LOWER], dtype=np.uint8)
    rows = np.array([pristine.shape[0]], dtype=np.int32)  # the leading dimension
    n = np.array([pristine.shape[1]], dtype=np.int32)
    width = np.array([pristine.shape[0] - 1], dtype=np.int32)  # kd, of a band
    info = np.zeros(1, dtype=np.int32)
    flat_pristine, flat_work = pristine.T.ravel(), work.T.reshape(-1)
    for _ in range(count):
        flat_work[:] = flat_pristine
        if factor and banded:
            _dpbtrf(lower.ctypes, n.ctypes, width.ctypes, flat_work.ctypes, rows.ctypes,
                    info.ctypes)
        elif factor:
            _dpotrf(lower.ctypes, n.ctypes, flat_work.ctypes, rows.ctypes, info.ctypes)
    return info[0]


@njit(cache=True)
def _repeat_product(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                    impulses: np.ndarray, product: np.ndarray, count: int) -> None:
    """``count`` times ``product = Q l`` over Q's CSC arrays, by pi-robust's own product."""
    for _ in range(count):
        matvec_into((indptr, indices, data), impulses, product)


def _repetitions(run: Callable[[int], object]) -> int:
    """Repetitions per timed round: about ROUND_SECONDS of ``run``, between 1 and
    MAX_REPETITIONS (after one untimed call that compiles or loads it)."""
    run(1)
    start = time.perf_counter()
    run(1)
    once = max(time.perf_counter() - start, 1e-9)
    return int(min(MAX_REPETITIONS, max(1.0, ROUND_SECONDS / once)))


def _round(run: Callable[[int], object], count: int) -> Callable[[], float]:
    """A function that times one round, ``run(count)``, and returns seconds per repetition."""
    def timed() -> float:
        start = time.perf_counter()
        run(count)
        return (time.perf_counter() - start) / count

    return timed


def cholesky_rounds(matrix: np.ndarray, banded: bool
                    ) -> Callable[[], tuple[float, float]] | None:
    """A timer of one round of Cholesky factorizations of ``matrix`` in LAPACK.

    The function returned times one round of Cholesky factorizations of ``matrix`` (dense n x n,
    or a lower band when ``banded``) in LAPACK and one round of its copies alone. The caller
    interleaves rounds with its other timings.

    Parameters
    ----------
    matrix : np.ndarray
        The symmetric matrix: dense (n, n), or its lower band ((kd + 1), n) with
        ``band[i - j, j] = A_ij``.
    banded : bool
        Whether ``matrix`` is a lower band (``dpbtrf``) rather than dense (``dpotrf``).

    Returns
    -------
    callable or None
        A function of no argument returning (seconds per copy and factorization, seconds per
        copy); None when ``matrix`` is not positive definite.
    """
    pristine = np.asfortranarray(matrix, dtype=float)
    if pristine.size == 0:
        return lambda: (0.0, 0.0)
    work = np.empty_like(pristine, order="F")
    if _repeat_cholesky(pristine, work, 1, True, banded) != 0:
        return None

    def factors(count: int) -> None:
        _repeat_cholesky(pristine, work, count, True, banded)

    def copies_only(count: int) -> None:
        _repeat_cholesky(pristine, work, count, False, banded)

    count = _repetitions(factors)
    with_copies, copies = _round(factors, count), _round(copies_only, count)
    return lambda: (with_copies(), copies())


def product_rounds(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                   impulses: np.ndarray) -> Callable[[], float]:
    """A timer of one round of products ``Q l`` over Q's CSC arrays, in compiled code.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays.
    impulses : np.ndarray
        (n,) the vector l.

    Returns
    -------
    callable
        A function of no argument returning seconds per product.
    """
    impulses = np.ascontiguousarray(impulses, dtype=float)
    product = np.empty(impulses.size)

    def run(count: int) -> None:
        _repeat_product(indptr, indices, data, impulses, product, count)

    return _round(run, _repetitions(run))
