"""Projected Gauss-Seidel, the game-engine standard for contact impulses.

Source: Cryer, "The solution of a quadratic programming problem using systematic
overrelaxation", SIAM J. Control 9(3), 1971 (without overrelaxation here); linear
convergence for the dual of a strictly convex QP: Luo and Tseng, "On the convergence
of the coordinate descent method for convex differentiable minimization", JOTA 72,
1992. One update per contact, ``l_i <- max(0, l_i - (Q l + b)_i / Q_ii)``.

Sweep order (recorded in the output's info): contacts are coloured greedily on the
graph of Q (two contacts conflict when they share a body, i.e. Q_ij != 0), and a
sweep visits the colours in order. Contacts of one colour do not interact, so
updating a colour at once in numpy is exactly Gauss-Seidel in that order. The
residual is checked every ``check_every`` sweeps; at most ``max_sweeps``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy, colouring
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register

NAME = "pgs"


class Sweep:
    """The colour classes of a problem and the rows of Q for each, ready for sweeping."""

    def __init__(self, lcp: Lcp) -> None:
        movable = lcp.diag > 0.0  # a contact with Q_ii = 0 moves nothing and stays at 0
        self.colour = colouring.colours_of(lcp.Q)
        self.classes: list[tuple[np.ndarray, sp.csr_matrix, np.ndarray, np.ndarray]] = []
        for c in range(int(self.colour.max(initial=-1)) + 1):
            index = np.flatnonzero((self.colour == c) & movable)
            if index.size:
                self.classes.append((index, lcp.Q[index], lcp.b[index], lcp.diag[index]))

    def __call__(self, impulses: np.ndarray) -> None:
        """One Gauss-Seidel sweep in place."""
        for index, rows, b, diag in self.classes:
            w = rows @ impulses + b
            impulses[index] = np.maximum(0.0, impulses[index] - w / diag)


def pgs(lcp: Lcp, sweep: Sweep, start: np.ndarray, tol: float, max_sweeps: int,
        check_every: int) -> tuple[np.ndarray, bool, str, int]:
    """Sweep from ``start`` until qpbench's residual reaches ``tol``.

    Parameters
    ----------
    lcp : Lcp
        The LCP to solve.
    sweep : Sweep
        The colour-ordered sweep of that LCP, which updates impulses in place.
    start : np.ndarray
        The first iterate, shape (n,), l >= 0; it is copied, not changed.
    tol : float
        qpbench's relative residual to reach.
    max_sweeps : int
        The most sweeps.
    check_every : int
        Sweeps between residual (and finiteness) checks.

    Returns
    -------
    l : np.ndarray
        The last iterate, shape (n,).
    converged : bool
        Whether its residual is at most ``tol``.
    status : str
        ``converged``, a divergence or the sweep limit reached.
    sweeps : int
        The sweeps taken.
    """
    impulses = start.copy()
    if lcp.converged(impulses, tol):
        return impulses, True, "converged", 0
    sweeps = 0
    while sweeps < max_sweeps:
        for _ in range(min(check_every, max_sweeps - sweeps)):
            sweep(impulses)
            sweeps += 1
        if not np.all(np.isfinite(impulses)):
            return impulses, False, "diverged: non-finite impulses", sweeps
        if lcp.converged(impulses, tol):
            return impulses, True, "converged", sweeps
    return impulses, False, f"max_sweeps ({max_sweeps}) reached", sweeps


def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    """Solve ``problem`` by projected Gauss-Seidel at accuracy level ``eps``.

    Parameters
    ----------
    problem : ImpactProblem
        The impact to solve.
    eps : float
        qpbench's accuracy level, the relative residual to reach; the solver's options
        follow from it in :mod:`qpbench.solvers.accuracy`.
    warm_start : np.ndarray or None, optional
        A guess of l, the start when finite and of the right size (clipped to
        l >= 0); None or an unusable guess starts at 0.

    Returns
    -------
    SolverOutput
        The impulses, status, the algorithm's own convergence test as claim, the
        sweeps taken, and the sweep order and number of colours in ``info``.
    """
    lcp = Lcp.of(problem)
    options = accuracy.options_for(NAME, eps, lcp.scale)
    sweep = Sweep(lcp)
    start = lcp.start(warm_start)
    impulses, converged, status, sweeps = pgs(lcp, sweep, start, options["tol"],
                                              options["max_sweeps"], options["check_every"])
    return output(impulses, converged, status, sweeps,
                  order="greedy colouring of the contact graph, colours in increasing order",
                  colours=len(sweep.classes))


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=True, prepare=colouring.warm_up,
                    description="projected Gauss-Seidel, colour-ordered sweeps"))
