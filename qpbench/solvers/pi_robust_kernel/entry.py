"""Entry points of pi-robust's compiled kernel.

:func:`envelope_pi_robust` computes l >= 0 with ``min(D l, Q l + b) = 0`` (D = diag Q, Q
symmetric positive semi-definite and often singular) to qpbench's residual
``||min(D l, Q l + b)||_inf / scale <= tol``, by the algorithm of
``qpbench.solvers.pi_robust`` in its order for dense problems, without per-step Python
overhead and with Q sparse throughout (but for the dense copy of step 2):

1. the start (a warm start, or zero) gets ``start_sweeps`` projected Gauss-Seidel sweeps in
   the posed order (:func:`_gauss_seidel`), which alone solve contacts that hardly interact,
   and more where one factorization costs many sweeps (``SWEEP_SHARE``, after step 3);
2. on at most ``DENSE_CONTACTS`` contacts, block principal pivoting on a dense copy of Q
   (:mod:`.dense`), which touches little of the kernel, at most ``DENSE_BUDGET`` solves; its
   answer is taken when qpbench's residual accepts it, else the steps below run;
3. above ``order_above`` contacts, or when the envelope in the posed order is wide, the
   contacts are put in reverse Cuthill-McKee order (:mod:`.ordering`); a problem whose whole
   envelope costs more than ``max_envelope_work`` to factor is declined;
4. proximal policy iteration (:mod:`.prox`), each prox step by block pivoting
   (:mod:`.pivoting`) or the primal active-set method (:mod:`.active_set`), every block
   solved by an envelope Cholesky factor (:mod:`.factor`);
5. when that fails, the interior point, its iterates finished by policy iteration
   (:mod:`.interior`);
6. a converged answer is certified by its residual plus a rounding bound (:mod:`.residual`).

:func:`pi_robust_into`, the call from Python, makes the same solve through fewer arguments,
first on the problem without the looser of its parallel contacts when it has any
(:mod:`.parallel`). :func:`relaxed_pi_robust` runs :func:`envelope_pi_robust` on Anitescu's
relaxation of a frictional problem, its start swept contact by contact
(:func:`contact_block_sweeps`). Compilation:
``cache=True`` (machine code cached beside the modules); :func:`warm_up` compiles or loads it
once per process, and pi-robust calls it in its set-up, outside the timed solve.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from qpbench.solvers import accuracy
from qpbench.solvers.pi_robust_kernel.constants import (
    DENSE_BUDGET,
    DENSE_CONTACTS,
    DENSE_SLACK,
    MOST_START_SWEEPS,
    PATH_DECLINED,
    PATH_DENSE,
    PATH_INTERIOR,
    PATH_NAMES,
    PATH_NONE,
    PATH_PARALLEL_DROPPED,
    PATH_START,
    PATH_SWEEPS,
    SWEEP_SHARE,
    WIDE_ENVELOPE,
    WIDE_ENVELOPE_WORK,
    WITHOUT_REFCOUNTS,
)
from qpbench.solvers.pi_robust_kernel.dense import dense_pivoting
from qpbench.solvers.pi_robust_kernel.interior import _solve_ordered
from qpbench.solvers.pi_robust_kernel.ordering import (
    _envelope_widths,
    _envelope_work,
    _leading_upper,
    _permuted,
    _upper_into,
    reverse_cuthill_mckee,
)
from qpbench.solvers.pi_robust_kernel.parallel import diagonal_into, looser_parallel, without
from qpbench.solvers.pi_robust_kernel.residual import (
    _certified,
    _matvec,
    _natural_residual_into,
    residual_scale,
)
from qpbench.solvers.pi_robust_kernel.structures import (
    Csc,
    OrderedLcp,
    Posed,
    options_of,
    unpacked,
)

# what qpbench.solvers.pi_robust and qpbench.solvers.staggered_compiled read from the kernel
__all__ = ["PATH_INTERIOR", "PATH_NAMES", "PATH_NONE", "PATH_PARALLEL_DROPPED", "PATH_SWEEPS",
           "_matvec", "call_options_of", "contact_block_sweeps", "envelope_pi_robust",
           "options_of", "pi_robust_into", "relaxed_pi_robust", "warm_up"]


@njit(cache=True, **WITHOUT_REFCOUNTS)
def _gauss_seidel(A: Csc, b: np.ndarray, diag: np.ndarray, impulses: np.ndarray,
                  inverse: np.ndarray, sweeps: int) -> None:
    """Run ``sweeps`` projected Gauss-Seidel sweeps on LCP(Q, b), in place on ``impulses``.

    For i = 1..n in turn, ``l_i <- max(0, l_i - (Q l + b)_i / D_i)``, with ``(Q l)_i`` from
    column i of the symmetric Q; contacts with D_i = 0 are left alone. ``inverse``
    (overwritten) holds 1 / D_i, 0 where D_i = 0. A few sweeps cost a few products and put most
    contacts on the right side of the active set, so that block pivoting from there needs
    fewer factorizations; contacts that hardly interact (Q nearly diagonal) are solved by the
    sweeps alone (Cottle, Pang and Stone, "The Linear Complementarity Problem", 1992,
    section 5.2).
    """
    indptr, indices, data = A
    for i in range(impulses.size):
        inverse[i] = 1.0 / diag[i] if diag[i] > 0.0 else 0.0
    for _ in range(sweeps):
        for i in range(impulses.size):
            w = b[i]
            for k in range(indptr[i], indptr[i + 1]):
                w += data[k] * impulses[indices[k]]
            impulses[i] = max(0.0, impulses[i] - w * inverse[i])


@njit(cache=True)
def clean_start(warm_start: np.ndarray, n: int) -> np.ndarray:
    """The start: ``max(warm_start, 0)`` when it has n entries, all finite, else zeros.

    As ``qpbench.solvers.lcp.Lcp.start``, in compiled code: no NumPy call overhead.

    Parameters
    ----------
    warm_start : np.ndarray
        The caller's start l (empty: none).
    n : int
        The number of contacts.

    Returns
    -------
    np.ndarray
        A new n-entry start, never a view of ``warm_start``.
    """
    if warm_start.size != n:
        return np.zeros(n)
    for value in warm_start:
        if not np.isfinite(value):
            return np.zeros(n)
    return np.maximum(warm_start, 0.0)


@njit(cache=True)
def envelope_pi_robust(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, b: np.ndarray,
                       diag: np.ndarray, warm_start: np.ndarray, order_above: int,
                       max_envelope_work: float, packed_options: np.ndarray):
    """Solve LCP(Q, b) by pi-robust in one compiled call.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays (SciPy's; the index arrays may be 32-bit, passed without a copy).
    b : np.ndarray
        The LCP's constant term.
    diag : np.ndarray
        diag(Q).
    warm_start : np.ndarray
        The start (:func:`clean_start`); an empty array starts from zero.
    order_above : int
        Above this many contacts a wide envelope is reordered (reverse Cuthill-McKee).
    max_envelope_work : float
        The most multiply-adds that one factorization of the whole envelope may cost
        (``sum_i w_i^2 / 2`` over its row widths w_i); above it the kernel declines.
    packed_options : np.ndarray
        The options, as :func:`.structures.options_of` packs them.

    Returns
    -------
    l : np.ndarray
        The answer (the start when declined), in the posed order.
    converged : bool
        Whether qpbench's residual formula, summed in scipy's order, is at most tol.
    path : int
        The path code (``constants.PATH_NAMES``).
    solves : int
        Linear solves and interior-point iterations.
    interior : int
        Interior-point iterations.
    factorizations : int
        Envelope factorizations.
    certified : bool
        Converged, and the residual plus a rounding bound is within tol
        (:func:`.residual._certified`): no other summation order puts it above tol.

    Raises
    ------
    np.linalg.LinAlgError
        When a factor fails; the caller then runs the Python path.

    Notes
    -----
    A start that is converged already, or that the start sweeps solve (in the posed order,
    :func:`_gauss_seidel`), is returned before any set-up (paths ``PATH_START`` and
    ``PATH_SWEEPS``). On at most ``DENSE_CONTACTS`` contacts, block pivoting on a dense copy
    of Q from the swept start's policy (:func:`.dense.dense_pivoting`) comes next, and its
    answer is returned when qpbench's residual accepts it (``PATH_DENSE``); otherwise its
    solves count into the general path's. Unless the envelope in the posed order is cheap already
    (``WIDE_ENVELOPE_WORK``), and when there are more than ``order_above`` contacts or the
    envelope costs more than ``WIDE_ENVELOPE`` of a dense factorization, the contacts are put in
    reverse Cuthill-McKee order, inside the timed call. When one factorization of the whole
    envelope would cost more than ``max_envelope_work`` (wide grids), the kernel declines
    (``PATH_DECLINED``) and the caller's sparse path runs. Otherwise the start gets more
    sweeps, as many in all as cost ``SWEEP_SHARE`` of one factorization of that envelope
    (``MOST_START_SWEEPS`` at most; a sweep costs one multiply-add per entry of Q), and a
    start they solve is returned; else :func:`.interior._solve_ordered` solves it.
    """
    options = unpacked(packed_options)
    n, entries = b.size, indices.size
    # the set-up's arrays, sliced from two allocations rather than one each: integers = Q's
    # indptr and indices as 64-bit, the envelope's row offsets, the upper triangle's starts
    # (or its ends, when Q's own arrays serve as it: _leading_upper) and rows; reals = the
    # start's Q l, the sweeps' 1 / D, the rounding bound's magnitudes, D with zeros
    # replaced, the upper triangle's values
    integers = np.empty(3 * (n + 1) + 2 * entries, dtype=np.int64)
    reals = np.empty(4 * n + entries)
    posed_indptr, posed_indices = integers[:n + 1], integers[n + 1:n + 1 + entries]
    for i in range(n + 1):
        posed_indptr[i] = indptr[i]
    for k in range(entries):
        posed_indices[k] = indices[k]
    indptr, indices = posed_indptr, posed_indices
    A_posed = (indptr, indices, data)
    scale = residual_scale(b)
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
    # a few contacts: dense block pivoting first, which touches little of the kernel
    dense_solves = 0
    if n <= DENSE_CONTACTS:
        answer, dense_solves, found = dense_pivoting(
            A_posed, b, start, DENSE_SLACK * options.tol * scale, DENSE_BUDGET)
        if found:
            residual = _natural_residual_into(A_posed, b, diag, scale, answer, magnitude)
            if residual <= options.tol:
                return answer, True, PATH_DENSE, dense_solves, 0, dense_solves, _certified(
                    A_posed, b, scale, answer, residual, options.tol, magnitude)
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
    # more sweeps where a factorization costs many of them (SWEEP_SHARE)
    more_sweeps = min(MOST_START_SWEEPS, int(SWEEP_SHARE * work / max(entries, 1))) \
        - options.start_sweeps
    if options.start_sweeps > 0 and more_sweeps > 0:
        _gauss_seidel(A_posed, b, diag, start, inverse, more_sweeps)
        start_residual = _natural_residual_into(A_posed, b, diag, scale, start, start_product)
        if start_residual <= options.tol:
            return start, True, PATH_SWEEPS, 0, 0, 0, _certified(
                A_posed, b, scale, start, start_residual, options.tol, magnitude)
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
    return impulses, converged, path, solves + dense_solves, interior, \
        factorizations + dense_solves, certified


@njit(cache=True)
def _pair_lcp(a: float, coupling: float, d: float, c_first: float, c_second: float):
    """Solve the 2x2 LCP ``x >= 0``, ``B x + c >= 0``, ``x . (B x + c) = 0``.

    ``B = [[a, coupling], [coupling, d]]`` is positive semi-definite. The four active sets are
    tried in turn (both zero, only x_1, only x_2, both free). Returns ``(x_1, x_2, solved)``;
    not solved when none fits (B singular and c inconsistent).
    """
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
    """Run block Gauss-Seidel sweeps on Anitescu's relaxation, one contact's pair at a time.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays (2 ``contacts`` columns: every z+ first, then every z-).
    b : np.ndarray
        The LCP's constant term.
    start : np.ndarray
        The start z (not changed).
    contacts : int
        The frictional contacts.
    sweeps : int
        The sweeps to make.

    Returns
    -------
    np.ndarray
        z after the sweeps.

    Notes
    -----
    The blocks are the pairs ``(k, contacts + k)``, a contact's z+ and z-: for k = 1..contacts
    in turn, the pair becomes the solution of the 2x2 LCP of Q's block (:func:`_pair_lcp`) with
    ``c = (Q z + b)_block - Q_block z_block``, the rest held fixed (a block whose LCP has no
    solution is left alone). A contact's two columns ``n +- mu t`` are nearly parallel, which is
    what slows scalar sweeps down; a single sliding or sticking contact is solved exactly in one
    sweep. ``w = Q z + b`` is kept up to date column by column.
    """
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
    """Solve Anitescu's relaxation of a frictional problem by pi-robust in one compiled call.

    Parameters
    ----------
    indptr, indices, data, b, diag : np.ndarray
        The relaxed impact problem in z = (z+, z-) >= 0 (2n contacts, columns ``n +- mu t``):
        Q's CSC arrays, b and diag(Q).
    warm_start : np.ndarray
        A warm start r = (l_N, l_T) (2n finite entries, else none).
    mu : np.ndarray
        The n friction coefficients.
    order_above, max_envelope_work, packed_options
        As for :func:`envelope_pi_robust`.

    Returns
    -------
    tuple
        r, then :func:`envelope_pi_robust`'s outputs (z first).

    Notes
    -----
    The warm start enters as ``z+- = max((l_N +- l_T / mu) / 2, 0)`` (``l_N / 2`` where mu = 0),
    and the answer maps back to ``r = (z+ + z-, mu (z+ - z-))``, both as
    ``qpbench.solvers.friction_ccp`` writes them. The start (zero without a warm start) first
    gets ``start_sweeps`` sweeps of :func:`contact_block_sweeps`; a cold start that they solve
    is path ``PATH_SWEEPS``.

    References
    ----------
    M. Anitescu, "Optimization-based simulation of nonsmooth rigid multibody dynamics", Math.
    Program. 105, 2006.
    """
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


# the entries of its ``call_options`` before envelope_pi_robust's packed options
CALL_ORDER_ABOVE = 0
CALL_WORK_LIMIT = 1
CALL_FROM_ZERO = 2  # 1: start from zero, whatever ``out`` holds; 0: ``out`` holds the start
CALL_HEAD = 3


def call_options_of(order_above: int, max_envelope_work: float, packed_options: np.ndarray,
                    from_zero: bool = False) -> np.ndarray:
    """Pack :func:`pi_robust_into`'s options: the ordering threshold, the work limit, whether
    to start from zero, then ``packed_options`` (:func:`.structures.options_of`).

    Parameters
    ----------
    order_above : int
        As for :func:`envelope_pi_robust`.
    max_envelope_work : float
        As for :func:`envelope_pi_robust`.
    packed_options : np.ndarray
        The kernel's packed options.
    from_zero : bool, optional
        Start from zero, so that the caller need not write into ``out`` before the call;
        False (default): ``out`` holds the start.

    Returns
    -------
    np.ndarray
        ``CALL_HEAD + len(packed_options)`` floats.
    """
    return np.concatenate(([float(order_above), float(max_envelope_work), float(from_zero)],
                           packed_options))


@njit(cache=True)
def pi_robust_into(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, b: np.ndarray,
                   out: np.ndarray, call_options: np.ndarray):
    """Solve LCP(Q, b) by :func:`envelope_pi_robust`, l written into ``out``; first without
    its looser parallel contacts, when it has any.

    The same solve through a narrower call: six array arguments, and scalars back, where
    :func:`envelope_pi_robust` takes nine arguments and hands back a new array. Crossing from
    Python, numba's dispatcher types every argument and boxes every returned object, an array
    dearest of all; on a problem of a few contacts, called after other work has taken over
    the caches, that crossing is a large part of the call (docs/notes/pi-robust.md, section
    "The call boundary"). diag(Q) is read from Q's own entries here, in the pass that also
    tells whether two contacts are parallel (:func:`.parallel.diagonal_into`); if so, the
    problem without the looser of each parallel group is solved first
    (:func:`_without_parallel`), and its answer, those contacts at zero, is taken when
    qpbench's residual of the whole problem accepts it (path plus ``PATH_PARALLEL_DROPPED``);
    else the whole problem is solved, and both solves count.

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays, as for :func:`envelope_pi_robust`.
    b : np.ndarray
        The LCP's constant term (n entries).
    out : np.ndarray
        n floats: in, the start (one non-finite entry: start from zero, as
        :func:`clean_start` has it), unless ``call_options`` says to start from zero; out, l.
    call_options : np.ndarray
        The ordering threshold, the work limit, whether to start from zero and the packed
        options (:func:`call_options_of`).

    Returns
    -------
    tuple
        :func:`envelope_pi_robust`'s converged, path, solves, interior, factorizations and
        certified (l is in ``out``).

    Raises
    ------
    np.linalg.LinAlgError
        When a factor fails; the caller then runs the Python path.
    """
    if call_options[CALL_FROM_ZERO] != 0.0 and out.size > 0:
        out[0] = np.nan  # read as no start (clean_start)
    diag = np.empty(b.size)
    order_above = int(call_options[CALL_ORDER_ABOVE])
    work_limit = call_options[CALL_WORK_LIMIT]
    packed = call_options[CALL_HEAD:]
    extra_solves = extra_interior = extra_factorizations = 0
    if diagonal_into(indptr, indices, data, diag):  # first without looser parallel contacts
        accepted, converged, path, solves, interior, factorizations, certified = \
            _without_parallel(indptr, indices, data, b, diag, out, order_above, work_limit,
                              packed)
        if accepted:
            return converged, path, solves, interior, factorizations, certified
        extra_solves, extra_interior, extra_factorizations = solves, interior, factorizations
    impulses, converged, path, solves, interior, factorizations, certified = envelope_pi_robust(
        indptr, indices, data, b, diag, out, order_above, work_limit, packed)
    out[:] = impulses
    return converged, path, solves + extra_solves, interior + extra_interior, \
        factorizations + extra_factorizations, certified


@njit(cache=True)
def _without_parallel(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                      b: np.ndarray, diag: np.ndarray, out: np.ndarray, order_above: int,
                      max_envelope_work: float, packed_options: np.ndarray):
    """Solve LCP(Q, b) without its looser parallel contacts (:mod:`.parallel`), l into ``out``
    when qpbench's residual of the whole problem accepts the answer mapped back (the dropped
    contacts at zero).

    Arguments as :func:`pi_robust_into`'s, its call options split; ``out`` holds the start.
    Returns whether the answer was accepted (``out`` untouched otherwise), then
    :func:`envelope_pi_robust`'s scalars of the smaller solve, its path plus
    ``PATH_PARALLEL_DROPPED`` and its certificate on the whole problem.
    """
    n = b.size
    kept, small_indptr, small_indices, small_data, small_b = without(
        indptr, indices, data, b, looser_parallel(indptr, indices, data, b, diag))
    if kept.size == n:  # (parallel, yet neither looser: a zero diagonal, or NaN in b)
        return False, False, PATH_NONE, 0, 0, 0, False
    start = clean_start(out, n)[kept]  # (zeros when out has a non-finite entry)
    small, converged, path, solves, interior, factorizations, _ = envelope_pi_robust(
        small_indptr, small_indices, small_data, small_b, diag[kept], start, order_above,
        max_envelope_work, packed_options)
    if converged:
        whole = np.zeros(n)
        whole[kept] = small
        csc = (indptr, indices, data)
        scale = residual_scale(b)
        product = np.empty(n)
        tol = unpacked(packed_options).tol
        residual = _natural_residual_into(csc, b, diag, scale, whole, product)
        if residual <= tol:
            out[:] = whole
            return True, True, path + PATH_PARALLEL_DROPPED, solves, interior, factorizations, \
                _certified(csc, b, scale, whole, residual, tol, product)
    return False, converged, path, solves, interior, factorizations, False


_warm = False


def warm_up() -> None:
    """Compile the kernel, or load it from numba's cache, once in this process.

    It runs on K3's LCP (both ordering branches' types) and on the relaxed entry with one
    frictional contact, outside any clock.
    """
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
        pi_robust_into(*csc, b, np.full(b.size, np.nan), call_options_of(order_above, 1e9,
                                                                         options))
    relaxed = (np.array([0, 2, 4], dtype=np.int32), np.array([0, 1, 0, 1], dtype=np.int32),
               np.array([2.0, 1.0, 1.0, 2.0]))  # one contact's two relaxed columns
    relaxed_pi_robust(*relaxed, np.array([-1.0, -1.0]), np.array([2.0, 2.0]), np.empty(0),
                      np.array([0.5]), 64, 1e9, options)
    _warm = True

