"""What a sparse factor in minimum degree order would save pi-robust's kernel per factorization.

One factorization of ``Q + rho D`` (and one pair of triangular solves) by the kernel's own
envelope Cholesky (``pi_robust_kernel.factor._factor_rows``) in reverse Cuthill-McKee order,
against an up-looking sparse Cholesky written here (row k's pattern from the elimination
tree, then a sparse triangular solve: Davis, "Direct Methods for Sparse Linear Systems",
SIAM 2006, sections 4.1-4.4 and 4.7) in CHOLMOD's approximate minimum degree order, both
compiled by numba; each the fastest of 30 alternating calls. Both answers are checked
against the matrix. A second table gives pi-robust's own solve of each grid at 1e-8 (the
fastest of 15 calls back to back): its solves, factorizations and time, to set the two
against.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_sparse_factor.py`` (a minute).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from numba import njit
from pi_robust_common import ROOT
from sksparse.cholmod import analyze

from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.solvers import pi_robust
from qpbench.solvers.pi_robust_kernel.factor import _envelope_solve_in_place, _factor_rows
from qpbench.solvers.pi_robust_kernel.ordering import (
    _envelope_widths,
    _upper,
    reverse_cuthill_mckee,
)

RHO = 1e-5
CALLS = 30


@njit(cache=True)
def elimination_tree(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """The elimination tree's parents (-1 at a root), by path compression over the upper
    triangle of the symmetric pattern (Davis 2006, section 4.1)."""
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        for p in range(indptr[k], indptr[k + 1]):
            i = indices[p]
            while i != -1 and i < k:
                following = ancestor[i]
                ancestor[i] = k
                if following == -1:
                    parent[i] = k
                i = following
    return parent


@njit(cache=True)
def row_pattern(indptr: np.ndarray, indices: np.ndarray, k: int, parent: np.ndarray,
                stack: np.ndarray, marks: np.ndarray) -> int:
    """Row k's pattern in L (its columns before k) in ``stack[top:]``, in an order where each
    column comes before its ancestors; returns top (Davis 2006, section 4.2)."""
    n = parent.size
    top = n
    marks[k] = k
    for p in range(indptr[k], indptr[k + 1]):
        i = indices[p]
        if i > k:
            continue
        length = 0
        while marks[i] != k:
            stack[length] = i
            length += 1
            marks[i] = k
            i = parent[i]
        while length > 0:
            top -= 1
            length -= 1
            stack[top] = stack[length]
    return top


@njit(cache=True)
def column_counts(indptr: np.ndarray, indices: np.ndarray, parent: np.ndarray) -> np.ndarray:
    """Entries of each column of L, diagonal included, from every row's pattern."""
    n = parent.size
    counts = np.ones(n, np.int64)
    stack, marks = np.empty(n, np.int64), np.full(n, -1, np.int64)
    for k in range(n):
        top = row_pattern(indptr, indices, k, parent, stack, marks)
        for t in range(top, n):
            counts[stack[t]] += 1
    return counts


@njit(cache=True)
def up_looking_cholesky(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                        shift: np.ndarray, parent: np.ndarray, starts: np.ndarray,
                        ends: np.ndarray, rows: np.ndarray, values: np.ndarray,
                        stack: np.ndarray, marks: np.ndarray, dense: np.ndarray) -> None:
    """L by columns (``starts``, ``ends``, ``rows``, ``values``; the diagonal first) with
    ``L L^T = A + diag(shift)``, row by row: row k solves ``L_(:k,:k) l = A_(:k,k)`` over its
    pattern (Davis 2006, section 4.7)."""
    n = parent.size
    for k in range(n):
        ends[k] = starts[k]
        marks[k] = -1
    for k in range(n):
        top = row_pattern(indptr, indices, k, parent, stack, marks)
        dense[k] = 0.0
        for p in range(indptr[k], indptr[k + 1]):
            if indices[p] <= k:
                dense[indices[p]] = data[p]
        diagonal = dense[k] + shift[k]
        dense[k] = 0.0
        for t in range(top, n):
            i = stack[t]
            entry = dense[i] / values[starts[i]]
            dense[i] = 0.0
            for p in range(starts[i] + 1, ends[i]):
                dense[rows[p]] -= values[p] * entry
            diagonal -= entry * entry
            rows[ends[i]], values[ends[i]] = k, entry
            ends[i] += 1
        if not diagonal > 0.0:
            raise np.linalg.LinAlgError("not positive definite")
        rows[ends[k]], values[ends[k]] = k, np.sqrt(diagonal)
        ends[k] += 1


@njit(cache=True)
def column_solve(starts: np.ndarray, ends: np.ndarray, rows: np.ndarray, values: np.ndarray,
                 x: np.ndarray) -> None:
    """``L L^T y = x`` in place, for L stored by :func:`up_looking_cholesky`."""
    n = x.size
    for j in range(n):
        x[j] /= values[starts[j]]
        for p in range(starts[j] + 1, ends[j]):
            x[rows[p]] -= values[p] * x[j]
    for j in range(n - 1, -1, -1):
        for p in range(starts[j] + 1, ends[j]):
            x[j] -= values[p] * x[rows[p]]
        x[j] /= values[starts[j]]


