"""pi-robust/staggered with its whole loop compiled (numba): one call per solve.

The loop of ``qpbench.solvers.friction_staggered.staggered``, round for round, with pi-robust
inside: the normal QP by pi-robust's compiled kernel
(``qpbench.solvers.pi_robust_kernel.entry.envelope_pi_robust``) and the friction box QP by the
compiled projected Gauss-Seidel (``qpbench.solvers.box_sweeps``), so that no round returns to
Python. Each round, from (l_N, l_T):

1. ``b_N = q_N + W_NT l_T`` for the l_T the round starts from; l_N = pi-robust on
   LCP(W_NN, b_N) at the inner accuracy, started from the last l_N, then ``max(l_N, 0)``;
2. the box QP ``(W_TT, q_T + W_TN l_N, -mu l_N, mu l_N)`` (every box empty: l_T = 0) by
   ``box_sweeps.box_gauss_seidel`` from the round's l_T, as the Python loop's box solver,
   until the box residual is at most ``inner accuracy * scale`` (checked every
   ``box_check_every`` sweeps);
3. qpbench's Coulomb residual (:func:`coulomb_residual`, the formula of
   ``qpbench.problem.friction_metrics``); the best iterate is kept; stop at ``<= eps`` or after
   ``max_outer`` rounds;
4. the next round's l_T: the answer, or with ``anderson_depth`` > 0 the Anderson mixing of
   the last rounds (``qpbench.solvers.anderson``), as the Python loop does.

Then one normal solve given the best l_T, kept when it is no worse (or meets eps). Products
are summed in SciPy's order (CSC products column by column, CSR products row by row). A
normal solve that does not converge, or converges without the kernel's rounding certificate,
ends the call with ``FALLBACK``: the caller then runs the Python loop from the start, and the
time of both counts. The options are the accuracy table's rows of ``staggered`` and
``pi-robust``, as in the Python loop.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
from numba import njit

from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import accuracy, anderson, pi_robust_call
from qpbench.solvers.base import SolverOutput
from qpbench.solvers.box_sweeps import box_gauss_seidel
from qpbench.solvers.colouring import colour_order
from qpbench.solvers.pi_robust_call import NO_START
from qpbench.solvers.pi_robust_kernel import entry as kernel

# how a call ends
CONVERGED, MAX_OUTER, WARM_START, FALLBACK = 0, 1, 2, 3
# which answer it returns
BEST_ITERATE, FINAL_NORMAL_SOLVE, GIVEN_START = 0, 1, 2
RETURNED = ("best iterate", "final normal solve", "warm start")
ROW = "staggered"  # the accuracy table's row of the loop (``friction_staggered.ROW``)
# the places of the loop's options in ``LoopSettings.packed``
(OPTION_EPS, OPTION_MAX_OUTER, OPTION_ORDER_ABOVE, OPTION_INNER_EPS, OPTION_BOX_MAX_SWEEPS,
 OPTION_BOX_CHECK_EVERY, OPTION_ANDERSON_DEPTH) = range(7)

Csc = tuple[np.ndarray, np.ndarray, np.ndarray]  # (indptr, indices, data)


@njit(cache=True)
def _csr_product(A: Csc, x: np.ndarray) -> np.ndarray:
    """A x over A's CSR arrays, each row summed in its stored order (as SciPy does)."""
    indptr, indices, data = A
    rows = indptr.size - 1
    product = np.zeros(rows)
    for i in range(rows):
        total = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            total += data[k] * x[indices[k]]
        product[i] = total
    return product


