"""pi-robust compiled with numba, on envelope (skyline, profile) Cholesky factors.

The same algorithm as ``qpbench.solvers.pi_robust`` in its order for dense problems
(proximal policy iteration with block principal pivoting, then the Mehrotra interior point of
``qpbench.solvers.lcp_interior`` whose close iterates are finished by policy iteration), for
problems with at most the accuracy table's ``compiled_limit`` contacts, without per-step
Python overhead. Nothing here is dense: Q stays sparse throughout.

What it computes: l >= 0 with ``min(D l, Q l + b) = 0`` (D = diag Q), to qpbench's residual
``||min(D l, Q l + b)||_inf / scale <= tol``. Each prox step around a centre z solves
LCP(Q + rho D, b - rho D z) by block pivoting, or when that stops improving by a primal
active-set method; each step of either solves, for the policy's free set F,

    (Q_FF + rho D_F) x_F = -q_F

by the envelope Cholesky factor ``L L^T = Q_FF + rho D_F``; the interior point solves its
Jacobi-scaled Newton system ``(S Q S + diag(max(w / l, 1e-14))) dl = r`` (S = D^-1/2) by the
same factorization of the whole matrix.

Linear algebra: Q stays in CSC (products are sparse, summed column by column). Unless the
envelope in the posed order is cheap to factor already (``WIDE_ENVELOPE_WORK``), above
``order_above`` contacts, or when that envelope would cost more than ``WIDE_ENVELOPE`` of a
dense factorization, the contacts are put in reverse Cuthill-McKee order (Q's graph is the
line graph of the contact graph, so this order keeps every block's envelope narrow: a few tens
of columns on grids and packings). Row i of a factor is stored contiguously, its columns
``first(i) .. i`` (the diagonal last, as its reciprocal), with ``first(i)`` the leftmost
nonzero of row i of the block; the factor has the same envelope (no fill outside it), so one
factorization costs ``sum_i w_i^2 / 2`` multiply-adds (w_i = i - first(i) + 1) and a solve
``2 sum_i w_i``. The last two block factors are kept in a :class:`FactorCache`, keyed by
(policy, rho), so prox steps on a settled policy cost two triangular solves, and a new factor
copies the leading rows it shares with a kept one. A start that is not converged first gets
``start_sweeps`` projected Gauss-Seidel sweeps (:func:`_gauss_seidel`, in the posed order,
before any set-up), which cut the pivots that follow, and which alone solve contacts that
hardly interact (Q nearly diagonal: path ``start sweeps``, no ordering and no factorization).
A factor that fails raises ``np.linalg.LinAlgError``; the caller then runs the Python path.

Every residual is qpbench's formula summed over the problem's own CSC Q in scipy's order. A
claimed convergence is certified by the residual the solve measured on its answer plus a
rounding bound (no second pass), or else by the caller with qpbench's own metric, before it is
reported. Additions to the Python path: on nearly singular blocks block pivoting hands over
to the active-set method at once (:func:`_inner_lcp`; the Python path's factors, dense or over
the degrees of freedom, report no pivots per contact); when the interior point stalls (its
residual not cut by 10% in five iterations, as rounding makes it on extreme mass ratios) its
best iterate is handed to the finishing policy iteration too; and a converged answer whose
residual is above tol / 10 gets one more prox step on its own policy (``_polish``), so that it
is certified without a second residual pass.

Where blocks are updated rather than refactored: only where the active-set method fixes at
most ``UPDATE_FIXED`` contacts of the block it solved last (its steps to a blocking contact and
its projections), on problems whose D_i span at most ``UPDATE_SPREAD``: their rows are deleted
from that factor by plane rotations (:func:`_delete_contact`, :func:`_block_solve_fixing`).
Measured hot against refactoring from the first changed row (same solves everywhere): the
fork's 7x7 scenes 6-7% faster (at most 1, 2, 4 or 8 deleted contacts: 5.2, 5.8, 6.2 and 5.8%),
its 5x5 dumps, the grid captures and the box packings within 1%. Without the spread gate the
generated mass-ratio-10 problems (D spanning 1e10-2e11) took 6455 -> 6616 solves over 60
seeds (6 worse, 2 better, one more handed to the Python path): the updated factors round
otherwise, and the pivoting there follows the rounding; every other generated family took
the same solves. Earlier, deleting rows wherever ``_block_solve`` found a kept factor whose
policy held the new one (a scan of both slots' policies at every solve) cost the 5x5 dumps
3-4% and the grid captures 7%: the scan, not the deletions. Not updated elsewhere:

- Fixing contacts by a Schur complement instead (U = L^-1 E_D, (U^T U) mu = U^T y,
  x = L^-T (y - U mu)) cut the 7x7 factorizations from 1,725 to 719 with the same solves,
  yet the 7x7 kernel was only about 5% faster and the 5x5 kernel 4% slower (each fixed
  contact costs a forward substitution from its place and each step a backward one), and
  freed contacts the same way (a quasi-definite Schur matrix) 9% slower.
- A dense factor in the active-set method (``U^T U = H_MM``, a joining contact appended by a
  forward substitution, a leaving one removed by rotations) cut the 7x7 factorizations from
  34.5 to 7.8 with the same solves, yet the kernel was 6% slower: at about 74 free contacts
  a dense solve (k^2 multiply-adds), an append (k^2 / 2) and a removal cost about 7, 3 and 2
  thousand cycles, together about what the envelope refactor and its solves cost.

Why the interior point is a fallback and not the first phase (same problems): on Q alone it
needs about 12 iterations, but each factors all of Q's envelope (about 124k multiply-adds on
7x7, against 5-13k for the final active block), so it was 2.0-2.4x slower than this kernel.
Posed in velocity space instead (Mehrotra on ``min 1/2 |v - v-|_M^2, G^T v >= lower``, normal
matrix ``M + G diag(l / w) G^T`` over the 98 translational degrees of freedom of a 7x7 scene,
in reverse Cuthill-McKee order) each factor costs about 22k multiply-adds (17 us), a median of
13 iterations at about 30 us each: 652 us against this kernel's 585 us (geometric means, same
run), and its factors and solves alone already cost about 290 us.

Arguments travel in tuples: a CSC matrix as ``(indptr, indices, data)``, the ordered problem
as :class:`OrderedLcp`, the problem as posed as :class:`Posed`, the options as
:class:`Options` and :class:`Prox`, the kept factors as :class:`FactorCache`. Unpacking them
is free where reference counting is off (``WITHOUT_REFCOUNTS``: every function of the policy
iteration loop), which cut the kernel's time on the fork's 5x5 dumps by a fifth and on its
7x7 scenes by 7% (hot, same solves).

Compilation: ``cache=True`` (machine code cached next to this file); ``warm_up()`` compiles or
loads it once per process, and pi-robust calls it in its set-up, outside the timed solve.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from qpbench.problem.metrics import TINY
from qpbench.solvers import accuracy
from qpbench.solvers.counting_sort import stable_order
from qpbench.solvers.pi_robust import COUPLED, DRIFT_RATIO

# floating-point freedoms of the factor and its solves: sums may be reordered (so that their
# inner products vectorise) and fused; NaN and infinity keep their meaning, so a failing pivot
# is still caught
REDUCTIONS = {"reassoc", "contract"}
# the functions that policy iteration runs in every step are compiled without numba's
# reference counting (its ``_nrt`` option): numba counts references to every array a function
# binds, slices or passes on, an atomic increment and decrement each, which was a fifth of a
# 5x5 dump's solve. Such a function cannot allocate (numba refuses to compile it) and must
# not return an array (no count would own it; a test checks every one's return type)
WITHOUT_REFCOUNTS = {"_nrt": False}
# the contacts are put in reverse Cuthill-McKee order when the envelope in the posed order
# costs more than WIDE_ENVELOPE_WORK multiply-adds to factor (below that, about 5 us, the
# ordering costs more than it saves) and either there are more than ``order_above`` contacts
# or it costs more than WIDE_ENVELOPE of a dense factorization's n^3 / 6 (Anitescu's
# relaxation puts the columns n + mu t and n - mu t of one contact n apart)
WIDE_ENVELOPE = 0.5
WIDE_ENVELOPE_WORK = 1e4
# a block factored with at least DEPENDENT_CONTACTS dependent contacts (pivots
# L_ii^2 < DEPENDENT_PIVOT rho D_i: contact i nearly a combination of the free contacts before
# it) is nearly singular at this rho, and block pivoting's iterate on it swings; when most of
# the exchange's contacts are negative free ones, the active-set method goes on from there (or,
# without it, block pivoting fixes only those, freeing no fixed contact into that block in this
# step; see _inner_lcp)
DEPENDENT_PIVOT = 100.0
DEPENDENT_CONTACTS = 4
# the active-set method's steps that only fix contacts, at most UPDATE_FIXED of them, delete
# their rows from the factor solved last instead of refactoring (_block_solve_fixing), on
# problems whose D_i > 0 span at most UPDATE_SPREAD (wider, on extreme mass ratios, the
# updates' rounding changed the method's pivots and cost solves; see _primal_active_set)
UPDATE_FIXED = 4
UPDATE_SPREAD = 1e6
# status codes of a prox run
PROX_CONVERGED, PROX_BUDGET, PROX_STALLED = 0, 1, 2
# paths of a whole solve
PATH_START, PATH_POLICY_ITERATION, PATH_INTERIOR, PATH_NONE, PATH_DECLINED, PATH_SWEEPS = \
    0, 1, 2, 3, 4, 5
PATH_NAMES = ("start", "policy iteration", "interior point + policy iteration",
              "interior point did not converge", "declined: envelope too wide",
              "start sweeps")

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
    """The kernel's options, packed in the order PACKED, from pi-robust's accuracy-table row
    (other keys ignored)."""
    return np.array([float(settings[name]) for name in PACKED])


@njit(cache=True)
def unpacked(values: np.ndarray) -> Options:
    """:class:`Options` from the array :func:`options_of` packs (positions as in PACKED)."""
    prox = Prox(values[2], values[3], values[4], int(values[5]), int(values[6]),
                values[7] != 0.0, int(values[8]))
    return Options(values[0], values[1], prox, int(values[9]), int(values[10]), values[11],
                   int(values[12]), int(values[13]))


class Posed(NamedTuple):
    """The problem as posed, on which every residual is measured: ``csc`` its Q,
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
    """(work, policy, first, polished): the :class:`Work` of a solve of n contacts whose whole
    envelope has ``capacity`` entries (its :class:`FactorCache`: two empty slots), and n-entry
    arrays for the start's policy, the first prox run's l and the polished l. Three allocations
    (reals, integers, flags) sliced into all of them: an allocation for each array (21 then)
    cost about 2% of a 5x5 dump's solve (hot). An l returned as it is (the posed order kept)
    is a view of ``reals`` and keeps it alive: two envelopes and 15 n numbers."""
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


