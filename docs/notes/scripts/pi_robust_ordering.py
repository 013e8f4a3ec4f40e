"""Why reverse Cuthill-McKee and envelope Cholesky: the multiply-adds of one factorization of
the whole matrix, in the posed order and in reverse Cuthill-McKee order, against a dense
Cholesky's n^3 / 6, and the envelope's entries against a dense factor's n^2 / 2; and what a
sparse factor in approximate minimum degree order (CHOLMOD's simplicial factor) would do:
``sum_j c_j^2 / 2`` multiply-adds over its columns' entries c_j, and its entries.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_ordering.py`` (seconds).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from pi_robust_common import ROOT
from sksparse.cholmod import analyze

from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate
from qpbench.solvers.pi_robust_kernel.ordering import (
    _envelope_widths,
    _envelope_work,
    _permuted,
    reverse_cuthill_mckee,
)


def minimum_degree(Q: sp.csc_matrix) -> tuple[float, int]:
    """(multiply-adds, entries) of a simplicial Cholesky factor of Q + eps I in CHOLMOD's
    approximate minimum degree order, from the factor's column counts (eps keeps the
    factorization of a singular Q going; it changes no entry's place)."""
    shifted = (Q + 1e-8 * Q.diagonal().max() * sp.identity(Q.shape[0])).tocsc()
    factor = analyze(shifted, mode="simplicial", ordering_method="amd")
    factor.cholesky_inplace(shifted)
    counts = np.diff(factor.L().indptr).astype(float)
    return float(np.sum(counts ** 2) / 2.0), int(counts.sum())


def figures(Q) -> tuple[int, float, float, float, int, int]:
    """(n, posed work, RCM work, dense work, RCM envelope entries, dense factor entries)."""
    n = Q.shape[0]
    indptr, indices = Q.indptr.astype(np.int64), Q.indices.astype(np.int64)
    widths = np.empty(n + 1, dtype=np.int64)
    _envelope_widths((indptr, indices, Q.data), widths)
    posed = _envelope_work(widths)
    order = reverse_cuthill_mckee(indptr, indices, n)
    upper = (np.empty(n + 1, dtype=np.int64), np.empty(Q.nnz, dtype=np.int64),
             np.empty(Q.nnz))
    _permuted(indptr, indices, Q.data, order, widths, upper)
    return n, posed, _envelope_work(widths), n ** 3 / 6.0, int(widths[n]), n * (n + 1) // 2


def main() -> None:
    problems = [("fork 5x5 dump", import_dump(
        sorted((ROOT / "problems/head_to_head/fork_5x5_grid").glob("*.out"))[0]))]
    problems += [(f"grid {size}", generate("grid", size, seed=0)[0])
                 for size in (7, 10, 14, 20, 30)]
    problems += [(f"box {size}", generate("box", size, seed=0)[0]) for size in (1000, 4000)]
    problems += [("mass ratio 10", generate("mass-ratio", 10, seed=0)[0])]
    print("| problem | contacts | posed work | RCM work | dense n^3/6 | RCM entries | "
          "dense entries | AMD work | AMD entries |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, problem in problems:
        Q = problem.Q.tocsc()
        n, posed, ordered, dense, entries, dense_entries = figures(Q)
        amd_work, amd_entries = minimum_degree(Q)
        print(f"| {name} | {n} | {posed:.3g} | {ordered:.3g} | {dense:.3g} | {entries} | "
              f"{dense_entries} | {amd_work:.3g} | {amd_entries} |")


if __name__ == "__main__":
    main()
