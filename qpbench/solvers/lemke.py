"""Lemke's complementary pivoting method with lexicographic degeneracy resolution.

Source: C. E. Lemke, "Bimatrix equilibrium points and mathematical programming",
Management Science 11(7), 1965; lexicographic ratio test as in Cottle, Pang and
Stone, "The Linear Complementarity Problem" (1992), section 4.4. For a PSD
(copositive-plus) Q and a solvable LCP, as every impact LCP with nrel = 0 is, the
method ends at a solution in finitely many pivots.

Tableau of ``w - Q z - e z0 = b`` (covering vector e = 1) on the Jacobi-scaled LCP
(``D^-1/2 Q D^-1/2``, unit diagonal), pivots below 1e-9 treated as zero, kept dense: meant for
small problems and as a reference method; above ``max_contacts`` it declines and
says so. Its answer is polished: on the final set F of basic z, ``Q_FF z_F = -b_F``
is solved again by least squares and kept when qpbench's residual improves.
"""

from __future__ import annotations

import numpy as np

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register

NAME = "lemke"


def _lexicographic_row(tableau: np.ndarray, rhs: np.ndarray, column: np.ndarray,
                       n: int, pivot_tol: float) -> int:
    """The leaving row: minimum ratio rhs_i / d_i over d_i > 0, ties broken by comparing the
    rows of [rhs, B^-1] / d_i lexicographically (B^-1 = the tableau's w columns); -1 if none."""
    rows = np.flatnonzero(column > pivot_tol)
    if rows.size == 0:
        return -1
    ratios = rhs[rows] / column[rows]
    best = ratios.min()
    tied = rows[ratios <= best + 1e-12 * max(1.0, abs(best))]
    for k in range(n):
        if tied.size == 1:
            break
        values = tableau[tied, k] / column[tied]
        low = values.min()
        tied = tied[values <= low + 1e-12 * max(1.0, abs(low))]
    return int(tied[0])


def lemke(lcp: Lcp, tol: float, max_pivots: int) -> tuple[np.ndarray, bool, str, int]:
    """(l, converged, status, pivots). Variables: w_0..w_{n-1}, z_n..z_{2n-1}, z0 = 2n."""
    n = lcp.n
    b = lcp.b
    if n == 0 or np.all(b >= 0.0):
        return np.zeros(n), True, "converged", 0
    # Jacobi scaling, l = S l~ with S = D^-1/2: the LCP (S Q S, S b) has a unit diagonal and
    # the same complementary bases, so one pivot tolerance fits every mass ratio
    root = 1.0 / np.sqrt(lcp.safe_diag)
    Q = lcp.Q.toarray() * root[:, None] * root[None, :]
    b = b * root
    # columns: w (identity), z (-Q), z0 (-e); each row reads w_i - (Q z)_i - z0 = b_i
    tableau = np.hstack([np.eye(n), -Q, -np.ones((n, 1))])
    rhs = b.astype(float).copy()
    basis = np.arange(n)
    pivot_tol = 1e-9
    artificial = 2 * n
    entering = artificial
    # first pivot: z0 enters at level -min(b); the row of the lexicographically smallest
    # (b_i, e_i) leaves: the most negative b_i, ties to the largest index
    most_negative = float(rhs.min())
    tied = np.flatnonzero(rhs <= most_negative + 1e-12 * max(1.0, abs(most_negative)))
    row = int(tied[-1])
    pivots = 0
    status = f"max_pivots ({max_pivots}) reached"
    while pivots < max_pivots:
        pivot = tableau[row, entering]
        tableau[row] /= pivot
        rhs[row] /= pivot
        factor = tableau[:, entering].copy()
        factor[row] = 0.0
        tableau -= np.outer(factor, tableau[row])
        rhs -= factor * rhs[row]
        leaving = int(basis[row])
        basis[row] = entering
        pivots += 1
        if leaving == artificial:
            status = "converged"
            break
        entering = leaving + n if leaving < n else leaving - n
        column = tableau[:, entering]
        row = _lexicographic_row(tableau, rhs, column, n, pivot_tol)
        if row < 0:
            status = "ray termination"
            break
    impulses = np.zeros(n)
    in_z = (basis >= n) & (basis < 2 * n)
    impulses[basis[in_z] - n] = np.maximum(rhs[in_z], 0.0) * root[basis[in_z] - n]
    impulses = _polish(lcp, impulses, basis[in_z] - n, Q, root)
    converged = status == "converged" and lcp.converged(impulses, tol)
    if status == "converged" and not converged:
        status = "pivoting ended above tolerance"
    return impulses, converged, status, pivots


def _polish(lcp: Lcp, impulses: np.ndarray, basic: np.ndarray, scaled_Q: np.ndarray,
            root: np.ndarray) -> np.ndarray:
    """Re-solves the basic block ``Q~_FF l~_F = -b~_F`` of the scaled LCP by least squares with
    two rounds of iterative refinement from Lemke's l; keeps the answer with the smaller
    residual."""
    if basic.size == 0:
        return impulses
    block = scaled_Q[np.ix_(basic, basic)]
    rhs = -lcp.b[basic] * root[basic]
    solution = impulses[basic] / root[basic]
    for _ in range(2):
        solution = solution + np.linalg.lstsq(block, rhs - block @ solution, rcond=None)[0]
    polished = np.zeros(lcp.n)
    polished[basic] = np.maximum(solution, 0.0) * root[basic]
    return polished if lcp.residual(polished) < lcp.residual(impulses) else impulses


def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    lcp = Lcp.of(problem)
    options = accuracy.options_for(NAME, eps, lcp.scale)
    if lcp.n > options["max_contacts"]:
        return output(None, False, f"declined: {lcp.n} contacts > max_contacts "
                      f"{options['max_contacts']} (dense tableau)", 0)
    impulses, converged, status, pivots = lemke(
        lcp, options["tol"], options["max_pivots_per_contact"] * lcp.n + 100)
    return output(impulses, converged, status, pivots)


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=False,
                    description="Lemke's method, lexicographic, dense tableau"))
