"""The tuples that carry one compiled pi-robust solve's arrays, and its packed options.

Arguments travel in tuples: a CSC matrix as ``(indptr, indices, data)`` (:data:`Csc`), the
ordered problem as :class:`OrderedLcp`, the problem as posed as :class:`Posed`, the options as
:class:`Options` and :class:`Prox`, the kept factors as :class:`FactorCache`, a solve's work
arrays as :class:`Work`. Unpacking a tuple is free in the functions compiled without
reference counting (``constants.WITHOUT_REFCOUNTS``). Options cross from Python as one float
array (:func:`options_of`, :func:`unpacked`): a call whose arguments are all arrays is typed
by numba's fast dispatch path, where a tuple of options is not.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

Csc = tuple[np.ndarray, np.ndarray, np.ndarray]  # (indptr, indices, data) of a CSC matrix
# (starts, ends, rows, values) of Q's upper triangle: column c's entries (Q_rc, r <= c) are
# rows[starts[c]:ends[c]] and values[starts[c]:ends[c]]
Upper = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class Prox(NamedTuple):
    """Safeguards of one prox policy iteration: rho falls by ``rho_decrease`` (not below
    ``rho_min``) after ``stall_steps`` steps that do not cut the residual by ``stall_ratio``;
    block pivoting takes ``backup_steps`` non-improving full exchanges, then (when
    ``active_set``) the primal active-set method :func:`_primal_active_set` finishes the prox
    step; at most ``drift_steps`` times a run, a settled step that does not cut the residual by
    ``stall_ratio`` moves the centre along its drift (:func:`_extrapolate_drift`)."""

    rho_min: float
    rho_decrease: float
    stall_ratio: float
    stall_steps: int
    backup_steps: int
    active_set: bool
    drift_steps: int


class Options(NamedTuple):
    """pi-robust's options that the kernel uses (see :func:`options_of`)."""

    tol: float  # converged when qpbench's residual <= tol
    rho: float  # the first prox weight
    prox: Prox  # the safeguards of every prox policy iteration
    pi_budget: int  # linear solves of the first policy iteration
    finish_budget: int  # linear solves of each finishing policy iteration
    finish_below: float  # interior-point residual below which it is finished
    ipm_iters: int
    start_sweeps: int  # projected Gauss-Seidel sweeps on a start that is not converged


# the order in which options travel packed into one array (a call with arrays only is typed
# by numba's fast path; tuples of options cost microseconds on every call)
PACKED = ("tol", "rho", *Prox._fields, "pi_budget", "finish_budget", "finish_below",
          "ipm_iters", "start_sweeps")


def options_of(settings: dict[str, Any]) -> np.ndarray:
    """Pack the kernel's options into one float array, in the order of ``PACKED``.

    Parameters
    ----------
    settings : dict[str, Any]
        pi-robust's accuracy-table row (``accuracy.options_for("pi-robust", ...)``); it must
        hold every name of ``PACKED``, other keys are ignored. Booleans and integers are
        stored as floats.

    Returns
    -------
    np.ndarray
        The ``len(PACKED)`` option values as float64, read back by :func:`unpacked`.
    """
    return np.array([float(settings[name]) for name in PACKED])


@njit(cache=True)
def unpacked(values: np.ndarray) -> Options:
    """:class:`Options` from the array :func:`options_of` packs (positions as in PACKED).

    Parameters
    ----------
    values : np.ndarray
        The packed options (float64, ``len(PACKED)`` entries); counts are truncated to int,
        and ``active_set`` is true when its entry is non-zero.

    Returns
    -------
    Options
        The options, their prox safeguards as :class:`Prox`.
    """
    prox = Prox(values[2], values[3], values[4], int(values[5]), int(values[6]),
                values[7] != 0.0, int(values[8]))
    return Options(values[0], values[1], prox, int(values[9]), int(values[10]), values[11],
                   int(values[12]), int(values[13]))


class Posed(NamedTuple):
    """The problem as posed, on which every residual is taken: ``csc`` its Q,
    ``l[order] = impulses`` for impulses in the kernel's order (``order`` empty: the kernel
    keeps the posed order)."""

    csc: Csc
    b: np.ndarray
    diag: np.ndarray
    order: np.ndarray


class OrderedLcp(NamedTuple):
    """LCP(Q, b) in the kernel's order (a bandwidth-reducing permutation of the contacts, or
    none): ``A`` is Q's CSC arrays, ``upper`` its upper triangle (:func:`_upper`: the lower
    triangle's rows, from which the envelope factors are filled), ``safe_diag`` is D with
    zeros replaced, ``scale`` the residual's scale; ``original`` the problem as posed."""

    A: Csc
    upper: Upper
    original: Posed
    b: np.ndarray
    diag: np.ndarray
    safe_diag: np.ndarray
    scale: float


