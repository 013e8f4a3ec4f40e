"""pi-robust: policy iteration made to converge on singular Q.

Plain policy iteration is Newton's method on ``min(D l, Q l + b) = 0`` (D = diag Q):
it cycles, and its policy systems are singular when Q is. pi-robust keeps the
policy-iteration step (solve the policy's block, switch every infeasible contact)
and adds published safeguards:

1. Proximal point (Rockafellar, "Monotone operators and the proximal point
   algorithm", SIAM J. Control Optim. 14(5), 1976). Each prox step solves the LCP
   with the positive definite ``H = Q + rho D`` and ``q = b - rho D z`` around the
   centre z, then moves z to its solution, so no policy block ``H_FF`` is
   singular. At a step's solution qpbench's residual is
   ``rho ||D (l - z)||_inf / scale`` on the active contacts. The null space of Q
   (where l is not unique and v+ does not change) is left alone. rho falls by
   ``rho_decrease`` when ``stall_steps`` prox steps in a row fail to cut the
   residual by ``stall_ratio``. A prox step that keeps its policy and does not
   cut the residual so, and whose change of l is as long as the step before's
   (a drift, not a contraction: ``DRIFT_RATIO``), instead moves the centre along
   that change to the first free contact that reaches zero (at most
   ``drift_steps`` times a run: a wrong policy on a singular Q_FF drifts along
   its null space by about ``D^-1 r / rho`` a step, r the part of -b_F outside
   its range; see ``pi_robust_kernel.prox._extrapolate_drift``).
2. Block principal pivoting with a backup rule (Judice and Pires, Comput. Oper.
   Res. 21(5), 1994; Kim and Park, SIAM J. Sci. Comput. 33(6), 2011) for each
   prox LCP: the policy-iteration exchange of every infeasible contact while
   their number falls, at most ``backup_steps`` full exchanges that do not
   reduce it. Then (``active_set``) a primal active-set method on the same prox
   step, as the QP ``min x^T H x / 2 + q^T x, x >= 0`` (Lawson and Hanson 1974;
   Nocedal and Wright 2006, section 16.5), from the feasible part of the best
   exchange's x: contacts fixed or freed per solve, the objective never
   rising, so it cannot cycle where block pivoting does (nearly singular H,
   as on grids at small rho).
3. A safe path when that is slow: policy iteration gets ``pi_budget`` linear solves
   (enough on boxes, cradles, K3/K4 and grids). Then a Mehrotra interior point with
   Gondzio's centrality correctors (``qpbench.solvers.lcp_interior``, Jacobi-scaled,
   ``ipm_iters`` at most) runs, and every iterate whose residual is below
   ``finish_below`` (then ten times lower than the last try) is handed back to the prox
   policy iteration for ``finish_budget`` solves from its policy ``{w < D l}``: near the
   solution that finds the exact active set in one or two solves (an active-set polish),
   so the answer is not an interior point's approximation. On sparse problems (more than
   ``dense_limit`` contacts, each policy solve a sparse factorization) without a warm
   start, or from one that is far (one solve of its policy leaves more than
   ``NEAR_START_INFEASIBLE`` contacts infeasible, as a settling pile's previous impulses
   do), the order is reversed: the interior point first, on the proximal LCP
   ``Q + 1e-10 D`` (which, unlike a dense pile's own, has a strictly feasible point), its Newton
   systems solved over the degrees of freedom through ``L = M^-1/2 G`` when fewer of
   them move than there are contacts (``lcp_interior.FactoredNormalMatrix``), its
   iterates handed on from a residual of ``finish_below`` where the policy blocks are
   updated rather than factored (``pi_robust_blocks``; prox weight ``UPDATED_FINISH_RHO``),
   elsewhere from ``FIRST_FINISH_BELOW``, ended at its floor or a stall, then policy
   iteration from its best iterate (see :func:`pi_robust`).
4. Lemke's method (``lemke_limit`` contacts at most) if all else failed.

Factorizations: dense (``dense_limit`` contacts at most; ``fixed_order_dense``: Cholesky,
blocks of up to 64 by Gaussian elimination, products too summed in an order that does not
depend on the CPU) or sparse (``qpbench.solvers.sparse_cholesky``: CHOLMOD, else SuperLU), a
sparse block over the degrees of freedom its contacts move when there are fewer of them than
contacts (``lcp_interior.WoodburyFactor``, refined once; ``pi_robust_blocks``); the last
factors of policy blocks are kept, so prox steps on a settled policy cost triangular solves
only, and a block a few contacts from the last one is made by a low-rank update of its
factor.

Up to ``compiled_limit`` contacts the whole algorithm runs first as one compiled call
(``qpbench.solvers.pi_robust_kernel``: numba, contacts in reverse Cuthill-McKee order,
envelope Cholesky factors, a start improved by ``start_sweeps`` projected Gauss-Seidel
sweeps, new factors that copy the rows they share with a kept one; on a few contacts, block
pivoting on a dense copy of Q first, ``pi_robust_kernel.dense``; where contacts are parallel,
the problem without the looser of each group first, ``pi_robust_kernel.parallel``); its
answer is reported
when a rounding bound or qpbench's own residual confirms it, otherwise (or when a factor
fails) this Python path runs, and the time of both counts. When the kernel has run policy
iteration and the interior point in full and failed, Lemke's method goes first: the Python
path (the same methods again) runs only when Lemke neither solves the problem nor ends on a
ray whose direction proves that it has no solution (``lemke.no_solution_certified``: y >= 0,
Q y = 0, b^T y < 0, checked in floating point, not taken on trust). The kernel is loaded
from numba's cache (compiled once, ``cache=True``) by :func:`prepare`, which the harness calls
before it starts any clock; ``qpbench.solvers.pi_robust_call`` reads this solver's row of the
accuracy table and makes the calls of the kernel.
Converged means qpbench's ``residual(l) <= tol`` (confirmed with qpbench's own metric);
otherwise it reports failure and returns its best l.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from qpbench.problem import metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import dot
from qpbench.solvers import fixed_order_dense, lemke, relaxation
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.lcp_interior import (
    NOT_TRIED,
    FactoredNormalMatrix,
    NormalMatrix,
    interior_point,
    jacobi_scaled,
)
from qpbench.solvers.pi_robust_blocks import UPDATE_CONTACTS, BlockSolver
from qpbench.solvers.pi_robust_call import (
    NAME,
    Settings,
    kernel_call,
    kernel_into,
    settings_for,
)
from qpbench.solvers.pi_robust_kernel import call as kernel_calls
from qpbench.solvers.pi_robust_kernel import entry as kernel_entry
from qpbench.solvers.pi_robust_kernel.constants import COUPLED, DRIFT_RATIO
from qpbench.solvers.registry import register

# the proximal weight of the interior point where it runs first (Jacobi-scaled units: Q~ has a
# unit diagonal); its answer then misses the LCP by at most 1e-10 max(l~). A larger weight
# leaves a residual floor above the finest accuracy level on dense piles; a smaller one makes
# the Newton matrix nearly singular again near the end (docs/notes/pi-robust.md)
INTERIOR_PROX = 1e-10
# where the interior point runs first, its iterates are handed to policy iteration from this
# residual on (or from the accuracy table's finish_below, when lower): a try far from the
# solution mostly fails, each costing factorizations; waiting for the floor leaves the answer
# the interior point's own (docs/notes/pi-robust.md)
FIRST_FINISH_BELOW = 1e-6
# where the policy blocks are updated rather than factored (BlockSolver.updatable), a finish
# costs little, so the first interior point hands its iterates on from the accuracy table's
# finish_below, with this many solves, at this prox weight (when below the table's rho): an
# interior iterate foretells the free contacts of the LCP itself, which a prox step at a small
# weight nearly is; much smaller, and the blocks' Woodbury form loses the digits it needs
# (docs/notes/pi-robust.md)
UPDATED_FINISH_BUDGET = 30
UPDATED_FINISH_RHO = 1e-9
# a sparse problem's warm start is followed by policy iteration only when one solve of its
# policy leaves at most this many contacts infeasible (then the next block is an update of
# this one); else the interior point runs as from a cold start: a start a step off (a settling
# pile) leaves hundreds, and policy iteration from it takes hundreds of prox steps, each a
# factorization, where the interior point takes about ten (docs/notes/pi-robust.md)
NEAR_START_INFEASIBLE = UPDATE_CONTACTS


def _policy_solve(blocks: BlockSolver, policy: np.ndarray, rho: float, q: np.ndarray
                  ) -> np.ndarray:
    """x_F with ``(Q_FF + rho D_F) x_F = -q_F`` on the policy's free contacts F, zero
    elsewhere."""
    index = np.flatnonzero(policy)
    x = np.zeros(policy.size)
    if index.size:
        x[index] = blocks.solve(policy, index, rho, -q[index])
    return x


def _inner_lcp(lcp: Lcp, blocks: BlockSolver, policy: np.ndarray, rho: float, q: np.ndarray,
               tol_l: np.ndarray, tol_w: float, backup_steps: int, budget: int,
               active_set: bool = True) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Solve one prox step's LCP(Q + rho D, q) by block principal pivoting from ``policy``.

    Every infeasible contact (free with ``x_i < -tol_l[i]``, or fixed with a slack below
    ``-tol_w``) is exchanged while their number falls, with at most ``backup_steps`` exchanges
    in a row that do not cut it (Judice and Pires, Comput. Oper. Res. 21(5), 1994); then, when
    ``active_set``, :func:`_primal_active_set` goes on from the feasible part of the best
    exchange's x, else the step stops unsolved. Returns (x, final policy, linear solves,
    solved), within ``budget`` solves.
    """
    shift = rho * lcp.safe_diag
    best = lcp.n + 1
    backup = backup_steps
    solves = 0
    x = best_x = np.zeros(lcp.n)
    while solves < budget:
        x = _policy_solve(blocks, policy, rho, q)
        solves += 1
        y = lcp.times(x) + shift * x + q
        infeasible = (policy & (x < -tol_l)) | (~policy & (y < -tol_w))
        count = int(np.count_nonzero(infeasible))
        if count == 0:
            return x, policy, solves, True
        policy = policy.copy()
        if count < best:
            best, backup, best_x = count, backup_steps, x
            policy ^= infeasible
        elif backup > 0:
            backup -= 1
            policy ^= infeasible
        elif active_set:
            x, policy, used, solved = _primal_active_set(
                lcp, blocks, rho, q, np.maximum(best_x, 0.0), tol_l, tol_w, budget - solves)
            return x, policy, solves + used, solved
        else:
            break  # the caller has a safer path than the active-set method
    return x, policy, solves, False