@njit(cache=True)
def natural_residual(csc: Csc, b: np.ndarray, diag: np.ndarray, scale: float,
                     impulses: np.ndarray) -> float:
    """||min(D l, Q l + b)||_inf / scale with Q l summed column by column over Q's CSC arrays
    ``(indptr, indices, data)`` in the order of scipy's CSC product, so that the value is
    qpbench's ``metrics.residual`` (even where rounding dominates, on extreme mass ratios)."""
    return _natural_residual_into(csc, b, diag, scale, impulses, np.empty(impulses.size))


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
    """A bound on how far any other summation order of ``Q l + b`` (another product, fused
    multiply-adds) can move the residual: ``2 gamma max_i (sum_k |Q_ik l_k| + |b_i|) / scale``
    with ``gamma = (m + 2) u / (1 - (m + 2) u)``, m the most entries in a column, u = 2^-53
    (Higham, "Accuracy and Stability of Numerical Algorithms", 2002, section 3.1). D l, min,
    abs, max and the division round identically in every implementation."""
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
    """A bound at least :func:`residual_rounding_bound`'s, without a product:
    ``2 gamma (m max |Q_ik| max |l_k| + max |b_i|) / scale`` (each of the at most m terms of a
    row of the symmetric Q is at most max |Q_ik| max |l_k|). Three maxima, where the product
    of |Q| and |l| scatters into every row: about 2% of a 5x5 dump's solve."""
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
    """``product = Q x`` over Q's CSC arrays (the columns of zero entries of x skipped)."""
    indptr, indices, data = csc
    product[:] = 0.0
    for column in range(x.size):
        value = x[column]
        if value != 0.0:
            for k in range(indptr[column], indptr[column + 1]):
                product[indices[k]] += data[k] * value


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _subtract_products(total: float, values: np.ndarray, left: int, right: int,
                       length: int) -> float:
    """``total - sum_k values[left + k] values[right + k]`` over k < length, subtracted in
    order; offsets taken unsigned (no negative-index wraparound), so that the loop vectorises.
    The two inner products of :func:`_factor_rows`'s entry pairs (measured hot: as fast as the
    loop written out in each, same solves)."""
    left_start, right_start = np.uint64(left), np.uint64(right)
    for k in range(np.uint64(length)):
        total -= values[left_start + k] * values[right_start + k]
    return total


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _factor_rows(upper: Upper, index: np.ndarray, position: np.ndarray, row_scale: np.ndarray,
                 shift_scale: float, shift: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                 first_row: int, x: np.ndarray) -> None:
    """The envelope Cholesky factor ``L L^T = S Q_II S + shift_scale diag(shift_I)`` (Jennings,
    "A compact storage scheme for the solution of symmetric linear simultaneous equations",
    Comput. J. 9(3), 1966) from row ``first_row`` on, the rows before it being L's already
    (row i of L depends on the rows up to i of the matrix only), and, unless x is empty, the
    forward substitution ``L y = x`` in place. S = diag(row_scale), S = I when row_scale is
    empty; entries (r, c) scale as (Q_rc s_r) s_c. ``upper`` is :func:`_upper` of Q, I =
    ``index`` in rising order, ``position[r]`` r's place in I or -1.

    Row i of L has the envelope of row i of the matrix, stored in
    ``values[offsets[i]:offsets[i + 1]]``: its columns first(i) .. i, first(i) the first place
    in I among the rows of column ``index[i]`` of the upper triangle, the diagonal last, kept
    as its reciprocal 1 / L_ii (each entry ``L_ij = (A_ij - sum_k L_ik L_jk) / L_jj`` is then a
    multiplication, whose latency is a third of a division's). Each row's pattern, entries,
    factor and substitution are formed in turn while it is in cache: one pass over the rows
    where four were made before (measured hot, same solves: 5x5 dumps 1-2% faster, box
    packings 8%, 7x7 scenes and grid captures within 0.3%). A row's entries are formed two at
    a time, the newest entries of the row kept out of the long inner products, which so run
    ahead while the entry before them is formed (measured hot, same solves, against one entry
    at a time with each inner product over all its columns: the 7x7 scenes and grid captures
    2.4% faster, the 5x5 dumps 1.3%, box packings 0.9%; one 7x7 block alone, 16%). The
    diagonal's sum of squares ``sum_j L_ij^2`` and the row's forward substitution sum
    ``sum_j L_ij y_j`` are taken as the entries are formed, not in two more loops over the row
    (measured as the benchmark times, each solve after posing: the fork's 7x7 scenes 1.5-3%
    faster, its 5x5 dumps the same; the sums round otherwise, so the generated mass-ratio
    problems, whose pivoting follows the rounding, took other solves: 60 seeds of mass
    ratio 5, 1695 -> 1545 solves, of mass ratio 10, 6455 -> 6591 with one more handed to the
    Python path; grids the same solves). Raises LinAlgError when a pivot is not positive."""
    starts, ends, rows, data = upper
    scaled = row_scale.size > 0
    forward = x.size > 0
    if forward:
        _forward_rows(values, offsets, 0, first_row, x)
    if first_row == 0:
        offsets[0] = 0
    for i in range(first_row, index.size):
        column = index[i]
        row_first = np.uint64(i)
        for k in range(starts[column], ends[column]):
            # unsigned: a row outside I (-1) compares above every place, without a branch
            row_first = min(row_first, np.uint64(position[rows[k]]))
        first_i = np.int64(row_first)
        base_i = offsets[i]
        end_i = base_i + i - first_i + 1
        offsets[i + 1] = end_i
        for k in range(np.uint64(base_i), np.uint64(end_i)):
            values[k] = 0.0
        if scaled:  # (two loops: a test inside the loop cost about 1%)
            for k in range(starts[column], ends[column]):
                place = position[rows[k]]
                if place >= 0:
                    values[base_i + place - first_i] = \
                        (data[k] * row_scale[rows[k]]) * row_scale[column]
        else:
            for k in range(starts[column], ends[column]):
                place = position[rows[k]]
                if place >= 0:
                    values[base_i + place - first_i] = data[k]
        values[end_i - 1] += shift_scale * shift[column]
        # the entries two at a time (j, j + 1), each inner product over the columns before
        # j - 1 first and the row's newest entries (L_i,j-1, then L_ij) subtracted last, so that
        # the long inner products never wait for the entry computed just before them
        squares = 0.0
        substituted = x[i] if forward else 0.0
        j = first_i
        latest = 0.0  # L_i,j-1
        while j < i:
            base_j = offsets[j]
            end_j = offsets[j + 1]
            first_j = j + 1 - (end_j - base_j)
            lo = max(first_i, first_j)
            total = values[base_i + j - first_i]
            if lo < j:  # (then row j holds column j - 1, at end_j - 2)
                total = _subtract_products(total, values, base_i + lo - first_i,
                                           base_j + lo - first_j, j - 1 - lo)
                total -= latest * values[end_j - 2]
            if j + 1 < i:
                base_next = offsets[j + 1]
                end_next = offsets[j + 2]
                first_next = j + 2 - (end_next - base_next)
                lo_next = max(first_i, first_next)
                total_next = values[base_i + j + 1 - first_i]
                if lo_next < j:  # (then row j + 1 holds columns j - 1 and j)
                    total_next = _subtract_products(total_next, values,
                                                    base_i + lo_next - first_i,
                                                    base_next + lo_next - first_next,
                                                    j - 1 - lo_next)
                    total_next -= latest * values[end_next - 3]
                entry = total * values[end_j - 1]
                values[base_i + j - first_i] = entry
                if first_next <= j:
                    total_next -= entry * values[end_next - 2]
                latest = total_next * values[end_next - 1]
                values[base_i + j + 1 - first_i] = latest
                squares += entry * entry + latest * latest
                if forward:
                    substituted -= entry * x[j] + latest * x[j + 1]
                j += 2
            else:
                latest = total * values[end_j - 1]
                values[base_i + j - first_i] = latest
                squares += latest * latest
                if forward:
                    substituted -= latest * x[j]
                j += 1
        total = values[end_i - 1] - squares
        if not total > 0.0:
            raise np.linalg.LinAlgError("block is not positive definite")
        values[end_i - 1] = 1.0 / np.sqrt(total)
        if forward:  # row i of the forward substitution (its sum taken above)
            x[i] = substituted * values[end_i - 1]