def permuted(Q: sp.csc_matrix, order: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q's rows and columns in ``order``, as sorted 64-bit CSC arrays."""
    P = Q[order][:, order].tocsc()
    P.sort_indices()
    return P.indptr.astype(np.int64), P.indices.astype(np.int64), P.data.copy()


def envelope(Q: sp.csc_matrix, shift: np.ndarray
             ) -> tuple[Callable[[], None], Callable[[np.ndarray], np.ndarray], int]:
    """(factor, solve, entries) of the kernel's envelope factor in reverse Cuthill-McKee
    order."""
    n = Q.shape[0]
    order = reverse_cuthill_mckee(Q.indptr.astype(np.int64), Q.indices.astype(np.int64), n)
    A = permuted(Q, order)
    upper = _upper(A)
    offsets = np.empty(n + 1, np.int64)
    _envelope_widths(A, offsets)
    values, every, none = np.empty(offsets[-1]), np.arange(n, dtype=np.int64), np.empty(0)
    ordered_shift = shift[order].copy()

    def factor() -> None:
        _factor_rows(upper, every, every, none, RHO, ordered_shift, values, offsets, 0, none)

    def solve(rhs: np.ndarray) -> np.ndarray:
        x = rhs[order].copy()
        _envelope_solve_in_place(values, offsets, n, x)
        answer = np.empty(n)
        answer[order] = x
        return answer

    return factor, solve, int(offsets[-1])


def minimum_degree(Q: sp.csc_matrix, shift: np.ndarray
                   ) -> tuple[Callable[[], None], Callable[[np.ndarray], np.ndarray], int]:
    """(factor, solve, entries) of the up-looking sparse factor in CHOLMOD's approximate
    minimum degree order."""
    n = Q.shape[0]
    pattern = (Q + 1e-8 * Q.diagonal().max() * sp.identity(n)).tocsc()
    order = analyze(pattern, mode="simplicial", ordering_method="amd").P()
    indptr, indices, data = permuted(Q, order)
    parent = elimination_tree(indptr, indices, n)
    counts = column_counts(indptr, indices, parent)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    ends, rows, values = np.empty(n, np.int64), np.empty(counts.sum(), np.int64), \
        np.empty(counts.sum())
    stack, marks, dense = np.empty(n, np.int64), np.empty(n, np.int64), np.zeros(n)
    ordered_shift = RHO * shift[order]

    def factor() -> None:
        up_looking_cholesky(indptr, indices, data, ordered_shift, parent, starts, ends, rows,
                            values, stack, marks, dense)

    def solve(rhs: np.ndarray) -> np.ndarray:
        x = rhs[order].copy()
        column_solve(starts, ends, rows, values, x)
        answer = np.empty(n)
        answer[order] = x
        return answer

    return factor, solve, int(counts.sum())


def time_once(action: Callable[[], object], times: list[float]) -> None:
    """Time ``action`` once, appending its wall time to ``times``."""
    start = time.perf_counter()
    action()
    times.append(time.perf_counter() - start)


def row(name: str, Q: sp.csc_matrix) -> str:
    """The table's row for ``Q``: its size, both factors' entries and times, and the larger
    relative residual of the two solves."""
    Q = sp.csc_matrix(Q)
    n = Q.shape[0]
    diag = Q.diagonal()
    shift = np.where(diag > 0.0, diag, 1.0)
    rhs = np.random.default_rng(0).standard_normal(n)
    methods = [envelope(Q, shift), minimum_degree(Q, shift)]
    H = Q + RHO * sp.diags(shift)
    residual = 0.0
    for factor, solve, _ in methods:
        factor()
        residual = max(residual, np.linalg.norm(H @ solve(rhs) - rhs) / np.linalg.norm(rhs))
    factor_times: list[list[float]] = [[], []]
    solve_times: list[list[float]] = [[], []]
    for _ in range(CALLS):
        for (factor, solve, _), factored, solved in zip(methods, factor_times, solve_times,
                                                        strict=True):
            time_once(factor, factored)
            time_once(lambda solve=solve: solve(rhs), solved)
    (envelope_factor, sparse_factor), (envelope_solve, sparse_solve) = \
        [[1e6 * min(times) for times in pair] for pair in (factor_times, solve_times)]
    return (f"| {name} | {n} | {methods[0][2]} | {methods[1][2]} | {envelope_factor:.1f} | "
            f"{sparse_factor:.1f} | {envelope_factor / sparse_factor:.2f}x | "
            f"{envelope_solve:.1f} | {sparse_solve:.1f} | {residual:.1e} |")


def own_solve(name: str, problem) -> str:
    """The second table's row: pi-robust's solves, factorizations and fastest time."""
    output = pi_robust.solve(problem, 1e-8)
    times: list[float] = []
    for _ in range(15):
        time_once(lambda: pi_robust.solve(problem, 1e-8), times)
    return (f"| {name} | {output.iterations} | {output.info.get('factorizations')} | "
            f"{1e3 * min(times):.2f} |")


def main() -> None:
    print("| problem | contacts | envelope entries | sparse entries | envelope factor (us) | "
          "sparse factor (us) | ratio | envelope solve (us) | sparse solve (us) | "
          "residual |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    dump = sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))[0]
    print(row("fork 5x5 dump", import_dump(dump).Q))
    grids = [(f"grid {size}, seed {seed}", generate("grid", size, seed=seed)[0])
             for size in (7, 10, 14, 20, 30) for seed in (9300, 9301)]
    for name, problem in grids:
        print(row(name, problem.Q))
    for size in (1000, 4000):
        print(row(f"box {size}", generate("box", size, seed=1)[0].Q))
    print("\n| problem | pi-robust's solves | factorizations | time (ms) |")
    print("|---|---:|---:|---:|")
    for name, problem in grids:
        print(own_solve(name, problem))


if __name__ == "__main__":
    main()