@njit(cache=True)
def coulomb_residual(W: Csc, q: np.ndarray, diag_N: np.ndarray, mu: np.ndarray, scale: float,
                     impulses: np.ndarray) -> float:
    """``||F||_inf / scale`` of r = (l_N, l_T), F the natural map of Coulomb's law.

    F with the De Saxce term: per contact, with ``u = W r + q`` (W's CSC product),
    ``u^ = (u_N + mu |u_T|, u_T)``, ``x = d r - u^`` (d = diag W_NN) and P_K the projection
    on ``|x_T| <= mu x_N``, ``F = d r - P_K(x)``; as ``friction_metrics.residual``.

    Parameters
    ----------
    W : Csc
        W's CSC arrays, shape (2n, 2n), order ``(l_N, l_T)``.
    q : np.ndarray
        The free velocity, shape (2n,).
    diag_N : np.ndarray
        d = diag W_NN, shape (n,).
    mu : np.ndarray
        The friction coefficients, shape (n,).
    scale : float
        The problem's residual scale (a velocity).
    impulses : np.ndarray
        r, shape (2n,).

    Returns
    -------
    float
        The relative Coulomb residual; 0 without contacts.
    """
    n = diag_N.size
    if n == 0:
        return 0.0
    u = kernel._matvec(W, impulses) + q
    worst = 0.0
    for k in range(n):
        m, d = mu[k], diag_N[k]
        u_tangential = u[n + k]
        x_normal = d * impulses[k] - (u[k] + m * abs(u_tangential))
        x_tangential = d * impulses[n + k] - u_tangential
        magnitude = abs(x_tangential)
        if magnitude <= m * x_normal:  # inside the cone
            p_normal, p_tangential = x_normal, x_tangential
        elif m * magnitude <= -x_normal:  # in the polar cone
            p_normal, p_tangential = 0.0, 0.0
        else:  # onto the nearer edge
            edge = (x_normal + m * magnitude) / (1.0 + m * m)
            p_normal, p_tangential = edge, edge * m * np.sign(x_tangential)
        worst = max(worst, max(abs(d * impulses[k] - p_normal),
                               abs(d * impulses[n + k] - p_tangential)))
    return worst / scale


@njit(cache=True)
def _diagonal(A: Csc) -> np.ndarray:
    """The diagonal of a square matrix given by its CSR (or CSC) arrays; 0 where unstored."""
    indptr, indices, data = A
    rows = indptr.size - 1
    diagonal = np.zeros(rows)
    for i in range(rows):
        for k in range(indptr[i], indptr[i + 1]):
            if indices[k] == i:
                diagonal[i] += data[k]
    return diagonal


@njit(cache=True)
def _block(W: Csc, first_row: int, end_row: int, first_column: int) -> Csc:
    """CSR arrays of ``W[first_row:end_row, first_column:first_column + n]``, n = W's size / 2.

    W is symmetric with sorted indices, so its CSC arrays are its CSR arrays: each row of the
    block is the part of a column of W in the column range, in stored order (as SciPy's
    slicing of W's CSR form gives it).
    """
    indptr, indices, data = W
    n = (indptr.size - 1) // 2
    rows = end_row - first_row
    starts = np.zeros(rows + 1, dtype=np.int32)
    for i in range(rows):
        count = 0
        for k in range(indptr[first_row + i], indptr[first_row + i + 1]):
            if first_column <= indices[k] < first_column + n:
                count += 1
        starts[i + 1] = starts[i] + count
    columns = np.empty(starts[rows], dtype=np.int32)
    entries = np.empty(starts[rows])
    for i in range(rows):
        place = starts[i]
        for k in range(indptr[first_row + i], indptr[first_row + i + 1]):
            if first_column <= indices[k] < first_column + n:
                columns[place] = indices[k] - first_column
                entries[place] = data[k]
                place += 1
    return starts, columns, entries


@njit(cache=True)
def _normal_solve(W_NN: Csc, W_NT: Csc, q: np.ndarray, diag_N: np.ndarray,
                  tangential: np.ndarray, start: np.ndarray, order_above: int,
                  max_work: float, normal_options: np.ndarray):
    """(l_N >= 0, pi-robust's linear solves, certified) of the normal QP for ``tangential``."""
    n = diag_N.size
    b_N = q[:n] + _csr_product(W_NT, tangential)
    impulses, converged, _, solves, _, _, certified = kernel.envelope_pi_robust(
        W_NN[0], W_NN[1], W_NN[2], b_N, diag_N, start, order_above, max_work, normal_options)
    return np.maximum(impulses, 0.0), solves, converged and certified


