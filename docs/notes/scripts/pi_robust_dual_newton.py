"""Prox steps solved by a damped Newton method on their dual, against pi-robust's solves.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_dual_newton.py [--quick]
[--rho R,R,...]`` (a few minutes; ``--quick``: two problems per group).

With ``Q = L^T L`` (``L = M^-1/2 G``), one prox step of pi-robust, the QP
``min_{x >= 0} x^T (Q + rho D) x / 2 + q^T x``, has the unconstrained, strongly concave and
piecewise quadratic dual ``max_y -||y||^2 / 2 - sum_i max(0, -(L^T y + q)_i)^2 / (2 rho D_i)``
(Rockafellar, "Conjugate Duality and Optimization", SIAM 1974; its maximizer gives
``x_i = max(0, -(L^T y + q)_i) / (rho D_i)``). Along ``y = L u`` every quantity is a product
with Q, and the full semismooth Newton step from u (Qi and Sun, "A nonsmooth version of
Newton's method", Math. Program. 58, 1993) is the policy solve
``(Q_AA + rho D_A) u_A = -q_A``, zero elsewhere, on ``A = {i : (Q u + q)_i < 0}``: policy
iteration on ``min(rho D u, (Q + rho D) u + q) = 0``. Damped by an exact line search on the
dual (its derivative along the step is piecewise linear), it cannot cycle, unlike block
pivoting, and exchanges many contacts a solve, unlike the primal active-set method that ends
pi-robust's prox steps on grids. This is the inner solve of a semismooth Newton augmented
Lagrangian method (Li, Sun and Toh, "A highly efficient semismooth Newton augmented
Lagrangian method for solving Lasso problems", SIAM J. Optim. 28(1), 2018) with penalty
``1 / rho``.

Each problem (the groups of ``pi_robust_refactor_work.py``: the fork's 5x5 dumps, grids of 7
to 20 balls a side of seeds 100 on) starts from the kernel's swept start, then takes prox steps
at a fixed rho, each solved by that Newton method to a tenth of the tolerance, until
qpbench's residual is at most 1e-8 (at most ``MOST_PROX_STEPS`` steps). The script prints per
group and rho: the Newton solves, the prox steps and the problems not converged; and
pi-robust's own linear solves and factorizations on the same problems (the compiled kernel,
one run).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from pi_robust_common import ACCURACY, option, quick_flag, run, words
from pi_robust_refactor_work import groups, swept_start
from sksparse.cholmod import cholesky

from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import residual, scale
from qpbench.solvers.accuracy import options_for

MOST_PROX_STEPS = 400
MOST_NEWTON_SOLVES = 200  # a prox step's


def exact_step(along_u: float, curvature: float, slack: np.ndarray, change: np.ndarray,
               weight: np.ndarray) -> float:
    """The t in (0, 1] that maximizes the dual along a Newton step, 1 when it still rises there.

    Parameters
    ----------
    along_u : float
        ``u^T Q d`` for the step d from u.
    curvature : float
        ``d^T Q d``.
    slack : np.ndarray
        ``Q u + q``.
    change : np.ndarray
        ``Q d``.
    weight : np.ndarray
        ``1 / (rho D)``.

    Returns
    -------
    float
        The step length.

    Notes
    -----
    The derivative ``-(along_u + t curvature) + sum_i max(0, -(slack_i + t change_i))
    change_i weight_i`` falls and is linear between the breakpoints ``-slack_i / change_i``;
    they are visited in order, the coefficients updated as each term starts or stops.
    """
    on = (slack < 0.0) | ((slack == 0.0) & (change < 0.0))
    constant = -along_u - np.sum(slack[on] * change[on] * weight[on])
    linear = -curvature - np.sum(change[on] ** 2 * weight[on])
    with np.errstate(divide="ignore", invalid="ignore"):
        breaks = -slack / change
    inside = np.flatnonzero((breaks > 0.0) & (breaks < 1.0))
    start = 0.0
    for i in inside[np.argsort(breaks[inside])]:
        end = breaks[i]
        if constant + linear * end <= 0.0:
            return max(start, -constant / linear) if linear < 0.0 else start
        sign = 1.0 if change[i] < 0.0 else -1.0  # the term starts (change < 0) or stops
        constant -= sign * slack[i] * change[i] * weight[i]
        linear -= sign * change[i] ** 2 * weight[i]
        start = end
    if constant + linear <= 0.0:
        return max(start, -constant / linear) if linear < 0.0 else start
    return 1.0


def prox_step(Q: sp.csr_matrix, D: np.ndarray, rho: float, q: np.ndarray, u: np.ndarray,
              tolerance: float) -> tuple[np.ndarray, int]:
    """Solve LCP(Q + rho D, q) by the damped Newton method on its dual, from u.

    Parameters
    ----------
    Q : scipy.sparse.csr_matrix
        The problem's Q.
    D : np.ndarray
        Q's diagonal, zeros replaced by ones.
    rho : float
        The prox weight.
    q : np.ndarray
        The prox step's constant term.
    u : np.ndarray
        The dual point to start from, as ``y = L u``.
    tolerance : float
        The largest ``|min(D x, (Q + rho D) x + q)|`` accepted, in velocity units.

    Returns
    -------
    x : np.ndarray
        The prox step's solution (the last iterate's, when the solves ran out).
    solves : int
        The Newton solves made.
    """
    rho_diag = rho * D
    weight = 1.0 / rho_diag
    solves = 0
    while True:
        slack = Q @ u + q
        free = np.flatnonzero(slack < 0.0)
        x = np.zeros_like(u)
        x[free] = -slack[free] * weight[free]
        natural = np.minimum(D * x, Q @ x + rho_diag * x + q)
        if np.max(np.abs(natural)) <= tolerance or solves >= MOST_NEWTON_SOLVES:
            return x, solves
        target = np.zeros_like(u)
        if free.size:
            block = Q[free][:, free] + sp.diags(rho_diag[free])
            target[free] = cholesky(sp.csc_matrix(block))(-q[free])
        solves += 1
        step = target - u
        change = Q @ step
        u = u + exact_step(u @ change, step @ change, slack, change, weight) * step


def dual_newton(problem: ImpactProblem, rho: float) -> tuple[int, int, bool]:
    """Prox steps at ``rho`` from the kernel's swept start, each by :func:`prox_step`.

    Parameters
    ----------
    problem : ImpactProblem
        The problem, posed as ``lcp``.
    rho : float
        The prox weight (relative to D, as pi-robust's).

    Returns
    -------
    solves : int
        The Newton solves of all prox steps.
    steps : int
        The prox steps taken.
    converged : bool
        Whether qpbench's residual reached ``ACCURACY``.
    """
    Q = sp.csr_matrix(problem.Q)
    D = np.where(problem.diag_Q > 0.0, problem.diag_Q, 1.0)
    centre = swept_start(problem, int(options_for("pi-robust", ACCURACY)["start_sweeps"]))
    tolerance = 0.1 * ACCURACY * scale(problem)
    solves = steps = 0
    while residual(problem, centre) > ACCURACY and steps < MOST_PROX_STEPS:
        centre, used = prox_step(Q, D, rho, problem.b - rho * D * centre, centre, tolerance)
        solves += used
        steps += 1
    return solves, steps, residual(problem, centre) <= ACCURACY


def main() -> None:
    arguments = words()
    rhos = [float(value) for value in option(arguments, "--rho", "1e-5,1e-4,1e-3").split(",")]
    print("\nProx steps by damped Newton on their dual, at a fixed rho, against pi-robust "
          "(compiled kernel) at 1e-8\n")
    print("| group | problems | pi-robust solves / factorizations | "
          + " | ".join(f"rho {rho:g}: solves / prox steps / not converged" for rho in rhos)
          + " |")
    print("|---|---:|---:|" + "---:|" * len(rhos))
    for name, problems in groups(quick_flag()).items():
        kernel = run(problems, 1)
        cells = []
        for rho in rhos:
            results = [dual_newton(problem, rho) for problem in problems]
            cells.append(f"{sum(r[0] for r in results)} / {sum(r[1] for r in results)} / "
                         f"{sum(not r[2] for r in results)}")
        print(f"| {name} | {len(problems)} | {kernel['solves']:.0f} / "
              f"{kernel['factorizations']:.0f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