@njit(cache=True, fastmath=REDUCTIONS)
def _envelope_solve(values: np.ndarray, offsets: np.ndarray, size: int,
                    rhs: np.ndarray) -> np.ndarray:
    """x with L L^T x = rhs for an envelope factor L stored as in :func:`_factor_rows` (its
    diagonal as reciprocals)."""
    x = rhs.copy()
    _envelope_solve_in_place(values, offsets, size, x)
    return x


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _envelope_solve_in_place(values: np.ndarray, offsets: np.ndarray, size: int,
                             x: np.ndarray) -> None:
    """:func:`_envelope_solve` overwriting its right side ``x`` with the solution."""
    _forward_rows(values, offsets, 0, size, x)
    _backward_substitution(values, offsets, size, x)


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _forward_rows(values: np.ndarray, offsets: np.ndarray, start: int, stop: int,
                  x: np.ndarray) -> None:
    """Rows start .. stop - 1 of the forward substitution ``L y = x`` in place (the entries of
    x before ``start`` are y's already): ``x_i <- (x_i - sum_k L_ik x_k) / L_ii``."""
    for i in range(start, stop):
        base = offsets[i]
        end = offsets[i + 1]
        first = i + 1 - (end - base)
        row, leading = np.uint64(base), np.uint64(first)  # unsigned: the loop vectorises
        total = x[i]
        for k in range(np.uint64(i - first)):
            total -= values[row + k] * x[leading + k]
        x[i] = total * values[end - 1]


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _backward_substitution(values: np.ndarray, offsets: np.ndarray, size: int,
                           x: np.ndarray) -> None:
    """``L^T x = y`` in place (y in ``x``), row by row of L from the last: ``x_i <- x_i / L_ii``,
    then ``x_k -= L_ik x_i`` for the columns k of row i."""
    for i in range(size - 1, -1, -1):
        base = offsets[i]
        end = offsets[i + 1]
        first = i + 1 - (end - base)
        x[i] *= values[end - 1]
        value = x[i]
        row, leading = np.uint64(base), np.uint64(first)
        for k in range(np.uint64(i - first)):
            x[leading + k] -= values[row + k] * value


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _envelope_widths(A: Csc, offsets: np.ndarray) -> None:
    """Row offsets of the lower envelope of the whole symmetric Q: row c starts at the
    smallest row index of column c."""
    indptr, indices, _ = A
    offsets[0] = 0
    for column in range(indptr.size - 1):
        row_first = column
        for k in range(indptr[column], indptr[column + 1]):
            row_first = min(row_first, indices[k])
        offsets[column + 1] = offsets[column] + column - row_first + 1