class FactorCache(NamedTuple):
    """The kept envelope Cholesky factors of blocks ``Q_FF + rho D_F``, one per slot s:
    ``factors[s]`` its rows, ``offsets[s]`` its row starts (row i in
    ``factors[s, offsets[s, i]:offsets[s, i + 1]]``), ``policies[s]`` and ``rhos[s]`` the key
    it belongs to (``rhos[s] = -1``: invalid), ``ages[s]`` its last use, ``dependents[s]`` its
    dependent contacts (:func:`_block_solve`); ``counters = [factorizations, uses, dependent
    contacts of the factor used last]``; ``position`` a work array (all -1 between uses). A
    new factor replaces the least recently used slot; a row deletion updates the most recently
    used one in place. A block's envelope is never wider than the whole matrix's in the same
    order, so each slot holds the whole envelope's size."""

    factors: np.ndarray
    offsets: np.ndarray
    policies: np.ndarray
    rhos: np.ndarray
    ages: np.ndarray
    counters: np.ndarray
    position: np.ndarray
    dependents: np.ndarray


class Work(NamedTuple):
    """What one solve works in, allocated once so that no step of policy iteration allocates:
    ``cache`` the kept factors; n entries each: ``x`` block pivoting's iterate, ``rhs`` a
    block system's right side and then its solution (and the violators' scaled slacks when the
    active-set method frees contacts), ``q`` a prox step's q, ``centre`` the prox centre,
    ``product`` a product ``Q x``, ``unpermuted`` an l in the posed order, ``free`` the
    policy's free contacts, ``infeasible`` the contacts to exchange, ``best_x`` the exchange
    with the fewest infeasible contacts, ``feasible`` the active-set method's point, ``tol_l``
    a prox run's tolerance on each impulse, ``drift`` and ``previous_drift`` the change of l in
    a prox step and in the one before, ``listed`` the free contacts that a solve of the
    active-set method sends below zero (then the places in its block of the contacts its step
    fixes, or at a minimum the violators, :func:`_free_violators`), ``cosines`` and ``sines``
    the rotations of a row deletion (:func:`_delete_contact`)."""

    cache: FactorCache
    x: np.ndarray
    rhs: np.ndarray
    q: np.ndarray
    centre: np.ndarray
    product: np.ndarray
    unpermuted: np.ndarray
    free: np.ndarray
    infeasible: np.ndarray
    best_x: np.ndarray
    feasible: np.ndarray
    tol_l: np.ndarray
    drift: np.ndarray
    previous_drift: np.ndarray
    listed: np.ndarray
    cosines: np.ndarray
    sines: np.ndarray


@njit(cache=True)
def _work(n: int, capacity: int):
    """Allocate the work arrays of a solve of n contacts, in three allocations.

    Returns ``(work, policy, first, polished)``: the :class:`Work` of a solve whose whole
    envelope has ``capacity`` entries (its :class:`FactorCache` with two empty slots), and
    n-entry arrays for the start's policy, the first prox run's l and the polished l. Three
    allocations (reals, integers, flags) are sliced into all of them. An l returned as it is
    (the posed order kept) is a view of ``reals`` and keeps it alive: two envelopes and 15 n
    numbers.
    """
    slots = 2
    reals = np.empty(slots * capacity + 15 * n + slots)
    integers = np.empty(slots * (n + 1) + 3 * n + 2 * slots + 3, dtype=np.int64)
    flags = np.zeros((slots + 2) * n, dtype=np.bool_)
    vectors = reals[slots * capacity:slots * capacity + 15 * n].reshape((15, n))
    rhos = reals[slots * capacity + 15 * n:]
    rhos[:] = -1.0
    vectors[0, :] = 0.0  # block pivoting's x starts at zero
    integers[:] = 0
    offsets = integers[:slots * (n + 1)].reshape((slots, n + 1))
    at = slots * (n + 1)
    position = integers[at:at + n]
    position[:] = -1
    cache = FactorCache(reals[:slots * capacity].reshape((slots, capacity)), offsets,
                        flags[:slots * n].reshape((slots, n)), rhos,
                        integers[at + 2 * n:at + 2 * n + slots],
                        integers[at + 2 * n + slots:at + 2 * n + slots + 3], position,
                        integers[at + 2 * n + slots + 3:at + 2 * n + 2 * slots + 3])
    work = Work(cache, vectors[0], vectors[1], vectors[2], vectors[3], vectors[4], vectors[5],
                integers[at + n:at + 2 * n], flags[slots * n:(slots + 1) * n], vectors[6],
                vectors[7], vectors[8], vectors[11], vectors[12],
                integers[at + 2 * n + 2 * slots + 3:], vectors[13], vectors[14])
    return work, flags[(slots + 1) * n:], vectors[9], vectors[10]

