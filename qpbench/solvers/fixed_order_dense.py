"""Dense products and factorizations whose rounding does not depend on the CPU.

NumPy's ``@`` and SciPy's LAPACK calls go to the BLAS, whose kernels (and so the order in
which each sum is taken) OpenBLAS picks for the CPU at run time: the same dense product or
factor rounds otherwise on another machine, and on problems whose solves follow the rounding
(extreme mass ratios, where pi-robust's Python path and Lemke's method run) the answer, its
residual and even its verdict change with the CPU.

Here every sum is taken in index order, in compiled loops (numba, no fast-math flags, so the
compiler neither reorders nor fuses a multiply and an add): the loops that vectorize update
independent entries (``y_i += a x_i``), which rounds the same at any vector width. The
algorithms are the textbook ones (Golub and Van Loan, "Matrix Computations", 4th ed., 2013):
the product of a symmetric matrix as a sum of its rows, Cholesky's factorization ``A = U^T U``
by rows with outer-product updates of the rows below (algorithm 4.2.2's right-looking form),
Gaussian elimination with partial pivoting (algorithm 3.4.1) for a general square matrix, and
the minimum-norm least-squares solution of a symmetric positive semi-definite system from
Cholesky's factorization with diagonal pivoting (algorithm 4.2.4; Higham, "Accuracy and
Stability of Numerical Algorithms", 2nd ed., 2002, section 10.3, its rank taken as LAPACK's
``dpstrf`` takes it by default) and a Householder QR factorization of the factor's transpose
(algorithm 5.2.1). :func:`warm_up` compiles them, or loads them from numba's cache, outside
any clock.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _symmetric_product(matrix: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A^T x``, which is ``A x`` for a symmetric A: row j of A times x_j, added in order of j."""
    n = x.size
    product = np.zeros(matrix.shape[1])
    for j in range(n):
        weight = x[j]
        if weight != 0.0:
            row = matrix[j]
            for i in range(product.size):
                product[i] += weight * row[i]
    return product


@numba.njit(cache=True)
def _cholesky_upper(matrix: np.ndarray) -> tuple[np.ndarray, bool]:
    """U with ``U^T U = A`` in the upper triangle (the strict lower one is left as A's), and
    False at the first pivot that is not positive (or not a number)."""
    n = matrix.shape[0]
    work = matrix.copy()
    for k in range(n):
        pivot = work[k, k]
        if not pivot > 0.0:
            return work, False
        root = np.sqrt(pivot)
        for j in range(k, n):
            work[k, j] = work[k, j] / root
        for i in range(k + 1, n):
            factor = work[k, i]
            if factor != 0.0:
                for j in range(i, n):
                    work[i, j] -= factor * work[k, j]
    return work, True


