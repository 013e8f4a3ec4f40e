"""Where pi-robust's solves go on grids, and what its factorizations would cost in another factor.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_refactor_work.py [--quick]
[--search-cap N]`` (a few minutes; ``--quick``: two problems per group).

Each problem (the fork's 5x5 dumps, generated grids of 7 to 20 balls a side, seeds 100 on)
is solved at 1e-8 by the proximal policy iteration of pi-robust's Python path, on the dense
LCP, from the start that the kernel sweeps first (``start_sweeps`` projected Gauss-Seidel
sweeps). Every policy block it solves is recorded, in order. The script prints per group:

- the linear solves, and those of them that the primal active-set method made (the rest are
  block pivoting's);
- the multiply-adds of factoring that sequence of blocks, each from the one before, in two
  factors: the kernel's envelope factor in reverse Cuthill-McKee order, which keeps the rows
  before the first changed contact and deletes the rows of at most ``UPDATE_FIXED`` newly
  fixed contacts by plane rotations (``sum w_i`` per deleted row over the rows after it) and
  otherwise refactors ``sum w_i^2 / 2`` over the rows from the first change on; and a sparse
  factor in CHOLMOD's approximate minimum degree order that refactors only the columns whose
  elimination-tree descendants changed (a changed contact's ancestors), ``c_j^2 / 2`` for a
  column of c_j entries (Davis, "Direct Methods for Sparse Linear Systems", SIAM 2006,
  sections 4.1 and 4.7; a fixed contact's row and column are unit ones in both);
- each factor's multiply-adds when every block is factored whole, for scale.

``--time`` then times the same sequences, block by block, as each factor would make them
(the fastest of 7 replays less that of 7 replays of the Python bookkeeping between blocks
alone, on this machine): the kernel's own envelope functions
(``_factor_rows`` from the first changed row, ``_delete_contact``, the substitutions), and an
up-looking sparse factor written here (:func:`sparse_refactor`, Davis 2006, section 4.7) that
recomputes only the rows of the changed contacts' ancestors, a fixed contact's row a unit row,
each block then solved once.

``--search-cap N`` replaces the active-set method's step to the first blocking contact by a
projected search (More and Toraldo, "On the solution of large quadratic programming problems
with bound constraints", SIAM J. Optim. 1(1), 1991): along ``max(x + t (s - x), 0)`` on the
free contacts, to the first minimum of the objective, through at most N breakpoints (each
fixes the contacts that reach zero there); N = 1 is the method as it is. The Python path
stands in for the kernel (same rules, other factors): its solves are close to the kernel's,
not equal.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from numba import njit
from pi_robust_common import ACCURACY, ROOT, option, quick_flag, words
from pi_robust_sparse_factor import column_solve
from sksparse.cholmod import analyze

from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy, pi_robust
from qpbench.solvers.lcp import Lcp
from qpbench.solvers.pi_robust_blocks import BlockSolver
from qpbench.solvers.pi_robust_kernel.constants import UPDATE_FIXED
from qpbench.solvers.pi_robust_kernel.entry import _gauss_seidel
from qpbench.solvers.pi_robust_kernel.factor import (
    _backward_substitution,
    _delete_contact,
    _factor_rows,
)
from qpbench.solvers.pi_robust_kernel.ordering import (
    _envelope_widths,
    _upper,
    reverse_cuthill_mckee,
)

RHO_KERNEL = 1e-5  # the accuracy table's first prox weight, which most blocks are factored at
PROX_KEYS = ("tol", "rho", "rho_min", "rho_decrease", "stall_ratio", "stall_steps",
             "backup_steps", "active_set", "drift_steps")


def groups(quick: bool) -> dict[str, list[ImpactProblem]]:
    """The problem groups of the module docstring, posed as ``lcp``."""
    count = 2 if quick else 6
    dumps = sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))
    found = {"fork 5x5 dumps": [import_dump(path) for path in dumps[:2 * count]]}
    for size in (7, 10, 14, 20):
        found[f"grid {size}"] = [generate("grid", size, seed=100 + k)[0] for k in range(count)]
    for problems in found.values():
        for problem in problems:
            pose(problem, "lcp")
    return found


def swept_start(problem: ImpactProblem, sweeps: int) -> np.ndarray:
    """``sweeps`` projected Gauss-Seidel sweeps on LCP(Q, b) from zero, in the posed order, by
    the kernel's own sweeps (:func:`.entry._gauss_seidel`)."""
    Q = problem.Q
    impulses = np.zeros(problem.b.size)
    _gauss_seidel((Q.indptr, Q.indices, Q.data), problem.b, problem.diag_Q, impulses,
                  np.empty(problem.b.size), sweeps)
    return impulses