def _violators_to_free(lcp: Lcp, violated: np.ndarray, gradient: np.ndarray,
                       all_of_them: bool) -> np.ndarray:
    """The violating fixed contacts that the active-set method frees (the kernel's
    ``_free_violators``): in order of the most negative ``gradient_i / sqrt(D_i)``, the first
    only unless ``all_of_them``, else each one with no ``Q_ij > COUPLED sqrt(D_i D_j)`` to a
    contact i freed before it."""
    scaled = gradient / np.sqrt(lcp.safe_diag)
    candidates = np.flatnonzero(violated)
    candidates = candidates[np.argsort(scaled[candidates], kind="stable")]
    chosen = np.zeros(lcp.n, dtype=bool)
    if not all_of_them:
        chosen[candidates[:1]] = True
        return chosen
    coupled = np.zeros(lcp.n, dtype=bool)
    Q = lcp.Q
    for i in candidates:
        if coupled[i]:
            continue
        chosen[i] = True
        columns = Q.indices[Q.indptr[i]:Q.indptr[i + 1]]
        couplings = Q.data[Q.indptr[i]:Q.indptr[i + 1]]
        coupled[columns[couplings > COUPLED * np.sqrt(lcp.safe_diag[i]
                                                      * lcp.safe_diag[columns])]] = True
    return chosen