@numba.njit(cache=True)
def _back_substitution(upper: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Overwrites y with the solution of ``U x = y`` (U's upper triangle) and returns it."""
    n = y.size
    for k in range(n - 1, -1, -1):
        total = y[k]
        for j in range(k + 1, n):
            total -= upper[k, j] * y[j]
        y[k] = total / upper[k, k]
    return y


@numba.njit(cache=True)
def _forward_substitution(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """y with ``U^T y = rhs`` (U upper triangular), forward by the rows of U."""
    n = rhs.size
    y = rhs.copy()
    for k in range(n):
        y[k] = y[k] / upper[k, k]
        weight = y[k]
        if weight != 0.0:
            for i in range(k + 1, n):
                y[i] -= weight * upper[k, i]
    return y


@numba.njit(cache=True)
def _cholesky_solve(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with ``U^T U x = rhs``: ``U^T y = rhs`` forward, then ``U x = y``."""
    return _back_substitution(upper, _forward_substitution(upper, rhs))


@numba.njit(cache=True)
def _lu_solve(matrix: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
    """x with ``A x = rhs`` by Gaussian elimination with partial pivoting (the first of equal
    candidates), and False when a column has no non-zero pivot left (A singular)."""
    n = rhs.size
    work = matrix.copy()
    x = rhs.copy()
    for k in range(n):
        chosen, largest = k, abs(work[k, k])
        for i in range(k + 1, n):
            if abs(work[i, k]) > largest:
                chosen, largest = i, abs(work[i, k])
        if largest == 0.0:
            return x, False
        if chosen != k:
            for j in range(k, n):
                work[k, j], work[chosen, j] = work[chosen, j], work[k, j]
            x[k], x[chosen] = x[chosen], x[k]
        for i in range(k + 1, n):
            factor = work[i, k] / work[k, k]
            if factor != 0.0:
                for j in range(k + 1, n):
                    work[i, j] -= factor * work[k, j]
                x[i] -= factor * x[k]
    return _back_substitution(work, x), True


@numba.njit(cache=True)
def _pivoted_cholesky(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(U, order, r): ``U^T U = A[order][:, order]`` to rank r, U's first r rows (upper
    trapezoidal, zeros below the diagonal), each step's pivot the largest diagonal of what is
    left (the first of equals), stopping where it is at most ``n eps max(diag A)``."""
    n = matrix.shape[0]
    work = matrix.copy()
    order = np.arange(n)
    largest = 0.0
    for i in range(n):
        largest = max(largest, work[i, i])
    tolerance = n * np.finfo(np.float64).eps * largest
    rank = n
    for k in range(n):
        chosen = k
        for i in range(k + 1, n):
            if work[i, i] > work[chosen, chosen]:
                chosen = i
        if not work[chosen, chosen] > tolerance:
            rank = k
            break
        if chosen != k:
            for j in range(n):
                work[k, j], work[chosen, j] = work[chosen, j], work[k, j]
            for i in range(n):
                work[i, k], work[i, chosen] = work[i, chosen], work[i, k]
            order[k], order[chosen] = order[chosen], order[k]
        root = np.sqrt(work[k, k])
        for j in range(k, n):
            work[k, j] = work[k, j] / root
        for i in range(k + 1, n):
            factor = work[k, i]
            if factor != 0.0:
                for j in range(k + 1, n):
                    work[i, j] -= factor * work[k, j]
    upper = work[:rank].copy()
    for i in range(rank):
        for j in range(i):
            upper[i, j] = 0.0
    return upper, order, rank


@numba.njit(cache=True)
def _reflect(reflectors: np.ndarray, k: int, x: np.ndarray) -> None:
    """Applies the Householder reflection ``I - 2 v v^T / v^T v`` of column k of
    ``reflectors`` (v in rows k and below) to x, in place."""
    n = x.size
    norm2 = 0.0
    dot = 0.0
    for i in range(k, n):
        norm2 += reflectors[i, k] * reflectors[i, k]
        dot += reflectors[i, k] * x[i]
    if norm2 == 0.0:
        return
    scale = 2.0 * dot / norm2
    for i in range(k, n):
        x[i] -= scale * reflectors[i, k]


@numba.njit(cache=True)
def _min_norm_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``A^+ rhs`` for a symmetric positive semi-definite A (module docstring): with
    ``A[order][:, order] = U^T U`` to rank r and ``P U^T = Q R`` (P's rows back in A's order),
    ``A^+ = Q R^-T R^-1 Q^T``; at full rank, ``A^-1 rhs`` from U by two triangular solves."""
    n = rhs.size
    upper, order, rank = _pivoted_cholesky(matrix)
    if rank == n:  # A is positive definite: A^-1 rhs from U alone
        permuted = np.empty(n)
        for j in range(n):
            permuted[j] = rhs[order[j]]
        permuted = _cholesky_solve(upper, permuted)
        solution = np.empty(n)
        for j in range(n):
            solution[order[j]] = permuted[j]
        return solution
    tall = np.zeros((n, rank))  # (U P^T)^T, A's order, then its reflectors below R
    for i in range(rank):
        for j in range(n):
            tall[order[j], i] = upper[i, j]
    triangle = np.zeros((rank, rank))  # R
    for k in range(rank):
        norm2 = 0.0
        for i in range(k, n):
            norm2 += tall[i, k] * tall[i, k]
        alpha = -np.sqrt(norm2) if tall[k, k] >= 0.0 else np.sqrt(norm2)
        tall[k, k] -= alpha
        triangle[k, k] = alpha
        for j in range(k + 1, rank):
            column = tall[:, j].copy()
            _reflect(tall, k, column)
            for i in range(k, n):
                tall[i, j] = column[i]
            triangle[k, j] = tall[k, j]
    x = rhs.copy()
    for k in range(rank):
        _reflect(tall, k, x)
    # R^-T R^-1 (Q^T rhs)
    y = _forward_substitution(triangle, _back_substitution(triangle, x[:rank].copy()))
    solution = np.zeros(n)
    solution[:rank] = y
    for k in range(rank - 1, -1, -1):
        _reflect(tall, k, solution)
    return solution


def _compiled_operand(values: np.ndarray) -> np.ndarray:
    """``values`` as the compiled functions take them: C-contiguous, writeable float64 (a
    read-only or other array would make numba compile another variant inside the clock)."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    return values if values.flags.writeable else values.copy()


def symmetric_product(matrix: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for a symmetric dense A, summed in an order that does not depend on the CPU.

    Computed as ``sum_j x_j A[j, :]`` (A's rows in index order, rows with ``x_j = 0``
    skipped), that is ``A^T x``: equal to ``A x`` for a symmetric A, and a matrix only nearly
    symmetric (a scaled copy of one) gets the product of its transpose, equally accurate.

    Parameters
    ----------
    matrix : np.ndarray
        A, shape (n, n), symmetric.
    x : np.ndarray
        A vector of n entries.

    Returns
    -------
    np.ndarray
        A x, n entries.
    """
    return _symmetric_product(_compiled_operand(matrix), _compiled_operand(x))


def product(matrix: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for any dense A (not symmetric: a frictional LCP's), in a fixed order.

    The symmetric product of a contiguous copy of ``A^T``: ``sum_j x_j A[:, j]``.

    Parameters
    ----------
    matrix : np.ndarray
        A, shape (m, n).
    x : np.ndarray
        A vector of n entries.

    Returns
    -------
    np.ndarray
        A x, m entries.
    """
    return _symmetric_product(np.ascontiguousarray(np.transpose(matrix), dtype=np.float64),
                              _compiled_operand(x))


def cholesky(matrix: np.ndarray) -> np.ndarray:
    """The Cholesky factor U of a symmetric positive definite A (``A = U^T U``), for
    :func:`cholesky_solve`.

    Parameters
    ----------
    matrix : np.ndarray
        A, shape (n, n); only its upper triangle is read.

    Returns
    -------
    np.ndarray
        U in the upper triangle of an (n, n) array (what lies below it is not part of U).

    Raises
    ------
    np.linalg.LinAlgError
        When a pivot is not positive: A is not positive definite to working precision.
    """
    upper, factored = _cholesky_upper(_compiled_operand(matrix))
    if not factored:
        raise np.linalg.LinAlgError("matrix is not positive definite")
    return upper


def cholesky_solve(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with ``U^T U x = rhs``, U from :func:`cholesky`.

    Parameters
    ----------
    upper : np.ndarray
        The factor, shape (n, n).
    rhs : np.ndarray
        The right side, n entries.

    Returns
    -------
    np.ndarray
        x, n entries.
    """
    return _cholesky_solve(upper, _compiled_operand(rhs))


def lu_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with ``A x = rhs`` for a square A, by Gaussian elimination with partial pivoting.

    Parameters
    ----------
    matrix : np.ndarray
        A, shape (n, n).
    rhs : np.ndarray
        The right side, n entries.

    Returns
    -------
    np.ndarray
        x, n entries.

    Raises
    ------
    np.linalg.LinAlgError
        When A is singular (a column without a non-zero pivot), as ``np.linalg.solve``.
    """
    x, solved = _lu_solve(_compiled_operand(matrix), _compiled_operand(rhs))
    if not solved:
        raise np.linalg.LinAlgError("singular matrix")
    return x


def min_norm_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares solution ``A^+ rhs`` of a symmetric positive
    semi-definite A, as ``np.linalg.lstsq`` gives it, in a fixed order.

    Cholesky's factorization with diagonal pivoting, ``A[o][:, o] = U^T U``, stops at the
    numerical rank r (the next pivot at most ``n eps max(diag A)``, LAPACK's ``dpstrf``
    default), so that ``A = F^T F`` with F, r x n, of full row rank; a Householder QR of
    ``F^T = Q R`` gives ``A^+ = Q (R R^T)^-1 Q^T = Q R^-T R^-1 Q^T``.

    Parameters
    ----------
    matrix : np.ndarray
        A, shape (n, n), symmetric positive semi-definite.
    rhs : np.ndarray
        The right side, n entries.

    Returns
    -------
    np.ndarray
        x, n entries: the least-squares solution of least norm (zero when A is).
    """
    return _min_norm_solve(_compiled_operand(matrix), _compiled_operand(rhs))


def warm_up() -> None:
    """Compiles the functions above, or loads them from numba's cache; once per process,
    outside any clock (a solver's ``prepare``)."""
    matrix, vector = np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([1.0, -1.0])
    symmetric_product(matrix, vector)
    product(matrix, vector)
    cholesky_solve(cholesky(matrix), vector)
    lu_solve(matrix, vector)
    min_norm_solve(matrix, vector)