def projected_search(lcp: Lcp, rho: float, q: np.ndarray, start: np.ndarray,
                     solution: np.ndarray, free: np.ndarray, cap: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The first minimum of ``f(x) = x^T H x / 2 + q^T x`` (``H = Q + rho D``) along
    ``max(start + t (solution - start), 0)`` over the free contacts, t in [0, 1], through at
    most ``cap`` breakpoints, and the contacts clamped to zero on the way."""
    Q = np.asarray(lcp.op)
    shift = rho * lcp.safe_diag
    direction = np.where(free, solution - start, 0.0)
    x = start.copy()
    gradient = Q @ x + shift * x + q
    curved = Q @ direction + shift * direction
    falling = np.flatnonzero(free & (direction < 0.0) & (solution < 0.0))
    breaks = start[falling] / -direction[falling]
    order = np.argsort(breaks, kind="stable")
    t, passed = 0.0, 0
    clamped = np.zeros(lcp.n, dtype=bool)
    while True:
        slope, curvature = gradient @ direction, direction @ curved
        if slope >= 0.0:
            break
        following = breaks[order[passed]] if passed < order.size else 1.0
        step = -slope / curvature if curvature > 0.0 else np.inf
        if t + step <= following:
            x += step * direction
            break
        x += (following - t) * direction
        gradient += (following - t) * curved
        t = following
        if passed >= order.size or passed >= cap:
            break
        while passed < order.size and breaks[order[passed]] <= following:
            j = falling[order[passed]]
            x[j], clamped[j] = 0.0, True
            curved -= direction[j] * Q[:, j]
            curved[j] -= direction[j] * shift[j]
            direction[j] = 0.0
            passed += 1
        if passed >= cap:
            break
    return np.maximum(np.where(free, x, 0.0), 0.0), clamped


def active_set_with_search(cap: int):
    """pi-robust's Python active-set method with :func:`projected_search` in place of the
    step to the first blocking contact (``cap`` 1: that step)."""
    def method(lcp: Lcp, blocks: BlockSolver, rho: float, q: np.ndarray, feasible: np.ndarray,
               tol_l: np.ndarray, tol_w: float, budget: int):
        shift = rho * lcp.safe_diag

        def objective(x: np.ndarray) -> tuple[float, np.ndarray]:
            gradient = lcp.op @ x + shift * x + q
            return float(x @ (0.5 * (gradient - q) + q)), gradient

        free = feasible > 0.0
        value_now, _ = objective(feasible)
        value_at_last_freeing = np.inf
        for solves in range(1, budget + 1):
            solution = pi_robust._policy_solve(blocks, free, rho, q)
            if (free & (solution < -tol_l)).any():
                projected = np.maximum(solution, 0.0)
                value, _ = objective(projected)
                if value < value_now:
                    feasible, value_now, free = projected, value, free & (solution > 0.0)
                    continue
                # (f falls along the segment to s, so the search passes the first breakpoint)
                feasible, clamped = projected_search(lcp, rho, q, feasible, solution, free,
                                                     cap)
                free = free & ~clamped & ~((solution < 0.0) & (feasible == 0.0))
                value_now, _ = objective(feasible)
                continue
            feasible = np.maximum(solution, 0.0)
            value_now, gradient = objective(feasible)
            violated = ~free & (gradient < -tol_w)
            if not violated.any():
                return feasible, free, solves, True
            free = free | pi_robust._violators_to_free(
                lcp, violated, gradient, all_of_them=value_now < value_at_last_freeing)
            value_at_last_freeing = value_now
        return feasible, free, budget, False
    return method


def policy_blocks(problem: ImpactProblem, cap: int
                  ) -> tuple[list[np.ndarray], int, int, bool]:
    """(the free sets of every policy solve in order, solves, active-set solves, converged) of
    one solve of ``problem`` by the Python path's policy iteration from the swept start."""
    settings = pi_robust.settings_for(ACCURACY)
    lcp = Lcp.of(problem, dense_limit=problem.b.size)
    blocks: list[np.ndarray] = []
    in_active_set = [0]
    solve_block, active_set = pi_robust._policy_solve, pi_robust._primal_active_set
    method = active_set if cap == 1 else active_set_with_search(cap)

    def recorded(blocks_solver: BlockSolver, policy: np.ndarray, rho: float, q: np.ndarray):
        blocks.append(policy.copy())
        return solve_block(blocks_solver, policy, rho, q)

    def counted(*arguments):
        answer = method(*arguments)
        in_active_set[0] += answer[2]
        return answer

    pi_robust._policy_solve, pi_robust._primal_active_set = recorded, counted
    try:
        start = swept_start(problem,
                            accuracy.options_for("pi-robust", ACCURACY)["start_sweeps"])
        _, converged, _, solves, _ = pi_robust._prox_policy_iteration(
            lcp, BlockSolver(lcp), start, lcp.w(start) <= lcp.diag * start,
            budget=settings.python["pi_budget"],
            **{key: settings.python[key] for key in PROX_KEYS})
    finally:
        pi_robust._policy_solve, pi_robust._primal_active_set = solve_block, active_set
    return blocks, solves, in_active_set[0], converged


def rcm_ordered(Q: sp.csc_matrix) -> tuple[np.ndarray, sp.csc_matrix]:
    """(the kernel's reverse Cuthill-McKee order of Q, Q in that order with sorted indices)."""
    n = Q.shape[0]
    order = reverse_cuthill_mckee(Q.indptr.astype(np.int64), Q.indices.astype(np.int64), n)
    P = Q[order][:, order].tocsc()
    P.sort_indices()
    return order, P


def amd_ordered(Q: sp.csc_matrix) -> tuple[np.ndarray, sp.csc_matrix, sp.csc_matrix,
                                           np.ndarray]:
    """(CHOLMOD's approximate minimum degree order of Q, Q in that order, the pattern of its
    Cholesky factor L (sorted, the diagonal first in each column), L's elimination tree: each
    column's parent, the first row below its diagonal, -1 at a root)."""
    n = Q.shape[0]
    order = analyze((Q + sp.identity(n)).tocsc(), mode="simplicial",
                    ordering_method="amd").P()
    P = Q[order][:, order].tocsc()
    P.sort_indices()
    lower = analyze(P + sp.identity(n), mode="simplicial", ordering_method="natural").cholesky(
        P + n * abs(P).max() * sp.identity(n)).L().tocsc()
    lower.sort_indices()
    parent = np.array([lower.indices[lower.indptr[j] + 1]
                       if lower.indptr[j + 1] > lower.indptr[j] + 1 else -1 for j in range(n)],
                      dtype=np.int64)
    return order, P, lower, parent


def envelope_work(Q: sp.csc_matrix, blocks: list[np.ndarray]) -> tuple[float, float]:
    """(multiply-adds of the envelope factor over ``blocks``, each kept from the one before as
    the kernel keeps it; the same with each block factored whole)."""
    n = Q.shape[0]
    order, P = rcm_ordered(Q)
    lower = sp.tril(P).tocsr()
    kept = whole = 0.0
    previous = None
    for policy in blocks:
        free = policy[order]
        widths = np.zeros(n)
        for i in np.flatnonzero(free):
            columns = lower.indices[lower.indptr[i]:lower.indptr[i + 1]]
            columns = columns[free[columns]]
            widths[i] = i - columns.min() + 1 if columns.size else 1
        whole += float((widths ** 2).sum() / 2)
        changed = np.flatnonzero(free != previous) if previous is not None else np.arange(n)
        first = changed.min() if changed.size else n
        if previous is not None and 0 < changed.size <= UPDATE_FIXED \
                and not (free & ~previous).any():
            kept += changed.size * float(widths[first:].sum())  # rows deleted by rotations
        else:
            kept += float((widths[first:] ** 2).sum() / 2)
        previous = free
    return kept, whole


def sparse_work(Q: sp.csc_matrix, blocks: list[np.ndarray]) -> tuple[float, float]:
    """(multiply-adds of a sparse factor in approximate minimum degree order over ``blocks``,
    refactoring the elimination-tree ancestors of each block's changed contacts; the same
    with each block factored whole)."""
    n = Q.shape[0]
    order, _, lower, parent = amd_ordered(Q)
    counts = np.diff(lower.indptr).astype(float)
    kept = whole = 0.0
    previous = None
    for policy in blocks:
        free = policy[order]
        work = np.where(free, counts ** 2 / 2, 0.0)
        whole += float(work.sum())
        if previous is None:
            affected = np.ones(n, dtype=bool)
        else:
            affected = np.zeros(n, dtype=bool)
            for j in np.flatnonzero(free != previous):
                while j >= 0 and not affected[j]:
                    affected[j] = True
                    j = parent[j]
        kept += float(work[affected].sum())
        previous = free
    return kept, whole


@njit(cache=True)
def sparse_refactor(colptr: np.ndarray, rowind: np.ndarray, rowptr: np.ndarray,
                    colind: np.ndarray, place: np.ndarray, A: tuple, shift: np.ndarray,
                    free: np.ndarray, parent: np.ndarray, changed: np.ndarray,
                    values: np.ndarray, dense: np.ndarray, marks: np.ndarray) -> None:
    """Refactor the rows of L (stored by columns, the diagonal first) that ``changed``
    contacts' elimination-tree ancestors hold, for ``L L^T = A_FF + diag(shift_F)`` with the
    fixed contacts' rows and columns unit ones. Row k solves ``L_(:k,:k) l = A_(:k,k)`` over
    its pattern (``colind[rowptr[k]:rowptr[k + 1]]``, rising; ``place``: where each entry
    sits in ``values``), the rows before it being L's already (Davis 2006, section 4.7)."""
    indptr, indices, data = A
    for contact in changed:
        j = contact
        while j >= 0 and not marks[j]:
            marks[j] = True
            j = parent[j]
    for k in range(parent.size):
        if not marks[k]:
            continue
        marks[k] = False
        if not free[k]:
            for p in range(rowptr[k], rowptr[k + 1]):
                values[place[p]] = 0.0
            values[colptr[k]] = 1.0
            continue
        diagonal = shift[k]
        for p in range(indptr[k], indptr[k + 1]):
            if indices[p] < k and free[indices[p]]:
                dense[indices[p]] = data[p]
            elif indices[p] == k:
                diagonal += data[p]
        for p in range(rowptr[k], rowptr[k + 1]):
            j = colind[p]
            entry = dense[j] / values[colptr[j]]
            dense[j] = 0.0
            for q in range(colptr[j] + 1, colptr[j + 1]):
                if rowind[q] >= k:
                    break
                dense[rowind[q]] -= values[q] * entry
            values[place[p]] = entry
            diagonal -= entry * entry
        if not diagonal > 0.0:
            raise np.linalg.LinAlgError("not positive definite")
        values[colptr[k]] = np.sqrt(diagonal)


def sparse_replay(Q: sp.csc_matrix, shift: np.ndarray) -> Callable:
    """A replay of policy blocks by :func:`sparse_refactor` in CHOLMOD's approximate minimum
    degree order: ``replay(blocks, rhs)`` factors each block from the one before and solves
    it once, returning the last solution (in the posed order, zero off its block)."""
    n = Q.shape[0]
    order, P, lower, parent = amd_ordered(Q)
    colptr, rowind = lower.indptr.astype(np.int64), lower.indices.astype(np.int64)
    below = sorted((rowind[q], j, q) for j in range(n) for q in range(colptr[j] + 1,
                                                                      colptr[j + 1]))
    rowptr = np.searchsorted([k for k, _, _ in below], np.arange(n + 1)).astype(np.int64)
    colind = np.array([j for _, j, _ in below], dtype=np.int64)
    place = np.array([q for _, _, q in below], dtype=np.int64)
    A = (P.indptr.astype(np.int64), P.indices.astype(np.int64), P.data.copy())
    ordered_shift = RHO_KERNEL * shift[order]
    values, dense, marks = np.zeros(colptr[-1]), np.zeros(n), np.zeros(n, dtype=np.bool_)

    def replay(blocks: list[np.ndarray], rhs: np.ndarray, work: bool = True) -> np.ndarray:
        previous = None
        for policy in blocks:
            free = policy[order]
            changed = np.arange(n) if previous is None else np.flatnonzero(free != previous)
            x = np.where(free, rhs[order], 0.0)
            if work:
                sparse_refactor(colptr, rowind, rowptr, colind, place, A, ordered_shift, free,
                                parent, changed, values, dense, marks)
                column_solve(colptr[:-1], colptr[1:], rowind, values, x)
            previous = free
        answer = np.zeros(n)
        answer[order] = x
        return answer
    return replay


def envelope_replay(Q: sp.csc_matrix, shift: np.ndarray) -> Callable:
    """:func:`sparse_replay` by the kernel's envelope factor in reverse Cuthill-McKee order:
    the rows before the first changed contact kept, the rows of at most ``UPDATE_FIXED``
    newly fixed contacts deleted (:func:`.factor._delete_contact`), else the rows from the
    first change refactored (:func:`.factor._factor_rows`)."""
    n = Q.shape[0]
    order, P = rcm_ordered(Q)
    A = (P.indptr.astype(np.int64), P.indices.astype(np.int64), P.data.copy())
    upper = _upper(A)
    offsets = np.empty(n + 1, np.int64)
    _envelope_widths(A, offsets)
    values, position, none = np.empty(offsets[-1]), np.full(n, -1, np.int64), np.empty(0)
    cosines, sines, ordered_shift = np.empty(n), np.empty(n), shift[order].copy()

    def replay(blocks: list[np.ndarray], rhs: np.ndarray, work: bool = True) -> np.ndarray:
        previous = None
        for policy in blocks:
            free = policy[order]
            index = np.flatnonzero(free).astype(np.int64)
            x = rhs[order][index]
            changed = np.flatnonzero(free != previous) if previous is not None else \
                np.arange(n)
            if not work:
                previous = free
                continue
            if previous is not None and 0 < changed.size <= UPDATE_FIXED \
                    and not (free & ~previous).any():
                places = np.searchsorted(np.flatnonzero(previous), changed)
                for d in range(places.size - 1, -1, -1):
                    _delete_contact(values, offsets, index.size + d + 1, places[d], cosines,
                                    sines, x if d == 0 else none)
            else:
                position[index] = np.arange(index.size)
                _factor_rows(upper, index, position, none, RHO_KERNEL, ordered_shift, values,
                             offsets, int(free[:changed.min()].sum()) if changed.size else
                             index.size, x)
                position[index] = -1
            _backward_substitution(values, offsets, index.size, x)
            previous = free
        answer = np.zeros(n)
        answer[order[index]] = x
        return answer
    return replay


def replay_times(problem: ImpactProblem, blocks: list[np.ndarray]) -> tuple[float, float]:
    """(envelope, sparse) seconds of replaying ``blocks``, each the fastest of 7 replays less
    the fastest of 7 replays of its bookkeeping alone (``work=False``), after checking that
    both give the last block's solution."""
    Q = sp.csc_matrix(problem.Q)
    diag = Q.diagonal()
    shift = np.where(diag > 0.0, diag, 1.0)
    rhs = np.random.default_rng(0).standard_normal(Q.shape[0])
    replays = [envelope_replay(Q, shift), sparse_replay(Q, shift)]
    envelope, sparse = (replay(blocks, rhs) for replay in replays)
    assert np.allclose(envelope, sparse, rtol=1e-6, atol=1e-9 * abs(envelope).max())
    times = []
    for replay in replays:
        fastest = {True: np.inf, False: np.inf}
        for _ in range(7):
            for work in fastest:
                start = time.perf_counter()
                replay(blocks, rhs, work)
                fastest[work] = min(fastest[work], time.perf_counter() - start)
        times.append(fastest[True] - fastest[False])
    return times[0], times[1]


def main() -> None:
    arguments = words()
    cap = int(option(arguments, "--search-cap", "1"))
    timing = "--time" in arguments
    print(f"\npi-robust's Python path at 1e-8, projected search through at most {cap} "
          "breakpoint(s); factorization multiply-adds over the policy blocks it solves"
          + ("; replay times (ms)" if timing else "") + "\n")
    print("| group | problems | not converged | solves | of them active-set | envelope, kept "
          "rows | sparse, etree ancestors | ratio | envelope, whole | sparse, whole |"
          + (" envelope replay | sparse replay | ratio |" if timing else ""))
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|" + ("---:|" * 3 if timing else ""))
    for name, problems in groups(quick_flag()).items():
        totals = np.zeros(9)
        for problem in problems:
            blocks, solves, active, converged = policy_blocks(problem, cap)
            Q = sp.csc_matrix(problem.Q)
            totals += (not converged, solves, active, *envelope_work(Q, blocks),
                       *sparse_work(Q, blocks),
                       *(replay_times(problem, blocks) if timing else (0.0, 0.0)))
        failed, solves, active, envelope_kept, envelope_whole, sparse_kept, sparse_whole, \
            envelope_time, sparse_time = totals
        print(f"| {name} | {len(problems)} | {failed:.0f} | {solves:.0f} | {active:.0f} | "
              f"{envelope_kept:.3g} | {sparse_kept:.3g} | {envelope_kept / sparse_kept:.1f}x | "
              f"{envelope_whole:.3g} | {sparse_whole:.3g} |"
              + (f" {1e3 * envelope_time:.2f} | {1e3 * sparse_time:.2f} | "
                 f"{envelope_time / sparse_time:.2f}x |" if timing else ""), flush=True)


if __name__ == "__main__":
    main()