def _primal_active_set(lcp: Lcp, blocks: BlockSolver, rho: float, q: np.ndarray,
                       feasible: np.ndarray, tol_l: np.ndarray, tol_w: float, budget: int
                       ) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Solve LCP(Q + rho D, q) by the primal active-set method, from a feasible point.

    The method and its rules are those of ``pi_robust_kernel.active_set._primal_active_set``.
    It starts from ``feasible`` (>= 0) with the free set ``{feasible > 0}`` and makes at most
    ``budget`` linear solves. Returns (x, free set, solves, solved).
    """
    shift = rho * lcp.safe_diag

    def objective(x: np.ndarray) -> tuple[float, np.ndarray]:
        """(f(x), H x + q)."""
        gradient = lcp.times(x) + shift * x + q
        return dot(x, 0.5 * (gradient - q) + q), gradient

    free = feasible > 0.0
    value_now, _ = objective(feasible)
    value_at_last_freeing = np.inf
    solves = 0
    while solves < budget:
        solution = _policy_solve(blocks, free, rho, q)
        solves += 1
        blocked = free & (solution < -tol_l)
        if blocked.any():
            projected = np.maximum(solution, 0.0)
            value, _ = objective(projected)
            if value < value_now:
                feasible, value_now, free = projected, value, free & (solution > 0.0)
                continue
            reach = np.full(lcp.n, np.inf)
            reach[blocked] = feasible[blocked] / (feasible[blocked] - solution[blocked])
            blocking = int(np.argmin(reach))
            feasible = np.where(free, np.maximum(
                feasible + reach[blocking] * (solution - feasible), 0.0), 0.0)
            free = free & ~((solution < 0.0) & (feasible == 0.0))
            feasible[blocking], free[blocking] = 0.0, False
            value_now, _ = objective(feasible)
            continue
        feasible = np.maximum(solution, 0.0)
        value_now, gradient = objective(feasible)
        violated = ~free & (gradient < -tol_w)
        if not violated.any():
            return feasible, free, solves, True
        free = free | _violators_to_free(lcp, violated, gradient,
                                         all_of_them=value_now < value_at_last_freeing)
        value_at_last_freeing = value_now
    return feasible, free, solves, False


def _prox_policy_iteration(lcp: Lcp, blocks: BlockSolver, centre: np.ndarray,
                           policy: np.ndarray, tol: float, rho: float, rho_min: float,
                           rho_decrease: float, stall_ratio: float, stall_steps: int,
                           backup_steps: int, active_set: bool, drift_steps: int, budget: int
                           ) -> tuple[np.ndarray, bool, str, int, float]:
    """Prox steps from ``centre`` and ``policy`` within ``budget`` linear solves:
    (best l, converged, status, solves, best residual)."""
    tol_l, tol_w = _tolerances(lcp, tol)
    res = lcp.residual(centre)
    best, best_res = centre, res
    solves = stalls = drifts = 0
    drift = np.zeros(lcp.n)
    status = f"policy iteration budget ({budget} solves) spent"
    while solves < budget:
        q = lcp.b - rho * lcp.safe_diag * centre
        try:
            x, policy, used, solved = _inner_lcp(lcp, blocks, policy, rho, q, tol_l, tol_w,
                                                 backup_steps, budget - solves,
                                                 active_set)
        except np.linalg.LinAlgError:
            status = "block factorization failed"
            rho /= rho_decrease
            if rho > 1.0:
                break
            continue
        solves += used
        settled = used == 1 and drifts < drift_steps  # the step kept its policy
        drift, previous_drift = x - centre, drift
        centre = np.maximum(x, 0.0)
        w = lcp.w(centre)
        previous, res = res, lcp.residual_of(centre, w)
        if res < best_res:
            best, best_res = centre, res
        if lcp.converged(centre, tol, w):
            return centre, True, "converged", solves, res
        if not solved:
            break
        stalls = stalls + 1 if res > stall_ratio * previous else 0
        if settled and stalls > 0:
            drifted = _drifted(centre, drift, previous_drift, policy)
            if drifted is not None:
                centre, drifts, stalls = drifted, drifts + 1, 0
                continue
        if stalls >= stall_steps:
            stalls = 0
            if rho * rho_decrease < rho_min:
                status = "prox steps stalled at rho_min"
                break
            rho *= rho_decrease
    return best, False, status, solves, best_res


def _start_is_near(lcp: Lcp, blocks: BlockSolver, start: np.ndarray, policy: np.ndarray,
                   tol: float, rho: float) -> bool:
    """Whether policy iteration should go on from ``start``: one prox step's solve of its
    ``policy`` (``{w <= D l}``) around it (:func:`_inner_lcp` with a budget of one solve)
    leaves at most ``NEAR_START_INFEASIBLE`` contacts infeasible; not when that block's
    factorization fails. The block's factor is kept, so policy iteration's first solve from
    there costs triangular solves only."""
    try:
        _, exchanged, _, _ = _inner_lcp(lcp, blocks, policy, rho,
                                        lcp.b - rho * lcp.safe_diag * start,
                                        *_tolerances(lcp, tol), backup_steps=0, budget=1,
                                        active_set=False)
    except np.linalg.LinAlgError:
        return False
    return int(np.count_nonzero(exchanged != policy)) <= NEAR_START_INFEASIBLE


def _tolerances(lcp: Lcp, tol: float) -> tuple[np.ndarray, float]:
    """(tol_l, tol_w): how far below zero a free contact's l and a fixed one's w may be for
    a prox step's LCP to count as solved, a tenth of qpbench's ``tol`` in its units."""
    return 0.1 * tol * lcp.scale / lcp.safe_diag, 0.1 * tol * lcp.scale


def _drifted(centre: np.ndarray, drift: np.ndarray, previous_drift: np.ndarray,
             policy: np.ndarray) -> np.ndarray | None:
    """The centre moved along a settled prox step's drift d when it is a drift (its ratio
    ``g = d_F . d'_F / d'_F . d'_F`` to the step before's d' at least ``DRIFT_RATIO``):
    ``max(z_F + t d_F, 0)``, t the step to the first free contact that reaches zero (set to
    exactly 0) or ``g / (1 - g)`` when smaller; None when it does not move (as
    ``pi_robust_kernel.prox._extrapolate_drift``)."""
    along = dot(drift[policy], previous_drift[policy])
    before = dot(previous_drift[policy], previous_drift[policy])
    if not along >= DRIFT_RATIO * before or before == 0.0:
        return None
    falling = policy & (drift < 0.0) & (centre > 0.0)
    reach = np.full(centre.size, np.inf)
    reach[falling] = centre[falling] / -drift[falling]
    step = along / (before - along) if along < before else np.inf
    blocking = int(np.argmin(reach))
    if falling[blocking] and reach[blocking] <= step:
        step = reach[blocking]
    else:
        blocking = -1
    if step == np.inf:
        return None
    moved = np.where(policy, np.maximum(centre + step * drift, 0.0), centre)
    if blocking >= 0:
        moved[blocking] = 0.0
    return moved


def pi_robust(lcp: Lcp, blocks: BlockSolver, start: np.ndarray,
              tol: float, rho: float, rho_min: float, rho_decrease: float, stall_ratio: float,
              stall_steps: int, backup_steps: int, active_set: bool, drift_steps: int,
              pi_budget: int,
              finish_budget: int,
              finish_below: float, ipm_iters: int, lemke_limit: int,
              lemke_answer: LemkeAnswer | None = None
              ) -> tuple[np.ndarray, bool, str, int, dict]:
    """Solve the LCP by pi-robust's Python path.

    Parameters
    ----------
    lcp : Lcp
        The LCP (dense or sparse).
    blocks : BlockSolver
        The policy blocks' solver and its kept factors.
    start : np.ndarray
        The start, l >= 0.
    tol, rho, rho_min, rho_decrease, stall_ratio, stall_steps, backup_steps, active_set, drift_steps
        The prox safeguards (module docstring, item 1 and 2).
    pi_budget, finish_budget : int
        Linear solves of the first policy iteration and of each finishing one.
    finish_below : float
        The interior point's residual below which its iterates are finished.
    ipm_iters : int
        The interior point's iterations at most.
    lemke_limit : int
        The most contacts on which Lemke's method runs.
    lemke_answer : LemkeAnswer or None
        Lemke's answer when it has run on this LCP already.

    Returns
    -------
    tuple
        (l, converged, status, linear solves, info).

    Notes
    -----
    Dense LCPs, and sparse ones from a near warm start (``start`` not 0,
    :func:`_start_is_near`): policy iteration from ``start``, then the interior point, its
    iterates finished by policy iteration (on sparse ones, the proximal interior point as
    below). Sparse ones (above ``dense_limit`` contacts, where each policy solve is a sparse
    factorization) from a cold or far start: the interior point first, proximal
    (``INTERIOR_PROX``, so that dense piles, which have no strictly feasible point, do not
    stall it), its Newton matrix over the degrees of freedom when fewer of them move than
    there are contacts (:func:`_normal_matrix`), ended at its floor or a stall, then policy
    iteration from its best iterate. When all of that fails, Lemke's method
    (:func:`_lemke_fallback`).
    """
    w = lcp.w(start)
    if lcp.converged(start, tol, w):
        return start, True, "converged", 0, {"path": "start"}
    settings = {"tol": tol, "rho": rho, "rho_min": rho_min, "rho_decrease": rho_decrease,
                "stall_ratio": stall_ratio, "stall_steps": stall_steps,
                "backup_steps": backup_steps, "active_set": active_set,
                "drift_steps": drift_steps}
    finishing_solves = [0]

    def finish(candidate: np.ndarray, candidate_w: np.ndarray, budget: int = finish_budget,
               finish_rho: float = rho) -> np.ndarray | None:
        result, done, _, used, _ = _prox_policy_iteration(
            lcp, blocks, candidate, candidate_w < lcp.diag * candidate, budget=budget,
            **{**settings, "rho": finish_rho})
        finishing_solves[0] += used
        return result if done else None

    def first_finish(candidate: np.ndarray, candidate_w: np.ndarray) -> np.ndarray | None:
        """The first interior point's finish: from ``finish_below`` with
        ``UPDATED_FINISH_BUDGET`` solves at the prox weight ``UPDATED_FINISH_RHO`` where the
        policy's blocks are updated rather than factored (each try is cheap), else from
        ``FIRST_FINISH_BELOW`` as any finish."""
        if blocks.updatable(candidate_w < lcp.diag * candidate):
            return finish(candidate, candidate_w, max(finish_budget, UPDATED_FINISH_BUDGET),
                          min(rho, UPDATED_FINISH_RHO))
        if lcp.residual_of(candidate, candidate_w) > FIRST_FINISH_BELOW:
            return NOT_TRIED
        return finish(candidate, candidate_w)

    def interior(first: bool) -> tuple[np.ndarray | None, bool, int, str, str]:
        """(the interior point's l, None when a factorization failed; converged; its
        iterations; the failure; what its Newton matrix runs over). ``first`` (sparse, cold):
        proximal (``INTERIOR_PROX``), finished from each iterate below
        ``finish_below`` whose policy blocks are updated, else below
        ``FIRST_FINISH_BELOW`` (``first_finish``), then from its floor or a stall; else
        plain, finished from each iterate below ``finish_below``."""
        normal = _normal_matrix(lcp)
        try:
            impulses, converged, iterations, _ = interior_point(
                lcp, normal.lcp, normal.root, normal, tol, ipm_iters,
                first_finish if first else finish, finish_below, end_on_stall=first,
                prox=INTERIOR_PROX if first else 0.0, stall_finish=finish)
        except np.linalg.LinAlgError as error:
            return None, False, 0, f"interior point failed: {error}", normal.over
        return impulses, converged, iterations, "", normal.over

    start_policy = w <= lcp.diag * start
    sparse_warm = not lcp.dense and bool(np.any(start))
    near = sparse_warm and _start_is_near(lcp, blocks, start, start_policy, tol, rho)
    warm_solves = int(sparse_warm)  # the solve that tested the start's nearness
    if lcp.dense or near:
        first, converged, status, solves, _ = _prox_policy_iteration(
            lcp, blocks, start, start_policy, budget=pi_budget, **settings)
        warm_solves += solves
        if converged:
            return first, True, "converged", warm_solves, {
                "path": "policy iteration", **blocks.counts()}
    if lcp.dense:
        impulses, converged, iterations, failure, over = interior(first=False)
        path, solves = "interior point + policy iteration", warm_solves
    else:  # cold, or from a warm start that is far (or whose policy iteration failed)
        impulses, converged, iterations, failure, over = interior(first=True)
        first = start if impulses is None else impulses
        status = "converged" if converged else "interior point stalled or out of iterations"
        path, solves = "interior point + policy iteration", 0
        if not converged:  # policy iteration from the interior point's best
            first, converged, _, solves, _ = _prox_policy_iteration(
                lcp, blocks, first, lcp.w(first) <= lcp.diag * first, budget=pi_budget,
                **settings)
            impulses, path = first, "interior point, then policy iteration"
        solves += warm_solves
        if near:
            path = "policy iteration from the start, then " + path
    status = failure or status
    solves += iterations + finishing_solves[0]
    info = {"path": path, "first_status": status, "interior_iterations": iterations,
            "interior_newton_matrix": over, **blocks.counts()}
    if converged:
        return impulses, True, "converged", solves, info
    if lemke_answer is None:
        lemke_answer = lemke_of(lcp, tol, lemke_limit)
    candidates = [first] if impulses is None else [impulses, first]
    return _lemke_fallback(lcp, tol, lemke_answer, candidates, solves, info)


def _normal_matrix(lcp: Lcp) -> NormalMatrix | FactoredNormalMatrix:
    """The interior point's Newton matrix of the Jacobi-scaled ``lcp``: over the degrees of
    freedom through Q's factor L = M^-1/2 G when fewer of them move than there are contacts
    (and the LCP is sparse), else over the contacts."""
    scaled, root = jacobi_scaled(lcp)
    factored = None
    if not lcp.dense and isinstance(lcp.problem, ImpactProblem):
        factored = FactoredNormalMatrix.when_smaller(scaled, root, lcp.problem.L)
    return factored or NormalMatrix(scaled, root)


class LemkeAnswer(NamedTuple):
    """What Lemke's method gives on an LCP (``qpbench.solvers.lemke.lemke``); ``on_ray``: it
    ended on a secondary ray whose direction proves that the LCP has no solution
    (``lemke.RAY_TERMINATION``; a ray without that proof is ``lemke.UNCERTIFIED_RAY``)."""

    impulses: np.ndarray
    converged: bool
    status: str
    pivots: int
    on_ray: bool


def lemke_of(lcp: Lcp, tol: float, lemke_limit: int) -> LemkeAnswer | None:
    """Lemke's method on the LCP, within ``50 n + 100`` pivots; None above ``lemke_limit``.

    Parameters
    ----------
    lcp : Lcp
        The LCP of n contacts (densified by Lemke's tableau).
    tol : float
        qpbench's relative residual to reach.
    lemke_limit : int
        The most contacts on which Lemke's method runs.

    Returns
    -------
    LemkeAnswer or None
        Lemke's l, whether it converged, its status, its pivots and whether it ended on a
        certified ray; None when the LCP has more than ``lemke_limit`` contacts.
    """
    if lcp.n > lemke_limit:
        return None
    impulses, converged, status, pivots = lemke.lemke(lcp, tol, max_pivots=50 * lcp.n + 100)
    return LemkeAnswer(impulses, converged, status, pivots, status == lemke.RAY_TERMINATION)


def _lemke_fallback(lcp: Lcp, tol: float, lemke_answer: LemkeAnswer | None,
                    candidates: list[np.ndarray], solves: int, info: dict
                    ) -> tuple[np.ndarray, bool, str, int, dict]:
    """pi-robust's ending once its own methods have failed (their best l: ``candidates``):
    Lemke's l when it converged, else the l of least residual among the candidates and
    Lemke's, converged when qpbench's residual says so; Lemke's ending in ``info["path"]``
    (``lemke_answer`` None: it did not run, above ``lemke_limit`` contacts).
    (l, converged, status, linear solves and pivots, info)."""
    if lemke_answer is not None:
        info["path"] = f"lemke fallback: {lemke_answer.status}"
        if lemke_answer.converged:
            return lemke_answer.impulses, True, "converged by lemke fallback", \
                solves + lemke_answer.pivots, info
        candidates = [*candidates, lemke_answer.impulses]
    best = min(candidates, key=lcp.residual)
    if lcp.converged(best, tol):
        return best, True, "converged (best of the interior point's iterates)", solves, info
    return best, False, "interior point did not converge", solves, info


def _unconfirmed(problem: ImpactProblem, settings: Settings, answer: tuple,
                 warm_start: np.ndarray | None) -> SolverOutput | None:
    """The output for the compiled kernel's ``answer`` that it did not certify itself: when
    qpbench's residual confirms it, that answer; when it failed in full,
    :func:`_after_kernel_failure`; else None (the caller then runs the Python path)."""
    confirmed = _confirmed(problem, settings, answer[0], answer)
    if confirmed is None and _failed_in_full(answer):
        return _after_kernel_failure(problem, settings, answer, warm_start)
    return confirmed


def _confirmed(problem: ImpactProblem, settings: Settings, impulses: np.ndarray,
               answer: tuple) -> SolverOutput | None:
    """``impulses`` as the output of the kernel's ``answer`` to ``problem`` (its l, converged,
    path, solves, interior iterations, factorizations, certified), when the answer converged
    and the kernel's rounding bound or qpbench's residual of l on ``problem`` confirms it;
    else None."""
    envelope = kernel_entry
    kernel_impulses, converged, path, solves, interior, factorizations, certified = answer
    if not converged:
        return None
    # the kernel's residual is qpbench's formula in the same summation order; accepted when
    # even a worst-case rounding difference keeps it within tol, else qpbench's own metric
    if not (certified or metrics.residual(problem, kernel_impulses) <= settings.python["tol"]):
        return None
    info: dict = {"path": envelope.PATH_NAMES[path], "compiled": True,
                  "factorizations": factorizations,
                  "confirmed_by": "rounding bound" if certified else "qpbench residual"}
    if path % envelope.PATH_PARALLEL_DROPPED == envelope.PATH_INTERIOR:
        info["interior_iterations"] = interior
    # (impulses, status, claimed_success, iterations, backend_times, info): positional, with
    # no keyword arguments and no default factory, on the path every solve takes
    return SolverOutput(impulses, "converged", True, solves, {}, info)


def _failed_in_full(answer: tuple) -> bool:
    """The kernel's ``answer`` (l, converged, path, ...) is a failure after policy iteration
    and then the interior point both ran (path ``PATH_NONE``)."""
    return not answer[1] and answer[2] == kernel_entry.PATH_NONE


def _after_kernel_failure(problem: ImpactProblem, settings: Settings, answer: tuple,
                          warm_start: np.ndarray | None) -> SolverOutput:
    """pi-robust's output on ``problem`` once the kernel's ``answer`` (l, converged, path,
    solves, interior iterations, factorizations, certified) has failed in full. Lemke's method
    runs first (``lemke_limit`` contacts at most). When it converges, or ends on a certified ray
    (the problem has no solution), the kernel's l or Lemke's, whichever has the lower residual,
    is the answer, with the kernel's solves and Lemke's pivots as its iterations. Otherwise the
    Python path runs from ``warm_start`` (in ``problem``'s variables) as it would have, Lemke's
    answer standing in for its own last step: the Python path repeats the kernel's methods in
    other arithmetic, and on extreme mass ratios that has solved what the kernel did not."""
    lcp = Lcp.of(problem, dense_limit=settings.dense_limit)
    tol, lemke_limit = settings.python["tol"], settings.python["lemke_limit"]
    kernel_impulses, _, _, solves, interior, factorizations, _ = answer
    lemke_answer = lemke_of(lcp, tol, lemke_limit)
    if lemke_answer is not None and (lemke_answer.converged or lemke_answer.on_ray):
        info = {"compiled": True, "factorizations": factorizations,
                "interior_iterations": interior}  # "path": Lemke's ending
        impulses, converged, status, iterations, info = _lemke_fallback(
            lcp, tol, lemke_answer, [kernel_impulses], solves, info)
        return output(impulses, converged, status, iterations, **info)
    impulses, converged, status, iterations, info = pi_robust(
        lcp, BlockSolver(lcp), lcp.start(warm_start), lemke_answer=lemke_answer,
        **settings.python)
    info["compiled"] = "failed in full; Lemke's method, then the Python path"
    return output(impulses, converged, status, iterations, **info)


def solve_relaxed(problem: FrictionalProblem, eps: float,
                  warm_start: np.ndarray | None = None) -> SolverOutput | None:
    """pi-robust on Anitescu's relaxation of ``problem`` (posed: ``problem.relaxed()``).

    Its warm start is mapped in, swept contact by contact (each contact's (z+, z-) as one
    block) and its answer r mapped back inside the one compiled call
    (``pi_robust_kernel.entry.relaxed_pi_robust``); when that fails in full,
    :func:`_after_kernel_failure` on the relaxed problem, mapped back; None when the compiled
    path declines, so that the ccp twin's general path runs.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    eps : float
        qpbench's accuracy level.
    warm_start : np.ndarray or None, optional
        A start r = (l_N, l_T) of 2n entries; None (the default) starts from zero.

    Returns
    -------
    SolverOutput or None
        The answer r on ``problem``, its status, solves and path; None when the relaxed
        problem has no contacts or more than ``compiled_limit``, when a factor fails, or when
        the kernel's answer is neither confirmed nor a failure in full.
    """
    relaxed = problem.relaxed()
    settings = settings_for(eps)
    contacts = relaxed.n_contacts
    if not 0 < contacts <= settings.compiled_limit:
        return None
    try:
        answer = kernel_call(kernel_entry.relaxed_pi_robust, relaxed, settings,
                             warm_start, problem.mu)
    except np.linalg.LinAlgError:
        return None
    confirmed = _confirmed(relaxed, settings, answer[0], answer[1:])
    if confirmed is not None:
        confirmed.info["relaxed_contacts"] = contacts
    elif _failed_in_full(answer[1:]):
        confirmed = relaxation.mapped_back(problem, _after_kernel_failure(
            relaxed, settings, answer[1:], relaxation.relaxed_start(problem, warm_start)))
    return confirmed


def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    """Solve an impact problem by pi-robust: the compiled kernel first, else the Python path.

    Parameters
    ----------
    problem : ImpactProblem
        The posed problem.
    eps : float
        The accuracy level.
    warm_start : np.ndarray or None
        A start l.

    Returns
    -------
    SolverOutput
        The answer, its status, linear solves and path.

    Notes
    -----
    Up to the accuracy table's ``compiled_limit`` contacts the compiled kernel
    (``pi_robust_kernel.entry.envelope_pi_robust``, called through its narrow entry
    ``pi_robust_into``, past numba's dispatcher where the arrays allow: ``kernel_into``)
    runs straight from the posed problem. Its answer is returned when its rounding bound
    certifies it (the usual case, built here without further calls, as :func:`_confirmed`
    would build it) or when qpbench's residual confirms it (:func:`_unconfirmed`); otherwise
    the Python path (:func:`pi_robust`) runs.
    """
    settings = settings_for(eps)
    # b's size is the number of contacts (b is posed; n_contacts would read G's shape)
    n = problem.b.size
    compiled = 0 < n <= settings.compiled_limit
    if compiled:
        kernel = kernel_entry
        try:
            impulses, answer = kernel_into(problem, settings, warm_start)
        except np.linalg.LinAlgError:
            answer = None
        if answer is not None:
            converged, path, solves, interior, factorizations, certified = answer
            if certified and path % kernel.PATH_PARALLEL_DROPPED != kernel.PATH_INTERIOR:
                # the usual answer, certified by the kernel's rounding bound: _confirmed's
                # output, without the call
                return SolverOutput(impulses, "converged", True, solves, {},
                                    {"path": kernel.PATH_NAMES[path], "compiled": True,
                                     "factorizations": factorizations,
                                     "confirmed_by": "rounding bound"})
            confirmed = _unconfirmed(problem, settings, (impulses, *answer), warm_start)
            if confirmed is not None:
                return confirmed
    lcp = Lcp.of(problem, dense_limit=settings.dense_limit)
    impulses, converged, status, iterations, info = pi_robust(
        lcp, BlockSolver(lcp), lcp.start(warm_start), **settings.python)
    if compiled:
        info["compiled"] = "declined or not confirmed; Python path"
    return output(impulses, converged, status, iterations, **info)


def prepare() -> None:
    """Loads the compiled kernel and the Python path's fixed-order dense functions from numba's
    cache (compiling them once), outside any clock."""
    kernel_calls.warm_up()
    fixed_order_dense.warm_up()


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=True, prepare=prepare, own_stopping_rule=True,
                    description="proximal policy iteration, block pivoting, Lemke fallback"))
