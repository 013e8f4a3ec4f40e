"""Envelope Cholesky factors of policy blocks, their substitutions, updates and cache.

Each policy solve of pi-robust solves, for the free set F of the policy,

    (Q_FF + rho D_F) x_F = -q_F

by the envelope Cholesky factor ``L L^T = Q_FF + rho D_F`` (Jennings, "A compact storage
scheme for the solution of symmetric linear simultaneous equations", Comput. J. 9(3), 1966;
George and Liu, "Computer Solution of Large Sparse Positive Definite Systems", 1981). Row i
of a factor is stored contiguously, its columns ``first(i) .. i`` with the diagonal last, as
its reciprocal, so that every division of the factorization and the substitutions is a
multiplication.

The last two block factors are kept in a ``FactorCache`` keyed by (policy, rho)
(:func:`_block_solve`): prox steps on a settled policy cost two triangular solves, and a new
factor copies the leading rows it shares with a kept one (row i of a Cholesky factor depends
on the leading i rows of the matrix only). Where the active-set method fixes at most
``UPDATE_FIXED`` contacts of the block it solved last, their rows are deleted from that
factor by plane rotations instead (:func:`_delete_contact`, :func:`_block_solve_fixing`;
Gill, Golub, Murray and Saunders, "Methods for modifying matrix factorizations", Math.
Comp. 28, 1974; Golub and Van Loan, "Matrix Computations", section 6.5). A pivot that is not
positive raises ``np.linalg.LinAlgError``, and the caller runs the Python path.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers.pi_robust_kernel.constants import (
    DEPENDENT_PIVOT,
    LANES,
    REDUCTIONS,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.structures import FactorCache, OrderedLcp, Upper, Work


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _subtract_dot(total: float, left: np.ndarray, left_start: int, right: np.ndarray,
                  right_start: int, length: int) -> float:
    """``total - sum_k left[left_start + k] right[right_start + k]`` over k < length.

    Parameters
    ----------
    total : float
        The value to subtract from.
    left, right : np.ndarray
        The two arrays (they may be the same one).
    left_start, right_start : int
        Where each run of ``length`` entries starts.
    length : int
        The number of products.

    Returns
    -------
    float
        ``total`` minus the inner product.

    Notes
    -----
    The products are summed in ``LANES`` (4) partial sums, product k into sum ``k mod 4``,
    over the leading multiple of four; the partial sums are added as ``(s0 + s1) + (s2 + s3)``,
    then the last ``length mod 4`` products in order, and the whole is subtracted from
    ``total``. The order is the code's, not the compiler's: the four sums vectorise as one
    four-wide register on every CPU with a vector unit, and the value is the same on every CPU
    (a reassociating compiler would pick the order by the CPU's vector width). Offsets are
    taken unsigned (no negative-index wraparound).
    """
    left_at, right_at = np.uint64(left_start), np.uint64(right_start)
    lanes = np.uint64(LANES)
    count = np.uint64(length)
    whole = count - count % lanes
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for k in range(np.uint64(0), whole, lanes):
        a, b = left_at + k, right_at + k
        s0 += left[a] * right[b]
        s1 += left[a + np.uint64(1)] * right[b + np.uint64(1)]
        s2 += left[a + np.uint64(2)] * right[b + np.uint64(2)]
        s3 += left[a + np.uint64(3)] * right[b + np.uint64(3)]
        s4 += left[a + np.uint64(4)] * right[b + np.uint64(4)]
        s5 += left[a + np.uint64(5)] * right[b + np.uint64(5)]
        s6 += left[a + np.uint64(6)] * right[b + np.uint64(6)]
        s7 += left[a + np.uint64(7)] * right[b + np.uint64(7)]
    inner = ((s0 + s4) + (s1 + s5)) + ((s2 + s6) + (s3 + s7))
    for k in range(whole, count):
        inner += left[left_at + k] * right[right_at + k]
    return total - inner


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _subtract_products(total: float, values: np.ndarray, left: int, right: int,
                       length: int) -> float:
    """``total - sum_k values[left + k] values[right + k]`` over k < length
    (:func:`_subtract_dot` within one array): the two inner products of each entry pair in
    :func:`_factor_rows`."""
    return _subtract_dot(total, values, left, values, right, length)


@njit(cache=True, fastmath=REDUCTIONS, **WITHOUT_REFCOUNTS)
def _factor_rows(upper: Upper, index: np.ndarray, position: np.ndarray, row_scale: np.ndarray,
                 shift_scale: float, shift: np.ndarray, values: np.ndarray, offsets: np.ndarray,
                 first_row: int, x: np.ndarray) -> None:
    """Factor ``L L^T = S Q_II S + shift_scale diag(shift_I)`` by rows, from ``first_row`` on.

    Parameters
    ----------
    upper : Upper
        Q's upper triangle (``ordering._upper``): column c holds row c of the lower triangle.
    index : np.ndarray
        I, the block's contacts in rising order.
    position : np.ndarray
        ``position[r]``: r's place in I, or -1 when r is not in I.
    row_scale : np.ndarray
        The diagonal of S; empty for S = I. Entry (r, c) scales as ``(Q_rc s_r) s_c``.
    shift_scale, shift : float, np.ndarray
        The diagonal shift is ``shift_scale * shift[index]`` (rho D_I for a policy block).
    values, offsets : np.ndarray
        The factor's storage: row i in ``values[offsets[i]:offsets[i + 1]]``, its columns
        ``first(i) .. i`` with the diagonal last, kept as its reciprocal ``1 / L_ii``. Rows
        before ``first_row`` are L's already and are not touched.
    first_row : int
        The first row to factor (row i of L depends on the leading i rows of the matrix only).
    x : np.ndarray
        Unless empty, overwritten by the forward substitution ``L y = x``.

    Raises
    ------
    np.linalg.LinAlgError
        When a pivot is not positive (the block is not positive definite in floating point).

    Notes
    -----
    Row i of L has the envelope of row i of the matrix: ``first(i)`` is the first place in I
    among the rows of column ``index[i]`` of the upper triangle, and Cholesky creates no fill
    to its left (George and Liu 1981, section 4.2). Each entry is
    ``L_ij = (A_ij - sum_k L_ik L_jk) / L_jj`` with the division a multiplication by the stored
    reciprocal. Each row's pattern, entries, factor and substitution are formed in one pass
    while the row is in cache. The entries are formed two at a time, ``(j, j + 1)``: each inner
    product runs over the columns before ``j - 1`` first and the row's newest entries are
    subtracted last, so that the long inner products do not wait on the entry formed just
    before them. The diagonal's sum of squares ``sum_j L_ij^2`` and the row's substitution sum
    ``sum_j L_ij y_j`` are accumulated as the entries are formed.

    References
    ----------
    A. Jennings, "A compact storage scheme for the solution of symmetric linear simultaneous
    equations", Comput. J. 9(3), 1966. A. George and J. W. H. Liu, "Computer Solution of Large
    Sparse Positive Definite Systems", Prentice-Hall, 1981.
    """
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
        if scaled:  # (two loops: no test inside either)
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
    """x with ``L L^T x = rhs``, for an envelope factor stored as by :func:`_factor_rows`."""
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
        x[i] = _subtract_dot(x[i], values, base, x, first, i - first) * values[end - 1]


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
def _block_solve(upper: Upper, safe_diag: np.ndarray, policy: np.ndarray, index: np.ndarray,
                 rho: float, rhs: np.ndarray, cache: FactorCache) -> None:
    """Solve ``(Q_FF + rho D_F) x_F = rhs`` in place, through the cache of kept factors.

    Parameters
    ----------
    upper : Upper
        Q's upper triangle (``ordering._upper``).
    safe_diag : np.ndarray
        D with its zeros replaced by ones.
    policy : np.ndarray
        The policy's flags (True: free); it keys the cache together with rho.
    index : np.ndarray
        F, the policy's free contacts in rising order.
    rho : float
        The prox weight.
    rhs : np.ndarray
        The right side, overwritten by x_F.
    cache : FactorCache
        The kept factors; updated (slot, key, age, counters).

    Raises
    ------
    np.linalg.LinAlgError
        When the new factor has a pivot that is not positive.

    Notes
    -----
    When a slot holds the factor of (policy, rho), two triangular solves. Otherwise the least
    recently used slot is refactored, starting from the kept factor of the same rho whose policy
    agrees with this one on the longest run of leading contacts: the rows of L for the free
    contacts in that run are copied (row i of a Cholesky factor depends on the leading i rows of
    the matrix only), and only the rows after them are factored, the forward substitution made
    as they are formed.
    """
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
    """Delete row and column ``place`` of a block from its envelope factor, in place.

    Parameters
    ----------
    values, offsets : np.ndarray
        The factor L of the block, stored as by :func:`_factor_rows`; overwritten by the new
        factor (rows only move up, each read before it is overwritten).
    size : int
        The rows of L.
    place : int
        The row (and column) to delete.
    cosines, sines : np.ndarray
        Work arrays for the rotations (at least ``size - 1`` entries).
    x : np.ndarray
        Unless empty, overwritten by the forward substitution ``L' y = x`` with the new factor,
        each row's as that row is formed.

    Notes
    -----
    With the block's rows split at the deleted one, ``L = [L11; l21^T l22; L31 l32 L33]``, the
    new factor is ``[L11; L31 L33']`` where ``L33' L33'^T = L33 L33^T + l32 l32^T``: a rank-one
    update, made by plane (Givens) rotations row by row. Row i after the deleted one keeps its
    columns before it; then, with ``w = L_i,place``, each later column c turns
    ``(L_ic, w) <- (cos_c L_ic + sin_c w, cos_c w - sin_c L_ic)``, and the diagonal becomes
    ``r = sqrt(L_ii^2 + w^2)``, whose ``cos = L_ii / r``, ``sin = w / r`` turn that column in
    the rows below. A row's envelope keeps its first column, so it may hold a few zeros that a
    new factorization would not store.

    References
    ----------
    P. E. Gill, G. H. Golub, W. Murray and M. A. Saunders, "Methods for modifying matrix
    factorizations", Math. Comp. 28, 1974. G. H. Golub and C. F. Van Loan, "Matrix
    Computations", 4th ed., 2013, sections 5.1.8 and 6.5.4.
    """
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
    """:func:`_block_solve` for the policy solved last with some of its contacts fixed.

    Parameters
    ----------
    safe_diag, policy, index, rho, rhs
        As for :func:`_block_solve` (``index``: the new free set).
    work : Work
        Its cache's most recently used slot holds the factor of the block solved last.
    places : np.ndarray
        The places, rising, in the block solved last, of the contacts this policy fixes.

    Notes
    -----
    The fixed contacts' rows are deleted from that factor in its own slot
    (:func:`_delete_contact`), from the last up so that the places before stay valid; the
    other slot keeps the factor before. The last deletion makes the forward substitution as it
    forms the rows, and the backward substitution follows.
    """
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
    """Solve a policy's block: ``work.x`` with ``(Q_FF + rho D_F) x_F = -q_F``, 0 off F.

    Parameters
    ----------
    lcp : OrderedLcp
        The problem in the kernel's order.
    policy : np.ndarray
        The policy's flags (True: free), F its free contacts.
    rho : float
        The prox weight.
    q : np.ndarray
        The prox step's constant term.
    work : Work
        Its ``x`` receives the solution, ``free[:|F|]`` the free contacts, ``rhs`` the block's
        solution; its cache is updated.
    fixed_places : np.ndarray
        Empty, or the places in the block solved last of the contacts this policy fixes of it:
        then the factor is updated by row deletions (:func:`_block_solve_fixing`) rather than
        found or refactored (:func:`_block_solve`).

    Returns
    -------
    int
        ``|F|``, the size of the block.
    """
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

