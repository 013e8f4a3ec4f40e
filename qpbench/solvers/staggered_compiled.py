"""pi-robust/staggered with its whole loop compiled (numba): one call per solve.

The loop of ``qpbench.solvers.friction_staggered.staggered``, round for round, with pi-robust
inside: the normal QP by pi-robust's compiled kernel
(``qpbench.solvers.pi_robust_kernel.entry.envelope_pi_robust``) and the friction box QP by the
compiled projected Gauss-Seidel (``qpbench.solvers.box_sweeps``), so that no round returns to
Python. Each round, from (l_N, l_T):

1. ``b_N = q_N + W_NT l_T``; l_N = pi-robust on LCP(W_NN, b_N) at the inner accuracy, started
   from the last l_N, then ``max(l_N, 0)``;
2. the box QP ``(W_TT, q_T + W_TN l_N, -mu l_N, mu l_N)`` (every box empty: l_T = 0) by
   ``box_sweeps.box_gauss_seidel`` from the last l_T, as the Python loop's box solver, until
   the box residual is at most ``inner accuracy * scale`` (checked every ``box_check_every``
   sweeps);
3. qpbench's Coulomb residual (:func:`coulomb_residual`, the formula of
   ``qpbench.problem.friction_metrics``); the best iterate is kept; stop at ``<= eps`` or after
   ``max_outer`` rounds.

Then one normal solve given the best l_T, kept when it is no worse (or meets eps). Products
are summed in SciPy's order (CSC products column by column, CSR products row by row). A
normal solve that does not converge, or converges without the kernel's rounding certificate,
ends the call with ``FALLBACK``: the caller then runs the Python loop from the start, and the
time of both counts. The options are the accuracy table's rows of ``staggered`` and
``pi-robust``, as in the Python loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import accuracy, pi_robust
from qpbench.solvers.base import SolverOutput
from qpbench.solvers.box_sweeps import box_gauss_seidel
from qpbench.solvers.colouring import colour_order
from qpbench.solvers.pi_robust_kernel import entry as kernel

# how a call ends
CONVERGED, MAX_OUTER, WARM_START, FALLBACK = 0, 1, 2, 3
# which answer it returns
BEST_ITERATE, FINAL_NORMAL_SOLVE, GIVEN_START = 0, 1, 2
RETURNED = ("best iterate", "final normal solve", "warm start")

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
def staggered_pi_robust(W: Csc, W_NN: Csc, W_NT: Csc, W_TN: Csc, W_TT: Csc,
                        q: np.ndarray, diag_N: np.ndarray, diag_T: np.ndarray, mu: np.ndarray,
                        scale: float, colour_order: np.ndarray, warm_start: np.ndarray,
                        eps: float, max_outer: int, normal_options: np.ndarray,
                        order_above: int, max_work: float, box_tolerance: float,
                        box_max_sweeps: int, box_check_every: int):
    """Staggered projections with pi-robust inside (module docstring), in one compiled call.

    Parameters
    ----------
    W : Csc
        W's CSC arrays, shape (2n, 2n), for the Coulomb residual.
    W_NN : Csc
        The normal block's CSC arrays (pi-robust's Q).
    W_NT, W_TN : Csc
        The coupling blocks' CSR arrays.
    W_TT : Csc
        The tangential block's CSR arrays, indices sorted (the box QP's P).
    q : np.ndarray
        The free velocity, shape (2n,).
    diag_N, diag_T : np.ndarray
        The diagonals of W_NN and W_TT, shape (n,).
    mu : np.ndarray
        The friction coefficients, shape (n,).
    scale : float
        The problem's residual scale (a velocity).
    colour_order : np.ndarray
        The contacts in a stable order of their greedy colours on W_TT.
    warm_start : np.ndarray
        r, shape (2n,), or an empty array for none.
    eps : float
        The Coulomb residual to reach.
    max_outer : int
        The most rounds.
    normal_options : np.ndarray
        pi-robust's kernel options at the inner accuracy, packed.
    order_above : int
        Above this many contacts the kernel reorders a wide envelope.
    max_work : float
        The kernel's most work for one envelope factorization; above it, it declines.
    box_tolerance : float
        The box residual to reach (inner accuracy times scale).
    box_max_sweeps : int
        The most sweeps of each box solve.
    box_check_every : int
        Sweeps between the box residual's checks.

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
    while rounds < max_outer:
        rounds += 1
        normal, used, ok = _normal_solve(W_NN, W_NT, q, diag_N, tangential, normal,
                                         order_above, max_work, normal_options)
        if not ok:
            return best, best_residual, FALLBACK, rounds, iterations, solves, BEST_ITERATE
        iterations += used
        solves += 1
        tangential, sweeps, counted = _box_solve(W_TT, diag_T, colour_order, W_TN, q, mu,
                                                 normal, tangential, box_tolerance,
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


def warm_up() -> None:
    """Compiles (or loads from numba's cache) the loop once in this process.

    It runs on one ball sliding on the floor, outside any clock.
    """
    global _warm
    if _warm:
        return
    kernel.warm_up()
    one = (np.array([0, 1], dtype=np.int32), np.array([0], dtype=np.int32), np.array([1.0]))
    W = (np.array([0, 1, 2], dtype=np.int32), np.array([0, 1], dtype=np.int32),
         np.array([1.0, 1.0]))
    zero = (np.array([0, 0], dtype=np.int32), np.zeros(0, dtype=np.int32), np.zeros(0))
    options = kernel.options_of(accuracy.options_for(pi_robust.NAME, 1e-9))
    staggered_pi_robust(W, one, zero, zero, one, np.array([-1.0, 0.5]), np.ones(1), np.ones(1),
                        np.array([0.5]), 1.0, np.zeros(1, dtype=np.int64), np.empty(0), 1e-8,
                        10, options, 64, 1e7, 1e-9, 100, 10)
    _warm = True


def solve(problem: FrictionalProblem, eps: float, warm_start: np.ndarray | None,
          options: dict[str, Any], box_options: dict[str, Any]) -> SolverOutput | None:
    """pi-robust/staggered in one compiled call, or None when the Python loop must run.

    The Python loop runs instead with no contacts, more than pi-robust's
    ``compiled_limit``, on ``FALLBACK``, or when the residual lies at eps and qpbench's
    own metric decides otherwise.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem to solve.
    eps : float
        The Coulomb residual to reach.
    warm_start : np.ndarray or None
        A guess of r = (l_N, l_T); None for none.
    options : dict[str, Any]
        The ``staggered`` row's options at eps (``max_outer``, ``inner_accuracy``).
    box_options : dict[str, Any]
        The same row at the inner accuracy (``box_max_sweeps``, ``box_check_every``).

    Returns
    -------
    SolverOutput or None
        r, status, the Coulomb residual's test as claim, the inner iterations and the
        loop's facts in ``info``; None when the Python loop must run.
    """
    n = problem.n_contacts
    inner_eps = options["inner_accuracy"]
    settings = pi_robust.settings_for(inner_eps)
    if not 0 < n <= settings.compiled_limit:
        return None
    W_TT = problem.W_TT
    W_TT.sort_indices()
    sweep_order = colour_order(W_TT.indptr, W_TT.indices)
    start = np.empty(0) if warm_start is None else np.asarray(warm_start, dtype=float).ravel()
    impulses, residual, ending, rounds, iterations, solves, returned = staggered_pi_robust(
        pi_robust.csc_arrays(problem.W), pi_robust.csc_arrays(problem.normal.Q),
        _arrays(problem.W_NT), _arrays(problem.W_TN), _arrays(W_TT), problem.q,
        problem.diag_N, W_TT.diagonal(), problem.mu, problem.scale, sweep_order, start,
        eps, int(options["max_outer"]), settings.kernel, pi_robust.ORDERING_ABOVE,
        settings.compiled_work_limit, inner_eps * problem.scale,
        int(box_options["box_max_sweeps"]), int(box_options["box_check_every"]))
    if ending == FALLBACK:
        return None
    if abs(residual - eps) <= 1e-9 * eps and (  # at the line: qpbench's own metric decides
            (friction_metrics.residual(problem, impulses) <= eps) != (residual <= eps)):
        return None
    status = {CONVERGED: "converged", WARM_START: "warm start already converged"}.get(
        ending, f"max_outer ({options['max_outer']}) reached")
    return SolverOutput(impulses=impulses, status=status, claimed_success=bool(residual <= eps),
                        iterations=int(iterations) if solves else None,
                        info={"outer_iterations": int(rounds), "inner_solves": int(solves),
                              "residual": float(residual), "returned": RETURNED[returned],
                              "compiled": True})


def _arrays(matrix: Any) -> Csc:
    """(indptr, indices, data) of a SciPy CSR or CSC matrix, as stored."""
    return matrix.indptr, matrix.indices, matrix.data