@njit(cache=True)
def _box_solve(W_TT: Csc, diag_T: np.ndarray, colour_order: np.ndarray, W_TN: Csc,
               q: np.ndarray, mu: np.ndarray, normal: np.ndarray, tangential: np.ndarray,
               tolerance: float, max_sweeps: int, check_every: int):
    """(l_T, sweeps, counted) of the friction box QP for ``normal`` from ``tangential``;
    ``counted`` is False when every box is empty (l_T = 0, no solve)."""
    n = normal.size
    linear = q[n:] + _csr_product(W_TN, normal)
    upper = mu * np.maximum(normal, 0.0)
    lower = -upper
    if not np.any(upper > lower):
        return np.zeros(n), 0, False
    x, sweeps, _ = box_gauss_seidel(W_TT[0], W_TT[1], W_TT[2], linear, lower, upper, diag_T,
                                    colour_order, tangential, tolerance, max_sweeps,
                                    check_every)
    return np.minimum(np.maximum(x, lower), upper), sweeps, True


@njit(cache=True)
def staggered_pi_robust(W: Csc, W_NN: Csc, q: np.ndarray, diag_N: np.ndarray, mu: np.ndarray,
                        scale: float, warm_start: np.ndarray, normal_options: np.ndarray,
                        max_work: float, loop_options: np.ndarray):
    """Staggered projections with pi-robust inside (module docstring), in one compiled call.

    W's blocks of the two QPs are read from W's own arrays (:func:`_block`), and the loop's
    options come packed in one array (:func:`loop_settings`): a call's arguments are few,
    since each costs the dispatcher time to type.

    Parameters
    ----------
    W : Csc
        W's CSC arrays, shape (2n, 2n), indices sorted: for the Coulomb residual, and, W being
        symmetric (so its CSC arrays are its CSR arrays), the coupling blocks W_NT, W_TN and
        the tangential block W_TT (the box QP's P), whose diagonal and whose contacts in a
        stable order of their greedy colours
        (``qpbench.solvers.colouring.colour_order``) the box sweeps take.
    W_NN : Csc
        The normal block's CSC arrays (pi-robust's Q).
    q : np.ndarray
        The free velocity, shape (2n,).
    diag_N : np.ndarray
        The diagonal of W_NN, shape (n,).
    mu : np.ndarray
        The friction coefficients, shape (n,).
    scale : float
        The problem's residual scale (a velocity).
    warm_start : np.ndarray
        r, shape (2n,), or an empty array for none.
    normal_options : np.ndarray
        pi-robust's kernel options at the inner accuracy, packed.
    max_work : float
        The kernel's most work for one envelope factorization; above it, it declines.
    loop_options : np.ndarray
        The loop's options (``LoopSettings.packed``): the Coulomb residual to reach, the most
        rounds, the contacts above which the kernel reorders a wide envelope, the inner
        accuracy (the box residual to reach is it times ``scale``), the most sweeps of each
        box solve, the sweeps between the box residual's checks and Anderson acceleration's
        depth (the Python loop's ``depth``; 0 for the plain loop).

    Returns
    -------
    r : np.ndarray
        The answer, shape (2n,), or empty when no round gave one.
    residual : float
        Its Coulomb residual.
    ending : int
        How the call ended: CONVERGED, MAX_OUTER, WARM_START or FALLBACK.
    rounds : int
        The rounds done.
    iterations : int
        The inner iterations (pi-robust's linear solves and box sweeps).
    solves : int
        The inner solves.
    returned : int
        Which answer: BEST_ITERATE, FINAL_NORMAL_SOLVE or GIVEN_START.
    """
    n = diag_N.size
    eps = loop_options[OPTION_EPS]
    max_outer = int(loop_options[OPTION_MAX_OUTER])
    order_above = int(loop_options[OPTION_ORDER_ABOVE])
    box_tolerance = loop_options[OPTION_INNER_EPS] * scale
    box_max_sweeps = int(loop_options[OPTION_BOX_MAX_SWEEPS])
    box_check_every = int(loop_options[OPTION_BOX_CHECK_EVERY])
    depth = int(loop_options[OPTION_ANDERSON_DEPTH])
    W_NT, W_TN = _block(W, 0, n, n), _block(W, n, 2 * n, 0)
    W_TT = _block(W, n, 2 * n, n)
    diag_T = _diagonal(W_TT)
    sweep_order = colour_order(W_TT[0], W_TT[1])
    normal, tangential = np.zeros(n), np.zeros(n)
    best, best_residual = np.zeros(0), np.inf
    iterations, solves = 0, 0
    if warm_start.size == 2 * n and np.all(np.isfinite(warm_start)):
        normal, tangential = np.maximum(warm_start[:n], 0.0), warm_start[n:].copy()
        best = warm_start.copy()
        best_residual = coulomb_residual(W, q, diag_N, mu, scale, warm_start)
        if best_residual <= eps:
            return best, best_residual, WARM_START, 0, 0, 0, GIVEN_START
    ending = MAX_OUTER
    rounds = 0
    start = tangential  # l_T that the next round starts from
    starts, answers = np.empty((depth + 1, n)), np.empty((depth + 1, n))  # the mixing's history
    kept, last_step = 0, np.inf
    while rounds < max_outer:
        rounds += 1
        normal, used, ok = _normal_solve(W_NN, W_NT, q, diag_N, start, normal,
                                         order_above, max_work, normal_options)
        if not ok:
            return best, best_residual, FALLBACK, rounds, iterations, solves, BEST_ITERATE
        iterations += used
        solves += 1
        tangential, sweeps, counted = _box_solve(W_TT, diag_T, sweep_order, W_TN, q, mu,
                                                 normal, start, box_tolerance,
                                                 box_max_sweeps, box_check_every)
        if counted:
            iterations += sweeps
            solves += 1
        impulses = np.concatenate((normal, tangential))
        residual = coulomb_residual(W, q, diag_N, mu, scale, impulses)
        if residual < best_residual:
            best, best_residual = impulses, residual
        if residual <= eps:
            ending = CONVERGED
            break
        start, kept, last_step = anderson.next_start(starts, answers, kept, last_step, start,
                                                     tangential)
    if best.size == 0:  # no finite residual in any round: the Python loop says so
        return best, best_residual, FALLBACK, rounds, iterations, solves, BEST_ITERATE
    # one normal solve given the best friction impulse (SCISim: "to prevent penetration")
    final_normal, used, ok = _normal_solve(W_NN, W_NT, q, diag_N, best[n:], best[:n],
                                           order_above, max_work, normal_options)
    if not ok:
        return best, best_residual, FALLBACK, rounds, iterations, solves, BEST_ITERATE
    iterations += used
    solves += 1
    final = np.concatenate((final_normal, best[n:]))
    final_residual = coulomb_residual(W, q, diag_N, mu, scale, final)
    if final_residual <= best_residual or final_residual <= eps:
        best, best_residual, returned = final, final_residual, FINAL_NORMAL_SOLVE
    else:
        returned = BEST_ITERATE
    if best_residual <= eps:
        ending = CONVERGED
    return best, best_residual, ending, rounds, iterations, solves, returned


