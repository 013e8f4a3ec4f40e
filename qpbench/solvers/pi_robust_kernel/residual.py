"""qpbench's natural residual in compiled code, its rounding bounds and the certificate.

Every residual of the kernel is qpbench's ``||min(D l, Q l + b)||_inf / scale``
(``qpbench.problem.metrics.residual``, D = diag Q) with ``Q l`` summed column by column over
the problem's own CSC arrays, in the order of scipy's CSC product, so that the value is
qpbench's to the bit. A claimed convergence is certified when that residual plus a bound on
what any other summation order could change (Higham, "Accuracy and Stability of Numerical
Algorithms", 2nd ed., SIAM 2002, section 3.1) is still within the tolerance
(:func:`_certified`); otherwise the caller checks it with qpbench's own metric.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.problem.metrics import TINY
from qpbench.solvers.pi_robust_kernel.constants import WITHOUT_REFCOUNTS
from qpbench.solvers.pi_robust_kernel.structures import Csc, Posed


@njit(cache=True)
def natural_residual(csc: Csc, b: np.ndarray, diag: np.ndarray, scale: float,
                     impulses: np.ndarray) -> float:
    """qpbench's natural residual ``||min(D l, Q l + b)||_inf / scale``, to the bit.

    Parameters
    ----------
    csc : Csc
        Q's CSC arrays ``(indptr, indices, data)`` as posed.
    b, diag : np.ndarray
        The LCP's constant term and diag(Q).
    scale : float
        The residual's scale (``metrics.scale``).
    impulses : np.ndarray
        l.

    Returns
    -------
    float
        The residual, with ``Q l`` summed column by column in the order of scipy's CSC product,
        so that it equals ``qpbench.problem.metrics.residual`` even where rounding dominates.
    """
    return _natural_residual_into(csc, b, diag, scale, impulses, np.empty(impulses.size))


@njit(cache=True, **WITHOUT_REFCOUNTS)
def residual_scale(b: np.ndarray) -> float:
    """qpbench's ``metrics.scale`` of the residual: ``max(max |b_i|, TINY)``.

    Parameters
    ----------
    b : np.ndarray
        The LCP's constant term.

    Returns
    -------
    float
        The scale; NaN when b has a NaN.
    """
    scale = TINY
    for value in b:
        if abs(value) > scale or value != value:
            scale = abs(value)
    return scale


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _natural_residual_into(csc: Csc, b: np.ndarray, diag: np.ndarray, scale: float,
                           impulses: np.ndarray, product: np.ndarray) -> float:
    """:func:`natural_residual`, with ``Q l`` formed in ``product`` (overwritten). The columns
    of zero entries of l are skipped: their terms are zeros, and adding a zero to a sum that
    starts at +0 never changes it, so the value is the same to the bit."""
    matvec_into(csc, impulses, product)
    worst = 0.0
    for i in range(impulses.size):
        value = abs(min(diag[i] * impulses[i], product[i] + b[i]))
        if value > worst:
            worst = value
    return worst / scale


@njit(cache=True)
def residual_rounding_bound(csc: Csc, b: np.ndarray, scale: float,
                            impulses: np.ndarray) -> float:
    """Bound how far any other summation order of ``Q l + b`` can move the residual.

    The bound is ``2 gamma max_i (sum_k |Q_ik l_k| + |b_i|) / scale`` with
    ``gamma = (m + 2) u / (1 - (m + 2) u)``, m the most entries in a column and u = 2^-53
    (Higham 2002, section 3.1: another product order, or fused multiply-adds, changes each sum
    by at most gamma times its sum of magnitudes). D l, min, abs, max and the division round
    identically in every implementation.

    Parameters
    ----------
    csc : Csc
        Q's CSC arrays ``(indptr, indices, data)`` as posed.
    b : np.ndarray
        The LCP's constant term (n entries).
    scale : float
        The residual's scale (``metrics.scale``).
    impulses : np.ndarray
        l (n entries).

    Returns
    -------
    float
        The bound, in the residual's (scaled) units: added to :func:`natural_residual`, no
        summation order can give a larger residual.
    """
    return _rounding_bound_into(csc, b, scale, impulses, np.empty(b.size))


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _rounding_bound_into(csc: Csc, b: np.ndarray, scale: float, impulses: np.ndarray,
                         magnitude: np.ndarray) -> float:
    """:func:`residual_rounding_bound`, with ``sum_k |Q_ik l_k| + |b_i|`` formed in
    ``magnitude`` (overwritten)."""
    indptr, indices, data = csc
    for i in range(b.size):
        magnitude[i] = abs(b[i])
    for column in range(impulses.size):
        value = abs(impulses[column])
        for k in range(indptr[column], indptr[column + 1]):
            magnitude[indices[k]] += abs(data[k]) * value
    largest = 0.0
    for i in range(b.size):
        largest = max(largest, magnitude[i])
    return 2.0 * _gamma(_longest(indptr)) * largest / scale


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _longest(indptr: np.ndarray) -> int:
    """m, the most entries in a column of Q."""
    longest = 0
    for column in range(indptr.size - 1):
        longest = max(longest, indptr[column + 1] - indptr[column])
    return longest


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _gamma(longest: int) -> float:
    """``gamma = (m + 2) u / (1 - (m + 2) u)``, m = ``longest``, u = 2^-53."""
    unit = (longest + 2) * 2.0 ** -53
    return unit / (1.0 - unit)


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _loose_rounding_bound(csc: Csc, b: np.ndarray, scale: float,
                          impulses: np.ndarray) -> float:
    """A bound at least :func:`residual_rounding_bound`'s, without a product.

    ``2 gamma (m max |Q_ik| max |l_k| + max |b_i|) / scale``: each of the at most m terms of a
    row of the symmetric Q is at most ``max |Q_ik| max |l_k|``. Three maxima, where the product
    of |Q| and |l| scatters into every row.
    """
    indptr, _, data = csc
    entry, impulse, constant = 0.0, 0.0, 0.0
    for k in range(data.size):
        entry = max(entry, abs(data[k]))
    for i in range(b.size):
        impulse = max(impulse, abs(impulses[i]))
        constant = max(constant, abs(b[i]))
    longest = _longest(indptr)
    return 2.0 * _gamma(longest) * (longest * entry * impulse + constant) / scale


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _original_residual(original: Posed, scale: float, impulses: np.ndarray,
                       product: np.ndarray, unpermuted: np.ndarray) -> float:
    """qpbench's residual of ``impulses`` given in the kernel's order, on the problem as posed
    (``l[original.order] = impulses``, formed in ``unpermuted``; Q l in ``product``)."""
    posed, order = impulses, original.order
    if order.size:
        posed = unpermuted
        for i in range(impulses.size):
            posed[order[i]] = impulses[i]
    return _natural_residual_into(original.csc, original.b, original.diag, scale, posed,
                                  product)


@njit(cache=True)
def _matvec(csc: Csc, x: np.ndarray) -> np.ndarray:
    """Q x over Q's CSC arrays."""
    product = np.empty(x.size)
    matvec_into(csc, x, product)
    return product