@njit(cache=True)
def _upper(A: Csc) -> Upper:
    """The upper triangle of the symmetric Q (its entries Q_rc with r <= c), copied: column c
    holds row c of the lower triangle, all that an envelope row reads. Once per solve,
    O(nnz(Q)); it halves what every block's pattern and fill visit."""
    n = A[0].size - 1
    starts, rows, values = (np.empty(n + 1, dtype=np.int64), np.empty(A[1].size, dtype=np.int64),
                            np.empty(A[1].size))
    _upper_into(A, (starts, rows, values))
    return starts, starts[1:], rows, values


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _upper_into(A: Csc, upper: Csc) -> None:
    """:func:`_upper`'s copy into ``upper``'s arrays (n + 1 starts, as many rows and values as
    Q has entries; those past the upper triangle's are left as they are)."""
    indptr, indices, data = A
    starts, rows, values = upper
    n = indptr.size - 1
    starts[0] = 0
    end = 0
    for column in range(n):
        for k in range(indptr[column], indptr[column + 1]):
            # written, then kept only when in the upper triangle (end <= k): no branch on it
            rows[end], values[end] = indices[k], data[k]
            end += indices[k] <= column
        starts[column + 1] = end


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _leading_upper(A: Csc, ends: np.ndarray) -> bool:
    """Whether every column's rows rise (SciPy's sorted indices), and then ``ends[c]``: one past
    column c's last entry with row <= c, so that its leading entries are the upper triangle's
    column and Q's own arrays serve as :func:`_upper` without a copy (about 1% of a 5x5 dump's
    solve)."""
    indptr, indices, _ = A
    for column in range(indptr.size - 1):
        end = indptr[column]
        previous = -1
        for k in range(indptr[column], indptr[column + 1]):
            if indices[k] <= previous:
                return False
            previous = indices[k]
            end += indices[k] <= column
        ends[column] = end
    return True


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _block_solve(upper: Upper, safe_diag: np.ndarray, policy: np.ndarray, index: np.ndarray,
                 rho: float, rhs: np.ndarray, cache: FactorCache) -> None:
    """Overwrites ``rhs`` with x_F, (Q_FF + rho D_F) x_F = rhs (F = ``index``, the policy's
    free contacts in rising order; ``upper``: :func:`_upper` of Q), from the cache's factor of
    (policy, rho) when it holds one, else by factoring ``L L^T = Q_FF + rho D_F`` into the
    least recently used slot.

    A new factor starts from the kept factor (same rho) whose policy agrees with this one on
    the longest run of leading contacts: rows of L for the free contacts in that run are the
    same (row i of a Cholesky factor depends on the leading rows of the matrix only), so they
    are copied and only the rows after them are factored."""
    n = safe_diag.size
    size = index.size
    factors, offsets, policies, rhos, ages, counters, position, dependents = cache
    counters[1] += 1
    source, agreeing = -1, 0
    for slot in range(rhos.size):
        if rhos[slot] != rho:
            continue
        k = 0
        while k < n and policies[slot, k] == policy[k]:
            k += 1
        if k == n:
            ages[slot] = counters[1]
            counters[2] = dependents[slot]
            _envelope_solve_in_place(factors[slot], offsets[slot], size, rhs)
            return
        if k > agreeing:
            source, agreeing = slot, k
    slot = int(np.argmin(ages))
    rhos[slot] = -1.0  # invalid until the factorization succeeds
    kept = 0
    if source >= 0:
        for k in range(agreeing):
            kept += policy[k]
        if source != slot and kept > 0:
            for k in range(kept + 1):  # (a slice assignment would allocate)
                offsets[slot, k] = offsets[source, k]
            for k in range(offsets[source, kept]):
                factors[slot, k] = factors[source, k]
    for a in range(size):
        position[index[a]] = a
    values, slot_offsets = factors[slot], offsets[slot]
    # an empty scale (S = I) as a view: this function may not allocate
    _factor_rows(upper, index, position, safe_diag[:0], rho, safe_diag, values, slot_offsets,
                 kept, rhs)
    for a in range(size):
        position[index[a]] = -1
    counters[0] += 1
    _keep(cache, slot, policy, rho, index, safe_diag)
    _backward_substitution(values, slot_offsets, size, rhs)


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _delete_contact(values: np.ndarray, offsets: np.ndarray, size: int, place: int,
                    cosines: np.ndarray, sines: np.ndarray, x: np.ndarray) -> None:
    """In place, the envelope factor (stored as in :func:`_factor_rows`) of a block without its
    row and column ``place``, from the factor L of the block (``size`` rows) in ``values``
    and ``offsets``. With the block's rows split at the deleted one,
    L = [L11; l21^T l22; L31 l32 L33], the new factor is [L11; L31 L33'] where
    ``L33' L33'^T = L33 L33^T + l32 l32^T``: a rank-one update, made by plane rotations row by
    row (Gill, Golub, Murray and Saunders, "Methods for modifying matrix factorizations",
    Math. Comp. 28, 1974). Row i after the deleted one keeps its columns before it, then, with
    w = L_i,place, each later column c turns ``(L_ic, w) <- (cos_c L_ic + sin_c w,
    cos_c w - sin_c L_ic)`` and the diagonal becomes ``r = sqrt(L_ii^2 + w^2)``, whose
    ``cos = L_ii / r``, ``sin = w / r`` turn that column in the rows below. A row's envelope
    keeps its first column (so it may hold a few zeros a new factor would not store). Rows
    only move up, and each row is read before it is overwritten. Unless ``x`` is empty, the
    forward substitution ``L' y = x`` in place, each new row's as it is formed."""
    if x.size:
        _forward_rows(values, offsets, 0, place, x)
    write = offsets[place]
    for i in range(place + 1, size):
        base = offsets[i]
        end = offsets[i + 1]
        first = i + 1 - (end - base)
        w = 0.0
        turned = first
        if first <= place:
            for c in range(first, place):
                values[write] = values[base + c - first]
                write += 1
            w = values[base + place - first]
            turned = place + 1
        for c in range(turned, i):  # column c of L is column c - 1 of the new factor
            value = values[base + c - first]
            values[write] = cosines[c - 1] * value + sines[c - 1] * w
            w = cosines[c - 1] * w - sines[c - 1] * value
            write += 1
        diagonal = 1.0 / values[end - 1]
        r = np.sqrt(diagonal * diagonal + w * w)
        cosines[i - 1] = diagonal / r
        sines[i - 1] = w / r
        values[write] = 1.0 / r
        write += 1
        offsets[i] = write  # (row i's start, read above; row i + 1's is read next)
        if x.size:  # the new row i - 1 of the forward substitution
            _forward_rows(values, offsets, i - 1, i, x)


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _keep(cache: FactorCache, slot: int, policy: np.ndarray, rho: float, index: np.ndarray,
          safe_diag: np.ndarray) -> None:
    """Marks ``slot``, which now holds the factor of the block of free contacts ``index``, as
    the factor of (policy, rho), used now, with its dependent contacts
    (``L_aa^2 < DEPENDENT_PIVOT rho D_a``, L_aa kept as its reciprocal) counted into the slot
    and into ``counters[2]``."""
    factors, offsets, policies, rhos, ages, counters, _, dependents = cache
    values, slot_offsets = factors[slot], offsets[slot]
    dependent = 0
    for a in range(index.size):
        reciprocal = values[slot_offsets[a + 1] - 1]
        dependent += DEPENDENT_PIVOT * rho * safe_diag[index[a]] * reciprocal * reciprocal > 1.0
    dependents[slot] = counters[2] = dependent
    for k in range(policy.size):
        policies[slot, k] = policy[k]
    rhos[slot] = rho
    ages[slot] = counters[1]


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _block_solve_fixing(safe_diag: np.ndarray, policy: np.ndarray, index: np.ndarray,
                        rho: float, rhs: np.ndarray, work: Work, places: np.ndarray) -> None:
    """:func:`_block_solve` for a policy that is the one solved last (its factor the cache's
    most recently used) with the contacts at ``places`` of its block (rising) fixed: their
    rows are deleted from that factor in its own slot (:func:`_delete_contact`, from the last
    up, so that the places before stay valid; the other slot keeps the factor before), the
    forward substitution made by the last deletion as it forms the rows (measured as the
    benchmark times, same solves: the fork's 7x7 scenes about 1% faster than deleting into the
    other slot and substituting after)."""
    factors, offsets, _, rhos, ages, counters, _, _ = work.cache
    size = index.size
    counters[1] += 1
    slot = int(np.argmax(ages))
    rhos[slot] = -1.0  # invalid until it holds the new factor
    for d in range(places.size - 1, -1, -1):
        _delete_contact(factors[slot], offsets[slot], size + d + 1, places[d], work.cosines,
                        work.sines, rhs if d == 0 else rhs[:0])
    _keep(work.cache, slot, policy, rho, index, safe_diag)
    _backward_substitution(factors[slot], offsets[slot], size, rhs)


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _policy_solve(lcp: OrderedLcp, policy: np.ndarray, rho: float, q: np.ndarray,
                  work: Work, fixed_places: np.ndarray) -> int:
    """``work.x``: x_F with ``(Q_FF + rho D_F) x_F = -q_F`` on the policy's free contacts F,
    zero elsewhere (by :func:`_block_solve`, or by :func:`_block_solve_fixing` when
    ``fixed_places`` lists the places, in the block solved last, of the contacts this policy
    fixes of it); returns |F|."""
    x, rhs, free = work.x, work.rhs, work.free
    size = 0
    for i in range(q.size):  # written, then kept only when free: no branch on the policy
        x[i] = 0.0
        free[size] = i
        rhs[size] = -q[i]
        size += policy[i]
    if fixed_places.size:
        _block_solve_fixing(lcp.safe_diag, policy, free[:size], rho, rhs[:size], work,
                            fixed_places)
    elif size:
        _block_solve(lcp.upper, lcp.safe_diag, policy, free[:size], rho, rhs[:size],
                     work.cache)
    for a in range(size):
        x[free[a]] = rhs[a]
    return size


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _fixed_slacks_negative(A: Csc, policy: np.ndarray, x: np.ndarray, q: np.ndarray,
                           tol_w: float, free_count: int, infeasible: np.ndarray,
                           product: np.ndarray) -> None:
    """``infeasible[i]`` for every fixed contact i (not ``policy[i]``): ``(Q x + q)_i < -tol_w``
    for an x that is zero on the fixed contacts (so rho D x adds nothing there). Formed by
    whichever visits fewer columns of Q: scattering the free columns into ``product``
    (x is zero elsewhere), or gathering column i (Q is symmetric) for each fixed i."""
    indptr, indices, data = A
    n = q.size
    if 2 * free_count <= n:
        matvec_into(A, x, product)
        for i in range(n):
            if not policy[i]:
                infeasible[i] = product[i] + q[i] < -tol_w
        return
    for i in range(n):
        if not policy[i]:
            total = q[i]
            for k in range(indptr[i], indptr[i + 1]):
                total += data[k] * x[indices[k]]
            infeasible[i] = total < -tol_w


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _inner_lcp(lcp: OrderedLcp, policy: np.ndarray, rho: float, q: np.ndarray,
               tol_l: np.ndarray, tol_w: float, prox: Prox, budget: int, work: Work):
    """Block principal pivoting on LCP(Q + rho D, q), within ``budget`` linear solves:
    (linear solves, solved), with x in ``work.x`` and the final policy in ``policy`` (changed
    in place). Contact i is infeasible when it is free with ``x_i < -tol_l[i]`` or fixed with
    ``y_i = (Q x + rho D x + q)_i < -tol_w``. Once ``prox.backup_steps`` exchanges in a row have
    not cut their number, :func:`_primal_active_set` goes on from the best exchange's x
    (``prox.active_set``), or it stops unsolved.

    Nearly singular blocks: when the block just solved has ``DEPENDENT_CONTACTS`` dependent
    contacts or more and most of the infeasible contacts are negative free ones, block
    pivoting's iterate swings (it fixed 42 contacts, then freed 36, on a 7x7 scene), so the
    active-set method goes on from the best exchange's x at once (``prox.active_set``); without
    it, only the negative free contacts are exchanged (fixed first). Measured against fixing
    first, as the benchmark times it (each solve after posing, fastest of 20, three rounds
    with the kernels in turn): the fork's 7x7 scenes 32.12 -> 30.44 solves a problem and
    9.2% faster (its block pivoting took 3.2 solves before the active-set method, each a
    factor from the first rows); its 5x5 dumps 7.84 -> 7.98 solves and 2.0% slower; the grid
    captures 5 -> 6.5 solves; box packings the same; generated problems: 126 of the hard
    families 2134 -> 2158 solves (the same four handed to the Python path), 40 seeds of mass
    ratio 10 4229 -> 4220, of mass ratio 5 1084 -> 1070, of grid 10 790 -> 849 (22 worse, 17
    better). Entering it after the first solve whatever the block (7x7 30.56 solves, 8.0%
    faster; 5x5 7.92, 3.4% slower; grid captures 6.5; grid 10 853) or whenever the block has
    dependent contacts (30.58, 8.1% faster; 8.06, 2.7% slower; 6.5) did no better.

    Fixing first, against exchanging all infeasible contacts (measured hot, when block pivoting
    went on from there): the fork's 7x7 scenes 35.28 -> 32.96 solves a problem and 5.5-7%
    faster, its 5x5 dumps 8.12 -> 7.84 solves, and 54 generated hard-family problems
    878 -> 868 solves. Without the test that most of the exchange is negative, the generated
    problems took 900 solves; with one dependent contact enough, the 7x7 scenes saved 7.5-8%
    but the 5x5 dumps lost 2-3%."""
    A = lcp.A
    backup_steps, active_set = prox.backup_steps, prox.active_set
    x, infeasible = work.x, work.infeasible
    n = q.size
    best = n + 1
    backup = backup_steps
    solves = 0
    x[:] = 0.0
    while solves < budget:
        free_count = _policy_solve(lcp, policy, rho, q, work, work.listed[:0])
        solves += 1
        _fixed_slacks_negative(A, policy, x, q, tol_w, free_count, infeasible, work.product)
        count = 0
        negative = 0
        for i in range(n):
            if policy[i]:
                infeasible[i] = x[i] < -tol_l[i]
                negative += infeasible[i]
            count += infeasible[i]
        if count == 0:
            return solves, True
        singular = work.cache.counters[2] >= DEPENDENT_CONTACTS and \
            count < 2 * negative < 2 * count
        improved = count < best
        if improved:
            best, backup = count, backup_steps
            for i in range(n):
                work.best_x[i] = x[i]
        if not (active_set and singular) and (improved or backup > 0):
            if not improved:
                backup -= 1
            if singular:
                for i in range(n):  # fix first: only the negative free contacts are exchanged
                    infeasible[i] &= policy[i]
            for i in range(n):
                policy[i] ^= infeasible[i]
        elif active_set:
            feasible = work.feasible
            for i in range(n):
                feasible[i] = max(work.best_x[i], 0.0)
                policy[i] = feasible[i] > 0.0
            used, solved = _primal_active_set(lcp, policy, rho, q, tol_l, tol_w,
                                              budget - solves, work)
            return solves + used, solved
        else:
            break
    return solves, False


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _objective(A: Csc, rho: float, safe_diag: np.ndarray, q: np.ndarray, x: np.ndarray,
               product: np.ndarray) -> float:
    """``x^T (Q + rho D) x / 2 + q^T x``, with Q x formed in ``product``."""
    matvec_into(A, x, product)
    total = 0.0
    for i in range(x.size):
        total += x[i] * (0.5 * (product[i] + rho * safe_diag[i] * x[i]) + q[i])
    return total


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _clipped_curvature(A: Csc, rho: float, safe_diag: np.ndarray, solution: np.ndarray,
                       listed: np.ndarray) -> float:
    """``d^T (Q + rho D) d / 2`` for ``d = max(-solution, 0)``, summed over the columns
    ``listed``: those where d > 0 (a few, the free contacts a policy solve sends below zero)."""
    indptr, indices, data = A
    total = 0.0
    for column in listed:
        clipped = -solution[column]
        inner = rho * safe_diag[column] * clipped
        for k in range(indptr[column], indptr[column + 1]):
            inner += data[k] * max(-solution[indices[k]], 0.0)
        total += clipped * inner
    return 0.5 * total


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _diagonal_spread(diag: np.ndarray) -> float:
    """``max D_i / min D_i`` over the contacts with D_i > 0 (1 when there are none)."""
    largest, smallest = 0.0, np.inf
    for value in diag:
        if value > 0.0:
            largest, smallest = max(largest, value), min(smallest, value)
    return largest / smallest if largest > 0.0 else 1.0


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _free_violators(A: Csc, safe_diag: np.ndarray, policy: np.ndarray, product: np.ndarray,
                    q: np.ndarray, tol_w: float, all_of_them: bool, listed: np.ndarray,
                    scaled: np.ndarray) -> bool:
    """Frees fixed contacts i (``policy[i]`` set) that violate ``(Q x + q)_i < -tol_w``
    (``product`` = Q x, x zero on them), in order of the most negative scaled slack
    ``(Q x + q)_i / sqrt(D_i)``: only the first unless ``all_of_them``, else each one that is
    not coupled to one freed before it, ``Q_ij > COUPLED sqrt(D_i D_j)`` (freeing i then
    raises j's slack by ``Q_ji x_i``: its violation is j's share of what i will carry).
    Whether any contact violated. ``listed`` and ``scaled`` (n entries, overwritten) hold the
    violators, sorted, and their scaled slacks (0 once coupled to a freed one; the other
    entries of ``scaled`` are scratch)."""
    indptr, indices, data = A
    count = 0
    for i in range(q.size):  # (written, then kept only when violating: no branch)
        listed[count] = i
        count += (product[i] + q[i] < -tol_w) & ~policy[i]
    for c in range(count):
        violator = listed[c]
        scaled[violator] = (product[violator] + q[violator]) / np.sqrt(safe_diag[violator])
    for c in range(1, count):  # most negative first (an insertion sort: a few violators)
        violator, place = listed[c], c
        while place > 0 and scaled[listed[place - 1]] > scaled[violator]:
            listed[place] = listed[place - 1]
            place -= 1
        listed[place] = violator
    if count and not all_of_them:
        policy[listed[0]] = True
        return True
    for c in range(count):
        chosen = listed[c]
        if scaled[chosen] < 0.0:  # (0: coupled to one freed before it)
            policy[chosen] = True
            for k in range(indptr[chosen], indptr[chosen + 1]):
                coupled = indices[k]
                if scaled[coupled] < 0.0 and \
                        data[k] > COUPLED * np.sqrt(safe_diag[chosen] * safe_diag[coupled]):
                    scaled[coupled] = 0.0
    return count > 0


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _primal_active_set(lcp: OrderedLcp, policy: np.ndarray, rho: float, q: np.ndarray,
                       tol_l: np.ndarray, tol_w: float, budget: int, work: Work):
    """LCP(H, q), H = Q + rho D positive definite, as the QP ``min f(x) = x^T H x / 2 + q^T x``,
    ``x >= 0``, by a primal active-set method (Lawson and Hanson, "Solving Least Squares
    Problems", 1974, chapter 23; Nocedal and Wright, "Numerical Optimization", 2006, section
    16.5) within ``budget`` linear solves: (linear solves, solved), x in ``work.x``. From the
    feasible point ``work.feasible`` with free set ``policy`` (both changed in place), each
    step solves ``H_FF s_F = -q_F``, then:

    - some free ``s_i < -tol_l[i]``: x becomes ``max(s, 0)`` with those contacts fixed when
      that lowers f (several at once); else x moves towards s until the first of them
      reaches zero, and the free contacts at zero with ``s_i < 0`` are fixed;
    - else x = max(s, 0), and the fixed contacts with ``(H x + q)_i < -tol_w`` are freed: all
      of them but those coupled to one freed before them (:func:`_free_violators`) when f has
      fallen since the last time contacts were freed, else the one with the most negative
      ``(H x + q)_i / sqrt(D_i)``; none: x is the solution.

    f never rises and every step that frees contacts starts lower than the one before, or
    frees one contact as Lawson and Hanson do, so unlike block pivoting it cannot cycle.

    Why coupled violators wait: freeing every violator overshoots on the grids, whose blocks
    are nearly singular: the method freed 3-21 contacts at each minimum and then fixed most of
    them back, one or two per solve. Skipping the violators coupled to one freed before them
    (measured hot against freeing all: the fork's 7x7 scenes 32.96 -> 32.12 solves a problem
    and 4-6% faster; its 5x5 dumps, the grid captures and the box packings the same solves;
    126 generated hard-family problems 2319 -> 2287 solves, the same five handed to the
    Python path). Blocking only pairs coupled by any positive Q_ij (nearly perpendicular
    contacts too) gave 32.70 solves and cost the 5x5 dumps solves; the same rule in block
    pivoting's exchanges 30.00 solves but the 5x5 dumps 7% and the grid captures 16% more
    time. Predicting each violator's slack after a Gauss-Seidel step on the ones freed before
    it gave 32.16 solves (30.80 with twice that step), but that step says little: the next
    solve's x_i was of the other sign in 37% of the cases, and a median 2.9 times the step.

    f needs no product with Q where a step fixes contacts: s minimizes f on the free set F and
    every point here is zero off F, so ``f(x) = f(s) + (x - s)^T H (x - s) / 2`` with
    ``f(s) = q^T s / 2``; hence ``f(max(s, 0)) = f(s) + d^T H d / 2`` (d = max(-s, 0), a few
    entries: :func:`_clipped_curvature`) and, on the segment towards s,
    ``f(x + t (s - x)) = f(s) + (1 - t)^2 (f(x) - f(s))``.

    A step's passes run over F alone (``work.free``, as :func:`_policy_solve` leaves it), since
    s and x are zero off it; the contacts where s < 0 are listed in the pass that finds the
    blocking one (measured hot, same solves: where each step made three passes over all
    contacts, the fork's 7x7 scenes took 3.2-3.5% longer, its 5x5 dumps 1-2%).

    The next solve after a step that fixed at most ``UPDATE_FIXED`` contacts deletes their
    rows from the factor just used (:func:`_block_solve_fixing`) when the problem's D_i span
    at most ``UPDATE_SPREAD`` (the module docstring says why and what it saves).

    Why the step stops at the first blocking contact: an exact projected search instead (the
    first local minimizer of f along ``max(x + t (s - x), 0)``, t in [0, 1], segment by
    segment between the contacts' breakpoints, f on each from the face's quadratic
    ``f(s) + e^T H e / 2``, e = p(t) - s, with no product) cut the fork's 7x7 solves from
    32.96 to 30.34 a problem but its time by only 1-2% (each accepted move fixes contacts
    earlier in the order, so each refactor starts earlier), left the 5x5 dumps, grid captures
    and box packings as they were, and took 54 generated hard-family problems from 868 to 986
    solves (mass ratio 5, seed 4: 36 -> 122); its global minimizer on the path was no better."""
    A, safe_diag = lcp.A, lcp.safe_diag
    solution, y, feasible = work.x, work.product, work.feasible
    free, listed = work.free, work.listed
    n = q.size
    value_now = _objective(A, rho, safe_diag, q, feasible, y)
    value_at_last_freeing = np.inf
    solves = 0
    solved = False
    updates = _diagonal_spread(lcp.diag) <= UPDATE_SPREAD
    fixed = 0  # contacts the last step fixed, their places in its block in listed[:fixed]
    while solves < budget:
        # F = free[:size]; the rows of the contacts the last step fixed deleted, or refactored
        size = _policy_solve(lcp, policy, rho, q, work,
                             listed[:fixed if fixed <= UPDATE_FIXED and updates else 0])
        fixed = 0
        solves += 1
        # one pass over F (s and x are zero off it): the first free contact that s sends below
        # zero, f(s), and the free contacts with s_i < 0 listed
        step, blocking = 1.0, -1
        at_minimum = 0.0
        count = 0
        for a in range(size):
            i = free[a]
            at_minimum += q[i] * solution[i]
            if solution[i] < -tol_l[i]:
                reach = feasible[i] / (feasible[i] - solution[i])
                if reach < step:
                    step, blocking = reach, i
            listed[count] = i  # (written, then kept only when s_i < 0: no branch)
            count += solution[i] < 0.0
        if blocking >= 0:
            at_minimum *= 0.5
            value = at_minimum + _clipped_curvature(A, rho, safe_diag, solution,
                                                    listed[:count])
            if value < value_now:
                value_now = value
                for a in range(size):
                    i = free[a]
                    feasible[i] = max(solution[i], 0.0)
                    policy[i] = solution[i] > 0.0
                    listed[fixed] = a  # (written, then kept only when fixed)
                    fixed += not policy[i]
                continue
            feasible[blocking] = 0.0  # (then the step below leaves it at zero: fixed)
            for a in range(size):
                i = free[a]
                feasible[i] = max(feasible[i] + step * (solution[i] - feasible[i]), 0.0)
                if solution[i] < 0.0 and feasible[i] == 0.0:
                    policy[i] = False
                    listed[fixed] = a
                    fixed += 1
            value_now = at_minimum + (1.0 - step) ** 2 * (value_now - at_minimum)
            continue
        for a in range(size):
            i = free[a]
            feasible[i] = max(solution[i], 0.0)
        value_now = _objective(A, rho, safe_diag, q, feasible, y)  # y = Q x
        all_of_them = value_now < value_at_last_freeing
        value_at_last_freeing = value_now
        if not _free_violators(A, safe_diag, policy, y, q, tol_w, all_of_them, listed,
                               work.rhs):
            solved = True
            break
    for i in range(n):
        solution[i] = feasible[i]
    return solves, solved


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _extrapolate_drift(centre: np.ndarray, drift: np.ndarray, previous_drift: np.ndarray,
                       policy: np.ndarray) -> bool:
    """Moves the prox centre z along a settled prox step's drift ``d = x - z_before`` (the
    step kept its policy F) when d is a drift and not a slow contraction: when the ratio
    ``g = d_F . d'_F / d'_F . d'_F`` to the step before's d' is at least ``DRIFT_RATIO``. Then
    ``z_F <- max(z_F + t d_F, 0)`` with t the step to the first free contact that reaches zero,
    ``t = min {z_i / -d_i : i in F, d_i < 0, z_i > 0}`` (that contact set to exactly 0), or
    the geometric series' ``g / (1 - g)`` steps when that is smaller. True when it moved.

    Why: on a settled policy a prox step is ``x = (Q_FF + rho D_F)^-1 (rho D_F z - b_F)``.
    When ``Q_FF l_F = -b_F`` has no solution (the policy is wrong and Q_FF singular, as on the
    fork's grids, where contacts outnumber the degrees of freedom) each step moves l along
    Q_FF's null space by the same ``D_F^-1 r / rho`` (g = 1), r the part of -b_F outside
    Q_FF's range, at a residual (about |r|) that hardly falls, until a free contact reaches
    zero and the policy changes; this takes those steps at once. Without it, rho fell after
    ``stall_steps`` such steps and the policy was pivoted anew at the smaller rho (the fork's
    7x7 scenes: 26 of 50 stalled so, 12% of the solves; with it solves fall from 38.5 to 35.3
    a problem). A step that contracts (g below 1: an ill-conditioned but consistent block,
    as on large mass ratios, g about 0.99 there) is left to the prox steps and rho's fall:
    jumping there cost the mass-ratio-5 problems up to 37% more solves."""
    along, before = 0.0, 0.0
    for i in range(centre.size):
        if policy[i]:
            along += drift[i] * previous_drift[i]
            before += previous_drift[i] * previous_drift[i]
    if not along >= DRIFT_RATIO * before or before == 0.0:
        return False
    step, blocking = along / (before - along) if along < before else np.inf, -1
    for i in range(centre.size):
        if policy[i] and drift[i] < 0.0 and centre[i] > 0.0:
            reach = centre[i] / -drift[i]
            if reach < step:
                step, blocking = reach, i
    if step == np.inf:
        return False
    for i in range(centre.size):
        if policy[i]:
            centre[i] = np.maximum(centre[i] + step * drift[i], 0.0)
    if blocking >= 0:
        centre[blocking] = 0.0
    return True


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _prox_policy_iteration(lcp: OrderedLcp, start: np.ndarray, start_residual: float,
                           policy: np.ndarray, tol: float, rho: float, prox: Prox,
                           budget: int, work: Work, best: np.ndarray):
    """Prox steps ``z <- max(x, 0)``, x solving LCP(Q + rho D, b - rho D z), from the centre
    ``start`` (whose residual the caller has measured: ``start_residual``) and ``policy``
    (changed in place) within ``budget`` solves: (converged, status code, solves, best
    residual), the best l written into the caller's ``best`` (an array other than ``start``)."""
    original, b, safe_diag, scale = lcp.original, lcp.b, lcp.safe_diag, lcp.scale
    centre, q, x, tol_l = work.centre, work.q, work.x, work.tol_l
    drift, previous_drift = work.drift, work.previous_drift
    n = b.size
    for i in range(n):
        tol_l[i] = 0.1 * tol * scale / safe_diag[i]
        centre[i] = start[i]
        best[i] = start[i]
        drift[i] = 0.0  # (no step before the first)
    tol_w = 0.1 * tol * scale
    res = start_residual
    best_res = res
    solves = 0
    stalls = 0
    drifts = 0
    status = PROX_BUDGET
    while solves < budget:
        for i in range(n):
            q[i] = b[i] - rho * safe_diag[i] * centre[i]
        used, solved = _inner_lcp(lcp, policy, rho, q, tol_l, tol_w, prox, budget - solves,
                                  work)
        solves += used
        settled = used == 1 and drifts < prox.drift_steps  # the step kept its policy
        drift, previous_drift = previous_drift, drift  # (swapped, not copied)
        for i in range(n):
            drift[i] = x[i] - centre[i]
            centre[i] = np.maximum(x[i], 0.0)
        previous = res
        res = _original_residual(original, scale, centre, work.product, work.unpermuted)
        if res < best_res or res <= tol:
            for i in range(n):
                best[i] = centre[i]
            best_res = min(res, best_res)
        if res <= tol:
            return True, PROX_CONVERGED, solves, res
        if not solved:
            break
        stalls = stalls + 1 if res > prox.stall_ratio * previous else 0
        if settled and stalls > 0 and _extrapolate_drift(centre, drift, previous_drift, policy):
            drifts += 1
            stalls = 0
            continue
        if stalls >= prox.stall_steps:
            stalls = 0
            if rho * prox.rho_decrease < prox.rho_min:
                status = PROX_STALLED
                break
            rho *= prox.rho_decrease
    return False, status, solves, best_res


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _gauss_seidel(A: Csc, b: np.ndarray, diag: np.ndarray, impulses: np.ndarray,
                  inverse: np.ndarray, sweeps: int) -> None:
    """In place on ``impulses``, ``sweeps`` projected Gauss-Seidel sweeps: for i = 1..n in turn,
    ``l_i <- max(0, l_i - (Q l + b)_i / D_i)`` (contacts with D_i = 0 left alone), with
    ``(Q l)_i`` from column i of the symmetric Q. A few sweeps cost a few products and put
    most contacts on the right side of the active set, so block pivoting from there needs
    fewer factorizations. ``inverse`` (overwritten) holds 1 / D_i, 0 where D_i = 0 (left
    alone): multiplied, not divided."""
    indptr, indices, data = A
    for i in range(impulses.size):
        inverse[i] = 1.0 / diag[i] if diag[i] > 0.0 else 0.0
    for _ in range(sweeps):
        for i in range(impulses.size):
            w = b[i]
            for k in range(indptr[i], indptr[i + 1]):
                w += data[k] * impulses[indices[k]]
            impulses[i] = max(0.0, impulses[i] - w * inverse[i])


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _step_to_boundary(value: np.ndarray, change: np.ndarray) -> float:
    """The largest alpha <= 1 with value + alpha * change >= 0."""
    alpha = 1.0
    for i in range(value.size):
        if change[i] < 0.0:
            candidate = -value[i] / change[i]
            if candidate < alpha:
                alpha = candidate
    return alpha


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _policy_from(lcp: OrderedLcp, impulses: np.ndarray, posed_product: np.ndarray,
                 policy: np.ndarray, strict: bool) -> None:
    """``policy``: the contacts with ``(Q l + b)_i < D_i l_i`` (``<=`` unless ``strict``), l in
    the kernel's order, from the ``Q l`` that its residual formed on the problem as posed
    (``posed_product``, in the posed order): no product of its own."""
    order, b, diag = lcp.original.order, lcp.b, lcp.diag
    for i in range(impulses.size):
        w = (posed_product[order[i]] if order.size else posed_product[i]) + b[i]
        policy[i] = w < diag[i] * impulses[i] if strict else w <= diag[i] * impulses[i]


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _polish(lcp: OrderedLcp, impulses: np.ndarray, residual: float, tol: float, rho: float,
            work: Work, polished: np.ndarray, policy: np.ndarray):
    """(moved, the answer's residual, solves): a converged l whose ``residual`` is above tol / 10
    gets one more prox step on its own policy ``{i : (Q l + b)_i < D_i l_i}`` (usually the kept
    factor: two triangular solves) into ``polished`` (moved: the answer is ``polished``, which is
    l unless the step lowered the residual; else it is l). A prox step ends at residual
    ~ rho |D (l - z)|, about tol when rho = tol; the margin lets the caller certify the answer
    without a second residual pass. ``work.product`` must hold the ``Q l`` of l's residual (as
    :func:`_prox_policy_iteration` leaves it when it converges); ``policy`` is overwritten."""
    if residual <= 0.1 * tol:
        return False, residual, 0
    _policy_from(lcp, impulses, work.product, policy, True)
    one_step = Prox(rho, 1.0, 0.5, 1, 0, False, 0)
    _, _, used, polished_residual = _prox_policy_iteration(
        lcp, impulses, residual, policy, 0.1 * tol, rho, one_step, np.int64(1), work, polished)
    return True, polished_residual, used