_warm = False


class LoopSettings(NamedTuple):
    """The ``staggered`` row's options at one level, for the compiled loop."""

    packed: np.ndarray  # the loop's options, at the places named above
    inner_eps: float  # the accuracy of the inner solves
    max_outer: int  # the most rounds


def loop_settings(eps: float) -> LoopSettings:
    """The ``staggered`` row's options at level ``eps`` for the compiled loop.

    Read once per level and per state of the row (``accuracy.overridden`` may change it for
    a measurement): its entries are relative to the problem's scale (none reads it), so one
    reading serves every problem; the box residual to reach is the inner accuracy times the
    scale, formed in the loop.

    Parameters
    ----------
    eps : float
        The Coulomb residual to reach.

    Returns
    -------
    LoopSettings
        The packed options, the inner accuracy and the most rounds. Cached: callers must not
        change them.
    """
    return _loop_settings(eps, tuple(accuracy.OPTIONS[ROW].items()))


@functools.lru_cache(maxsize=64)
def _loop_settings(eps: float, row: tuple) -> LoopSettings:
    """:func:`loop_settings` for the row's entries ``row`` (the cache's key)."""
    options = accuracy.options_for(ROW, eps)
    inner_eps = float(options["inner_accuracy"])
    box_options = accuracy.options_for(ROW, inner_eps)
    packed = np.array([eps, options["max_outer"], pi_robust_call.ORDERING_ABOVE, inner_eps,
                       box_options["box_max_sweeps"], box_options["box_check_every"],
                       options["anderson_depth"]], dtype=float)
    return LoopSettings(packed=packed, inner_eps=inner_eps, max_outer=int(options["max_outer"]))


