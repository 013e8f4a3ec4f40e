"""Projected Gauss-Seidel on a box QP, compiled (numba): the friction QP of ``staggered`` for
the solvers written here.

For ``min 1/2 x^T P x + c^T x`` over ``lower <= x <= upper`` (P symmetric positive
semi-definite, given by its CSR arrays), one sweep updates the coordinates in the given order,

    x_i <- clip(x_i - (P x + c)_i / P_ii, lower_i, upper_i),

with ``(P x)_i`` summed over row i in its stored order, and the residual is the box QP's
natural map ``||d x - clip(d x - g, d lower, d upper)||_inf`` with ``g = P x + c``, ``d = diag P``
(1 where it is 0). :func:`box_gauss_seidel` sweeps the coordinates colour by colour (no two
coordinates of one colour are coupled), so a sweep here is the same sweep as one of its
colour classes at a time; ``qpbench.solvers.friction_staggered`` and
``qpbench.solvers.staggered_compiled`` both call it, with the order of
``qpbench.solvers.colouring.colour_order``. Compiled once per process and cached beside this
file (``cache=True``); :func:`warm_up` loads it (and the colouring) outside any clock.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers import colouring


@njit(cache=True)
def box_residual(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, c: np.ndarray,
                 lower: np.ndarray, upper: np.ndarray, x: np.ndarray) -> float:
    """The box QP's natural-map residual of ``x``.

    ``||d x - clip(d x - g, d lower, d upper)||_inf``, ``g = P x + c``, ``d = diag P`` (1 where
    it is 0).

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        P in CSR form, shape (m, m).
    c : np.ndarray
        The linear term, shape (m,).
    lower, upper : np.ndarray
        The box's bounds, shape (m,).
    x : np.ndarray
        The point, shape (m,).

    Returns
    -------
    float
        The residual, 0 for an empty x.
    """
    worst = 0.0
    for i in range(x.size):
        gradient = c[i]
        d = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            gradient += data[k] * x[indices[k]]
            if indices[k] == i:
                d = data[k]
        d = d if d > 0.0 else 1.0
        scaled = d * x[i]
        value = abs(scaled - min(max(scaled - gradient, d * lower[i]), d * upper[i]))
        worst = max(worst, value)
    return worst


@njit(cache=True)
def box_sweeps(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, c: np.ndarray,
               lower: np.ndarray, upper: np.ndarray, diag: np.ndarray, order: np.ndarray,
               x: np.ndarray, tolerance: float, max_sweeps: int, check_every: int
               ) -> tuple[int, bool]:
    """Sweep the coordinates ``order`` of ``x`` in place until the residual reaches ``tolerance``.

    Each sweep visits ``order`` (coordinates with ``diag > 0``) once; it stops when
    :func:`box_residual` is at most ``tolerance`` (checked every ``check_every`` sweeps) or
    ``max_sweeps`` are done.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        P in CSR form, shape (m, m).
    c : np.ndarray
        The linear term, shape (m,).
    lower, upper : np.ndarray
        The box's bounds, shape (m,).
    diag : np.ndarray
        diag P, shape (m,); positive on every coordinate of ``order``.
    order : np.ndarray
        The coordinates to update, in sweep order.
    x : np.ndarray
        The start inside the box, shape (m,), updated in place.
    tolerance : float
        The residual of :func:`box_residual` to reach (absolute).
    max_sweeps : int
        The most sweeps.
    check_every : int
        Sweeps between residual checks.

    Returns
    -------
    sweeps : int
        The sweeps done.
    converged : bool
        Whether the residual reached ``tolerance``.
    """
    sweeps = 0
    while sweeps < max_sweeps:
        for _ in range(min(check_every, max_sweeps - sweeps)):
            for i in order:
                product = 0.0  # (P x)_i as SciPy's CSR product sums it, then + c_i
                for k in range(indptr[i], indptr[i + 1]):
                    product += data[k] * x[indices[k]]
                gradient = product + c[i]
                x[i] = min(max(x[i] - gradient / diag[i], lower[i]), upper[i])
            sweeps += 1
        if box_residual(indptr, indices, data, c, lower, upper, x) <= tolerance:
            return sweeps, True
    return sweeps, False


@njit(cache=True)
def box_gauss_seidel(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, c: np.ndarray,
                     lower: np.ndarray, upper: np.ndarray, diag: np.ndarray,
                     colour_order: np.ndarray, start: np.ndarray, tolerance: float,
                     max_sweeps: int, check_every: int) -> tuple[np.ndarray, int, bool]:
    """Projected Gauss-Seidel on the box QP from ``start`` clipped into the box.

    A coordinate with ``lower == upper`` (an empty box) stays at its bound; one
    with ``diag <= 0`` has a zero row (P is PSD) and a constant gradient c_i, so it goes to the
    bound that gradient points to, once; the others are swept (:func:`box_sweeps`) in
    ``colour_order`` (every coordinate, in a stable order of the greedy colours of P's graph),
    unless :func:`box_residual` is at most ``tolerance`` already (0 sweeps).

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        P in CSR form, shape (m, m), symmetric positive semi-definite.
    c : np.ndarray
        The linear term, shape (m,).
    lower, upper : np.ndarray
        The box's bounds, shape (m,); ``lower <= upper``.
    diag : np.ndarray
        diag P, shape (m,).
    colour_order : np.ndarray
        Every coordinate once, in sweep order
        (:func:`qpbench.solvers.colouring.colour_order`).
    start : np.ndarray
        The starting point, shape (m,); not changed.
    tolerance : float
        The residual of :func:`box_residual` to reach (absolute).
    max_sweeps : int
        The most sweeps.
    check_every : int
        Sweeps between residual checks.

    Returns
    -------
    x : np.ndarray
        The last iterate, shape (m,), inside the box.
    sweeps : int
        The sweeps done.
    converged : bool
        Whether the residual reached ``tolerance``.
    """
    x = np.minimum(np.maximum(start, lower), upper)
    movable = np.zeros(x.size, dtype=np.bool_)
    for i in range(x.size):
        if upper[i] <= lower[i]:
            continue
        if diag[i] <= 0.0:
            if c[i] > 0.0:
                x[i] = lower[i]
            elif c[i] < 0.0:
                x[i] = upper[i]
        else:
            movable[i] = True
    if box_residual(indptr, indices, data, c, lower, upper, x) <= tolerance:
        return x, 0, True
    sweeps, converged = box_sweeps(indptr, indices, data, c, lower, upper, diag,
                                   colour_order[movable[colour_order]], x, tolerance,
                                   max_sweeps, check_every)
    return x, sweeps, converged


_warm = False


def warm_up() -> None:
    """Compiles (or loads from the cache) the kernels once in this process."""
    global _warm
    if _warm:
        return
    indptr = np.array([0, 2, 4], dtype=np.int32)
    indices = np.array([0, 1, 0, 1], dtype=np.int32)
    data = np.array([2.0, 1.0, 1.0, 2.0])
    ones = np.ones(2)
    box_gauss_seidel(indptr, indices, data, -ones, -ones, ones, 2.0 * ones,
                     np.arange(2, dtype=np.int64), np.zeros(2), 1e-12, 10, 5)
    box_residual(indptr, indices, data, -ones, -ones, ones, np.zeros(2))
    colouring.warm_up()
    _warm = True