@njit(cache=True)
def _finish(lcp: OrderedLcp, start: np.ndarray, start_w: np.ndarray, tol: float, rho: float,
            prox: Prox, finish_budget: int, work: Work):
    """(l, done, solves, l's residual): proximal policy iteration from an interior-point
    iterate, with the policy {i : w_i < D_i l_i}; when it converges, :func:`_polish` on its
    answer."""
    finished = np.empty(start.size)
    done, _, used, finished_residual = _prox_policy_iteration(
        lcp, start, _original_residual(lcp.original, lcp.scale, start, work.product,
                                       work.unpermuted),
        start_w < lcp.diag * start, tol, rho, prox, finish_budget, work, finished)
    if done:
        polished = np.empty(start.size)
        moved, finished_residual, extra = _polish(lcp, finished, finished_residual, tol, rho,
                                                  work, polished,
                                                  np.empty(start.size, dtype=np.bool_))
        used += extra
        if moved:
            finished = polished
    return finished, done, used, finished_residual


@njit(cache=True)
def _solve_ordered(lcp: OrderedLcp, start: np.ndarray, start_residual: float,
                   start_product: np.ndarray, options: Options, normal_first: np.ndarray):
    """(l, converged by qpbench's residual formula, path code, linear solves, interior
    iterations, factorizations, l's residual) of pi-robust on the LCP (Q, b) from ``start``
    (l >= 0, not converged: the caller has measured its residual, ``start_residual``, with the
    ``Q l`` it formed in the posed order, ``start_product``).

    ``lcp`` and ``start`` and the answer are in the kernel's order; every residual is measured
    on ``lcp.original`` (a converged l's is qpbench's, summed as the caller would sum it);
    ``normal_first`` are the row offsets of the whole matrix's lower envelope
    (``_envelope_widths``)."""
    A, upper, original, b, diag, safe_diag, scale = lcp
    tol, rho = options.tol, options.rho
    prox = options.prox
    finish_budget, finish_below = options.finish_budget, options.finish_below
    n = b.size
    work, policy, first, polished = _work(n, normal_first[n])
    product, unpermuted = work.product, work.unpermuted
    counters = work.cache.counters
    _policy_from(lcp, start, start_product, policy, False)
    converged, _, solves, first_res = _prox_policy_iteration(
        lcp, start, start_residual, policy, tol, rho, prox, options.pi_budget, work, first)
    if converged:
        moved, first_res, used = _polish(lcp, first, first_res, tol, rho, work, polished,
                                         policy)
        return polished if moved else first, True, PATH_POLICY_ITERATION, solves + used, 0, \
            counters[0], first_res
    # Mehrotra predictor-corrector on the Jacobi-scaled LCP (as lcp_interior.interior_point)
    root = 1.0 / np.sqrt(safe_diag)
    everything = np.arange(n)
    normal = np.empty(normal_first[n])
    scaled_b = b * root
    scaled_scale = max(np.max(np.abs(scaled_b)), 1e-300)
    impulses = np.full(n, scaled_scale)
    slack = np.maximum(root * _matvec(A, root * impulses) + scaled_b, scaled_scale)
    floor = 1e-14
    best, best_res, best_w = impulses * root, np.inf, slack / root
    progress, stalled = np.inf, 0
    iterations = 0
    for iteration in range(1, options.ipm_iters + 1):
        iterations = iteration - 1
        infeasibility = root * _matvec(A, root * impulses) + scaled_b - slack
        mu = float(impulses @ slack) / n
        original_l = impulses * root
        original_w = (infeasibility + slack) / root
        res = 0.0
        for i in range(n):
            value = abs(min(diag[i] * original_l[i], original_w[i]))
            if value > res:
                res = value
        res /= scale
        if res < best_res:
            best, best_res, best_w = original_l, res, original_w
        if res < 0.9 * progress:
            progress, stalled = res, 0
        else:
            stalled += 1
        if res <= tol:
            exact = _original_residual(original, scale, original_l, product, unpermuted)
            if exact <= tol:
                return original_l, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], exact
        if res <= finish_below:
            finished, done, used, finished_res = _finish(lcp, original_l, original_w, tol, rho,
                                                         prox, finish_budget, work)
            solves += used
            if done:
                return finished, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], finished_res
            finish_below = 0.1 * res
        if stalled >= 5:  # the interior point stalls (rounding, extreme mass ratios): finish
            stalled = 0
            finished, done, used, finished_res = _finish(  # from its best iterate
                lcp, best, best_w, tol, rho, prox, finish_budget, work)
            solves += used
            if done:
                return finished, True, PATH_INTERIOR, solves + iterations, iterations, \
                    counters[0], finished_res
        _factor_rows(upper, everything, everything, root, 1.0,
                     np.maximum(slack / impulses, floor), normal, normal_first, np.int64(0),
                     root[:0])
        counters[0] += 1
        dl = _envelope_solve(normal, normal_first, n, -slack - infeasibility)
        dw = root * _matvec(A, root * dl) + infeasibility
        alpha = min(_step_to_boundary(impulses, dl), _step_to_boundary(slack, dw))
        mu_affine = float((impulses + alpha * dl) @ (slack + alpha * dw)) / n
        sigma = (mu_affine / mu) ** 3 if mu > 0 else 0.0
        rhs = sigma * mu / impulses - slack - infeasibility - dl * dw / impulses
        dl = _envelope_solve(normal, normal_first, n, rhs)
        dw = root * _matvec(A, root * dl) + infeasibility
        alpha = min(1.0, 0.99 * min(_step_to_boundary(impulses, dl),
                                    _step_to_boundary(slack, dw)))
        impulses = np.maximum(impulses + alpha * dl, 1e-300)
        slack = np.maximum(slack + alpha * dw, 1e-300)
        iterations = iteration
        if not (np.all(np.isfinite(impulses)) and np.all(np.isfinite(slack))):
            break
    if first_res < best_res:  # policy iteration's best, whose residual is qpbench's already
        best, best_res = first, first_res
    else:  # the interior point's estimate, measured as qpbench measures it
        best_res = _original_residual(original, scale, best, product, unpermuted)
    return best, best_res <= tol, PATH_NONE, solves + iterations, iterations, counters[0], \
        best_res


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _envelope_work(offsets: np.ndarray) -> float:
    """Multiply-adds of one envelope factorization, ``sum_i w_i^2 / 2`` over the row widths
    ``w_i = offsets[i + 1] - offsets[i]``."""
    work = 0.0
    for i in range(offsets.size - 1):
        work += 0.5 * float(offsets[i + 1] - offsets[i]) ** 2
    return work