def warm_up() -> None:
    """Compiles (or loads from numba's cache) the loop once in this process.

    It runs on one ball sliding on the floor, outside any clock.
    """
    global _warm
    if _warm:
        return
    kernel.warm_up()
    anderson.warm_up()
    one = (np.array([0, 1], dtype=np.int32), np.array([0], dtype=np.int32), np.array([1.0]))
    W = (np.array([0, 1, 2], dtype=np.int32), np.array([0, 1], dtype=np.int32),
         np.array([1.0, 1.0]))
    settings = loop_settings(1e-8)
    normal = pi_robust_call.settings_for(settings.inner_eps)
    staggered_pi_robust(W, one, np.array([-1.0, 0.5]), np.ones(1), np.array([0.5]), 1.0,
                        np.empty(0), normal.kernel, normal.compiled_work_limit,
                        settings.packed)
    _warm = True


def solve(problem: FrictionalProblem, eps: float, warm_start: np.ndarray | None
          ) -> SolverOutput | None:
    """pi-robust/staggered in one compiled call, or None when the Python loop must run.

    The options are the accuracy table's rows of ``staggered`` (:func:`loop_settings`) and of
    ``pi-robust`` at the inner accuracy (``pi_robust_call.settings_for``), as in the Python loop.
    The Python loop runs instead with no contacts, more than pi-robust's ``compiled_limit``,
    on ``FALLBACK``, or when the residual lies at eps and qpbench's own metric decides
    otherwise.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem to solve.
    eps : float
        The Coulomb residual to reach.
    warm_start : np.ndarray or None
        A guess of r = (l_N, l_T); None for none.

    Returns
    -------
    SolverOutput or None
        r, status, the Coulomb residual's test as claim, the inner iterations and the
        loop's facts in ``info``; None when the Python loop must run.
    """
    settings = loop_settings(eps)
    normal = pi_robust_call.settings_for(settings.inner_eps)
    diag_N = problem.diag_N
    if not 0 < diag_N.size <= normal.compiled_limit:
        return None
    start = NO_START if warm_start is None else np.asarray(warm_start, dtype=float).ravel()
    impulses, residual, ending, rounds, iterations, solves, returned = staggered_pi_robust(
        pi_robust_call.csc_arrays(problem.W), pi_robust_call.csc_arrays(problem.normal.Q),
        problem.q, diag_N, problem.mu, problem.scale, start, normal.kernel,
        normal.compiled_work_limit, settings.packed)
    if ending == FALLBACK:
        return None
    if abs(residual - eps) <= 1e-9 * eps and (  # at the line: qpbench's own metric decides
            (friction_metrics.residual(problem, impulses) <= eps) != (residual <= eps)):
        return None
    if ending == CONVERGED:
        status = "converged"
    elif ending == WARM_START:
        status = "warm start already converged"
    else:
        status = f"max_outer ({settings.max_outer}) reached"
    return SolverOutput(impulses=impulses, status=status, claimed_success=bool(residual <= eps),
                        iterations=int(iterations) if solves else None,
                        info={"outer_iterations": int(rounds), "inner_solves": int(solves),
                              "residual": float(residual), "returned": RETURNED[returned],
                              "compiled": True})