@njit(cache=True, **WITHOUT_REFCOUNTS)
def matvec_into(csc: Csc, x: np.ndarray, product: np.ndarray) -> None:
    """Form ``product = Q x`` over Q's CSC arrays (the columns of zero entries of x skipped).

    Parameters
    ----------
    csc : Csc
        Q's CSC arrays ``(indptr, indices, data)``.
    x : np.ndarray
        The vector to multiply (n entries).
    product : np.ndarray
        Where Q x is written (n entries, overwritten); summed column by column, in the order
        of scipy's CSC product.
    """
    indptr, indices, data = csc
    product[:] = 0.0
    for column in range(x.size):
        value = x[column]
        if value != 0.0:
            for k in range(indptr[column], indptr[column + 1]):
                product[indices[k]] += data[k] * value


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _certified(csc: Csc, b: np.ndarray, scale: float, impulses: np.ndarray, residual: float,
               tol: float, magnitude: np.ndarray) -> bool:
    """Whether ``residual`` plus a rounding bound is at most tol.

    ``residual`` is qpbench's, summed in scipy's order; when the sum with a bound on what any
    other summation order could change is still within tol, no implementation of the residual
    can put the answer above tol. :func:`_loose_rounding_bound` is tried first (no product), then
    :func:`residual_rounding_bound` (formed in ``magnitude``, n entries, overwritten).
    """
    return residual + _loose_rounding_bound(csc, b, scale, impulses) <= tol or \
        residual + _rounding_bound_into(csc, b, scale, impulses, magnitude) <= tol