@njit(cache=True)
def reverse_cuthill_mckee(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """A reverse Cuthill-McKee order of the graph of a symmetric CSC pattern (Cuthill and
    McKee, "Reducing the bandwidth of sparse symmetric matrices", ACM 1969; George 1971):
    breadth-first from a least-degree node of each component (the seeds in a stable order by
    degree, :func:`~qpbench.solvers.counting_sort.stable_order`), neighbours by rising degree,
    the whole order reversed."""
    degree = indptr[1:] - indptr[:-1]
    order = np.empty(n, dtype=np.int64)
    visited = np.zeros(n, dtype=np.bool_)
    head = tail = 0
    for seed in stable_order(degree):
        if visited[seed]:
            continue
        visited[seed] = True
        order[tail] = seed
        tail += 1
        while head < tail:
            node = order[head]
            head += 1
            begin = tail
            for k in range(indptr[node], indptr[node + 1]):
                neighbour = indices[k]
                if not visited[neighbour]:
                    visited[neighbour] = True
                    order[tail] = neighbour
                    tail += 1
            for i in range(begin + 1, tail):  # insertion sort by degree (few neighbours)
                moving = order[i]
                j = i - 1
                while j >= begin and degree[order[j]] > degree[moving]:
                    order[j + 1] = order[j]
                    j -= 1
                order[j + 1] = moving
    return order[::-1].copy()


@njit(cache=True)
def _permuted(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, order: np.ndarray,
              widths: np.ndarray, upper: Csc):
    """CSC arrays of Q[order][:, order] (row indices within a column left unsorted), and in
    the same pass over its entries the permuted matrix's upper triangle into ``upper``
    (``(starts, rows, values)``, as :func:`_upper_into` copies it) and its envelope's row
    offsets into ``widths`` (as :func:`_envelope_widths`: column c's smallest row is where row
    c starts, and every column holds its diagonal). One pass where three were made (measured
    hot, same solves: box packings 8% faster, the fork's 7x7 scenes 0.6-1.8%)."""
    n = order.size
    starts, rows, values = upper
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = np.arange(n)
    new_indptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        new_indptr[j + 1] = new_indptr[j] + indptr[order[j] + 1] - indptr[order[j]]
    new_indices = np.empty(new_indptr[n], dtype=np.int64)
    new_data = np.empty(new_indptr[n])
    starts[0] = widths[0] = 0
    end = 0
    for j in range(n):
        position = new_indptr[j]
        row_first = j
        for k in range(indptr[order[j]], indptr[order[j] + 1]):
            row = inverse[indices[k]]
            new_indices[position] = row
            new_data[position] = data[k]
            position += 1
            # written, then kept only when in the upper triangle (row <= j): no branch on it
            rows[end], values[end] = row, data[k]
            end += row <= j
            row_first = min(row_first, row)
        starts[j + 1] = end
        widths[j + 1] = widths[j] + j - row_first + 1
    return new_indptr, new_indices, new_data


@njit(cache=True)
def clean_start(warm_start: np.ndarray, n: int) -> np.ndarray:
    """The start: ``max(warm_start, 0)`` when it has n entries, all finite, else zeros (as
    ``qpbench.solvers.lcp.Lcp.start``, in compiled code: no NumPy call overhead)."""
    if warm_start.size != n:
        return np.zeros(n)
    for value in warm_start:
        if not np.isfinite(value):
            return np.zeros(n)
    return np.maximum(warm_start, 0.0)


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _certified(csc: Csc, b: np.ndarray, scale: float, impulses: np.ndarray, residual: float,
               tol: float, magnitude: np.ndarray) -> bool:
    """``residual`` (qpbench's, summed in scipy's order) plus a rounding bound is at most tol:
    no other summation order of ``Q l + b`` can put it above tol. The bound is
    :func:`_loose_rounding_bound` first (no product), and :func:`residual_rounding_bound`
    (formed in ``magnitude``, n entries, overwritten) only when that one does not certify."""
    return residual + _loose_rounding_bound(csc, b, scale, impulses) <= tol or \
        residual + _rounding_bound_into(csc, b, scale, impulses, magnitude) <= tol


@njit(cache=True)
def envelope_pi_robust(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, b: np.ndarray,
                       diag: np.ndarray, warm_start: np.ndarray, order_above: int,
                       max_envelope_work: float, packed_options: np.ndarray):
    """(l, converged by qpbench's residual formula, path code, linear solves, interior
    iterations, factorizations, certified) of pi-robust on LCP(Q, b), Q given by its CSC arrays,
    from ``clean_start(warm_start)`` (an empty array: from zero), with the options
    :func:`options_of` packs. A start that is already converged, or that the start sweeps solve
    (in the posed order), is returned before any set-up.
    Above ``order_above`` contacts, or when the envelope in the posed order is wide
    (``WIDE_ENVELOPE``), and unless it is cheap already (``WIDE_ENVELOPE_WORK``), the contacts
    are first put in reverse Cuthill-McKee order (inside the timed call), which keeps
    the envelope factors narrow. When one factorization of the whole envelope would cost more than
    ``max_envelope_work`` multiply-adds (``sum_i w_i^2 / 2`` over its row widths w_i: wide grids),
    it declines at once (path ``PATH_DECLINED``) and the caller's sparse path runs. ``certified``:
    converged, and :func:`_certified`. ``indptr`` and ``indices`` may be 32-bit (SciPy's, passed
    without a copy)."""
    options = unpacked(packed_options)
    n, entries = b.size, indices.size
    # the set-up's arrays, sliced from two allocations (an allocation for each of them cost
    # about 4% of a 5x5 dump's solve, hot): integers = Q's indptr and indices as 64-bit, the
    # envelope's row offsets, the upper triangle's starts (or its ends, when Q's own arrays
    # serve as it: _leading_upper) and rows; reals = the start's Q l, the sweeps' 1 / D, the
    # rounding bound's magnitudes, D with zeros replaced, the upper triangle's values
    integers = np.empty(3 * (n + 1) + 2 * entries, dtype=np.int64)
    reals = np.empty(4 * n + entries)
    posed_indptr, posed_indices = integers[:n + 1], integers[n + 1:n + 1 + entries]
    for i in range(n + 1):
        posed_indptr[i] = indptr[i]
    for k in range(entries):
        posed_indices[k] = indices[k]
    indptr, indices = posed_indptr, posed_indices
    A_posed = (indptr, indices, data)
    scale = TINY  # qpbench's metrics.scale, max(max |b_i|, TINY) (NaN when b has one)
    for i in range(n):
        if abs(b[i]) > scale or b[i] != b[i]:
            scale = abs(b[i])
    start = clean_start(warm_start, n)  # (a new array: the sweeps change it in place)
    start_product, inverse, magnitude = reals[:n], reals[n:2 * n], reals[2 * n:3 * n]
    start_residual = _natural_residual_into(A_posed, b, diag, scale, start, start_product)
    if start_residual <= options.tol:  # converged already: returned before any set-up
        return start, True, PATH_START, 0, 0, 0, _certified(
            A_posed, b, scale, start, start_residual, options.tol, magnitude)
    # the start sweeps, in the posed order: contacts that hardly interact (Q nearly diagonal)
    # are solved by the sweeps alone, before any set-up
    if options.start_sweeps > 0:
        _gauss_seidel(A_posed, b, diag, start, inverse, options.start_sweeps)
        start_residual = _natural_residual_into(A_posed, b, diag, scale, start, start_product)
        if start_residual <= options.tol:
            return start, True, PATH_SWEEPS, 0, 0, 0, _certified(
                A_posed, b, scale, start, start_residual, options.tol, magnitude)
    safe_diag = reals[3 * n:4 * n]  # D with zeros replaced, for divisions
    for i in range(n):
        safe_diag[i] = diag[i] if diag[i] > 0.0 else 1.0
    order = integers[:0]  # the posed order
    A = A_posed
    at = n + 1 + entries
    widths = integers[at:at + n + 1]
    starts, rows, values = integers[at + n + 1:at + 2 * n + 2], integers[at + 2 * n + 2:], \
        reals[4 * n:]
    _envelope_widths(A, widths)
    work = _envelope_work(widths)
    if work > WIDE_ENVELOPE_WORK and (n > order_above or work > WIDE_ENVELOPE * n ** 3 / 6.0):
        order = reverse_cuthill_mckee(indptr, indices, n)
        A = _permuted(indptr, indices, data, order, widths, (starts, rows, values))
        work = _envelope_work(widths)
    if work > max_envelope_work:
        return start, False, PATH_DECLINED, 0, 0, 0, False
    if order.size == 0 and _leading_upper(A, starts[:n]):
        upper = (indptr, starts[:n], indices, data)
    else:
        if order.size == 0:  # (else _permuted has copied its upper triangle)
            _upper_into(A, (starts, rows, values))
        upper = (starts, starts[1:], rows, values)
    if order.size:
        lcp = OrderedLcp(A, upper, Posed(A_posed, b, diag, order), b[order], diag[order],
                         safe_diag[order], scale)
        start = start[order]
    else:
        lcp = OrderedLcp(A, upper, Posed(A_posed, b, diag, order), b, diag, safe_diag, scale)
    answer, converged, path, solves, interior, factorizations, residual = _solve_ordered(
        lcp, start, start_residual, start_product, options, widths)
    impulses = answer
    if order.size:
        impulses = np.empty(n)
        impulses[order] = answer
    certified = converged and _certified(A_posed, b, scale, impulses, residual, options.tol,
                                         magnitude)
    return impulses, converged, path, solves, interior, factorizations, certified


@njit(cache=True)
def _pair_lcp(a: float, coupling: float, d: float, c_first: float, c_second: float):
    """(x_1, x_2, solved): the LCP of one 2x2 block, ``x >= 0``, ``B x + c >= 0``,
    ``x . (B x + c) = 0`` with ``B = [[a, coupling], [coupling, d]]`` (B positive
    semi-definite), by its four active sets in turn (both zero, only x_1, only x_2, both
    free); not solved when none fits (B singular and c inconsistent)."""
    if c_first >= 0.0 and c_second >= 0.0:
        return 0.0, 0.0, True
    if a > 0.0:
        first = -c_first / a
        if first >= 0.0 and coupling * first + c_second >= 0.0:
            return first, 0.0, True
    if d > 0.0:
        second = -c_second / d
        if second >= 0.0 and coupling * second + c_first >= 0.0:
            return 0.0, second, True
    determinant = a * d - coupling * coupling
    if determinant > 0.0:
        first = (coupling * c_second - d * c_first) / determinant
        second = (coupling * c_first - a * c_second) / determinant
        if first >= 0.0 and second >= 0.0:
            return first, second, True
    return 0.0, 0.0, False


@njit(cache=True)
def contact_block_sweeps(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                         b: np.ndarray, start: np.ndarray, contacts: int,
                         sweeps: int) -> np.ndarray:
    """``sweeps`` block Gauss-Seidel sweeps on LCP(Q, b) whose blocks are the pairs
    ``(k, contacts + k)`` (Anitescu's relaxation: a contact's ``z+`` and ``z-``): for
    k = 1..contacts in turn, ``z_k`` and ``z_{contacts+k}`` become the solution of the 2x2
    LCP of Q's block with ``c = (Q z + b)_block - Q_block z_block`` (the rest held fixed; a
    block whose LCP has none is left alone). Each contact's two columns ``n +- mu t`` are
    nearly parallel, which is what slows scalar sweeps down; a single sliding or sticking
    contact is solved exactly in one sweep. ``w = Q z + b`` is kept up to date column by
    column."""
    size = 2 * contacts
    impulses = start.copy()
    w = b.copy()
    block_diag, coupling = np.zeros(size), np.zeros(contacts)
    for column in range(size):
        value = impulses[column]
        for k in range(indptr[column], indptr[column + 1]):
            row = indices[k]
            w[row] += data[k] * value
            if row == column:
                block_diag[column] = data[k]
            elif column >= contacts and row == column - contacts:
                coupling[row] = data[k]
    for _ in range(sweeps):
        for contact in range(contacts):
            first, second = contact, contacts + contact
            plus, cross, minus = block_diag[first], coupling[contact], block_diag[second]
            z_first, z_second, solved = _pair_lcp(
                plus, cross, minus, w[first] - plus * impulses[first] - cross * impulses[second],
                w[second] - cross * impulses[first] - minus * impulses[second])
            if not solved:
                continue
            for column, value in ((first, z_first), (second, z_second)):
                change = value - impulses[column]
                if change != 0.0:
                    for k in range(indptr[column], indptr[column + 1]):
                        w[indices[k]] += data[k] * change
                    impulses[column] = value
    return impulses


@njit(cache=True)
def relaxed_pi_robust(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                      b: np.ndarray, diag: np.ndarray, warm_start: np.ndarray, mu: np.ndarray,
                      order_above: int, max_envelope_work: float, packed_options: np.ndarray):
    """(r, then :func:`envelope_pi_robust`'s outputs, z first) on Anitescu's relaxation of a
    frictional problem with n contacts: the impact problem in z = (z+, z-) >= 0 (2n contacts,
    columns ``n +- mu t``) whose Q, b and diag(Q) are given, its answer mapped back to ``r = (z+
    + z-, mu (z+ - z-))``. A warm start r (2n finite entries, else none) enters as ``z+- =
    max((l_N +- l_T / mu) / 2, 0)`` (``l_N / 2`` where mu = 0), both maps as
    ``qpbench.solvers.friction_ccp`` writes them. The start (zero without a warm start) first
    gets ``start_sweeps`` sweeps of :func:`contact_block_sweeps`, which solve each contact's
    two variables together; a cold start that they solve is path ``PATH_SWEEPS``."""
    n = mu.size
    start = np.zeros(2 * n)
    warm = warm_start.size == 2 * n and np.all(np.isfinite(warm_start))
    if warm:
        for k in range(n):
            ratio = warm_start[n + k] / mu[k] if mu[k] > 0 else 0.0
            start[k] = max((warm_start[k] + ratio) / 2.0, 0.0)
            start[n + k] = max((warm_start[k] - ratio) / 2.0, 0.0)
    start = contact_block_sweeps(indptr, indices, data, b, start, n,
                                 unpacked(packed_options).start_sweeps)
    z, converged, path, solves, interior, factorizations, certified = envelope_pi_robust(
        indptr, indices, data, b, diag, start, order_above, max_envelope_work, packed_options)
    if path == PATH_START and not warm:
        path = PATH_SWEEPS
    impulses = np.empty(2 * n)
    for k in range(n):
        impulses[k] = z[k] + z[n + k]
        impulses[n + k] = mu[k] * (z[k] - z[n + k])
    return impulses, z, converged, path, solves, interior, factorizations, certified


_warm = False


def warm_up() -> None:
    """Compiles (or loads from the cache) the kernel once in this process, on K3's LCP (and
    its relaxed entry on one frictional contact)."""
    global _warm
    if _warm:
        return
    Q = np.array([[2.0, 1.0, -1.0], [1.0, 2.0, 1.0], [-1.0, 1.0, 2.0]])
    b = np.array([-4.0, -2.0, 2.0])
    diag = np.diag(Q).copy()
    csc = (np.array([0, 3, 6, 9], dtype=np.int32), np.array([0, 1, 2] * 3, dtype=np.int32),
           Q.T.ravel().copy())
    options = options_of(accuracy.options_for("pi-robust", 1e-8))
    for order_above in (64, 0):  # both branches' types
        envelope_pi_robust(*csc, b, diag, np.empty(0), order_above, 1e9, options)
    relaxed = (np.array([0, 2, 4], dtype=np.int32), np.array([0, 1, 0, 1], dtype=np.int32),
               np.array([2.0, 1.0, 1.0, 2.0]))  # one contact's two relaxed columns
    relaxed_pi_robust(*relaxed, np.array([-1.0, -1.0]), np.array([2.0, 2.0]), np.empty(0),
                      np.array([0.5]), 64, 1e9, options)
    _warm = True
