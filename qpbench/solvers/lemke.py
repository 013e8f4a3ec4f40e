"""Lemke's complementary pivoting method with lexicographic degeneracy resolution.

Source: C. E. Lemke, "Bimatrix equilibrium points and mathematical programming",
Management Science 11(7), 1965; lexicographic ratio test as in Cottle, Pang and
Stone, "The Linear Complementarity Problem" (1992), section 4.4. For a PSD
(copositive-plus) Q and a solvable LCP, as every impact LCP with nrel = 0 is, the
method ends at a solution in finitely many pivots.

Tableau of ``w - Q z - e z0 = b`` (covering vector e = 1) on the Jacobi-scaled LCP
(``D^-1/2 Q D^-1/2``, unit diagonal), pivots below 1e-9 treated as zero, kept dense: meant for
small problems and as a reference method; above ``max_contacts`` it declines and
says so. Its answer is polished: on the final set F of basic z, ``Q_FF z_F = -b_F`` is
solved again by Gaussian elimination with two rounds of iterative refinement, and kept when
qpbench's residual improves. The tableau's updates are elementwise, and the polish's products
and eliminations run in a fixed order (``fixed_order_dense``), so the answer does not depend
on the CPU's BLAS. An ending on a secondary ray is reported as ``ray termination`` (the LCP
has no solution) only when the ray's direction checks out as a proof of it
(:func:`no_solution_certified`), else as ``ray termination without a certificate``.

The same pivoting (:func:`complementary_pivoting`, any dense A) solves a frictional problem's
exact 2D law as one LCP, Stewart-Trinkle's ``z = (l_N, b+, b-, s) >= 0`` with
``l_T = b+ - b-`` (:meth:`FrictionalProblem.stewart_trinkle`; Stewart and Trinkle, IJNME 39,
1996; Anitescu and Potra, Nonlinear Dynamics 14, 1997): A is not symmetric and its slip rows
have a zero diagonal, so termination at a solution is not guaranteed (it is for e = 0 without
kinematic terms); a ray there proves nothing and is reported as ``STEWART_TRINKLE_RAY``, never
as ``ray termination``. One spec serves both kinds.
"""

from __future__ import annotations

import numpy as np

from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import dot
from qpbench.solvers import accuracy, fixed_order_dense
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lcp import BACKEND, FORMULATION, VERSION, Lcp, output
from qpbench.solvers.registry import register

NAME = "lemke"
# the ending on a secondary ray: for a copositive-plus matrix (every positive semi-definite Q)
# the LCP then has no feasible point in exact arithmetic (Lemke, Management Science 11(7),
# 1965; Cottle, Pang and Stone, "The Linear Complementarity Problem", 1992, chapter 4)
RAY_TERMINATION = "ray termination"
# a ray whose direction fails the check of :func:`no_solution_certified` (rounding in the
# pivots, not a proof): reported apart, so that no caller takes it for one
UNCERTIFIED_RAY = "ray termination without a certificate"
# the relative tolerance of that check
CERTIFICATE_TOL = 1e-9
# a ray on Stewart-Trinkle's LCP: a secondary ray proves that no solution exists only for a
# copositive-plus matrix (the impact LCP's Q, PSD), which Stewart-Trinkle's, not symmetric, is
# not in general; so there it proves nothing, whether the problem has a solution or not
STEWART_TRINKLE_RAY = "ray termination (no proof that no solution exists: Stewart-Trinkle's " \
    "LCP)"


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


def complementary_pivoting(A: np.ndarray, c: np.ndarray, max_pivots: int,
                           pivot_tol: float = 1e-9
                           ) -> tuple[np.ndarray, np.ndarray, str, int, np.ndarray]:
    """Lemke's method on a general LCP ``w = A z + c >= 0, z >= 0, z^T w = 0``.

    A is dense, not necessarily symmetric. Variables: w_0..w_{n-1}, z_n..z_{2n-1},
    z0 = 2n. ``ray``: on a secondary ray, the direction in which z moves along it (the
    entering variable rises by one, each basic z_j by ``-d_i``, d the entering column, none
    of whose entries is positive); else zeros.

    Parameters
    ----------
    A : np.ndarray
        The LCP's matrix, shape (n, n).
    c : np.ndarray
        Its constant term, shape (n,).
    max_pivots : int
        The most pivots.
    pivot_tol : float, optional
        Entries of the entering column at most this count as zero in the ratio test;
        1e-9 by default (meant for a unit diagonal).

    Returns
    -------
    z : np.ndarray
        z at the last basis, shape (n,), >= 0.
    basic : np.ndarray
        The indices of the basic z.
    status : str
        ``converged``, ``ray termination`` or the pivot limit reached.
    pivots : int
        The pivots done.
    ray : np.ndarray
        z's direction along a secondary ray, shape (n,); zeros on any other ending.
    """
    n = c.shape[0]
    # columns: w (identity), z (-A), z0 (-e); each row reads w_i - (A z)_i - z0 = c_i
    tableau = np.hstack([np.eye(n), -A, -np.ones((n, 1))])
    rhs = c.astype(float).copy()
    basis = np.arange(n)
    artificial = 2 * n
    entering = artificial
    # first pivot: z0 enters at level -min(c); the row of the lexicographically smallest
    # (c_i, e_i) leaves: the most negative c_i, ties to the largest index
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
            status = RAY_TERMINATION
            break
    z = np.zeros(n)
    in_z = (basis >= n) & (basis < 2 * n)
    z[basis[in_z] - n] = np.maximum(rhs[in_z], 0.0)
    ray = np.zeros(n)
    if status == RAY_TERMINATION:
        ray[basis[in_z] - n] = -tableau[in_z, entering]
        if n <= entering < 2 * n:
            ray[entering - n] = 1.0
    return z, basis[in_z] - n, status, pivots, ray


def no_solution_certified(Q: np.ndarray, b: np.ndarray, direction: np.ndarray) -> bool:
    """Whether ``direction`` proves that LCP(Q, b) has no feasible point.

    For a symmetric positive semi-definite Q, a y proves it has no feasible point, hence no
    solution, when ``y >= 0``, ``Q y = 0`` and ``b^T y < 0`` (for any
    l >= 0 with Q l + b >= 0, ``0 <= y^T (Q l + b) = b^T y``), each to ``CERTIFICATE_TOL``
    relative to ``max |Q| ||y||_1`` and ``||b||_inf ||y||_1``. Along a secondary ray of Lemke's
    method on such a Q, z's direction zh is such a y in exact arithmetic: complementarity
    along the ray gives ``zh^T Q zh + z0h e^T zh = 0``, both terms are non-negative, so
    ``Q zh = 0``, and then ``b^T zh = -z0 e^T zh < 0`` (Cottle, Pang and Stone, 1992,
    section 4.4).

    Parameters
    ----------
    Q : np.ndarray
        The LCP's symmetric positive semi-definite matrix, shape (n, n), dense.
    b : np.ndarray
        Its constant term, shape (n,).
    direction : np.ndarray
        The candidate y, shape (n,): a secondary ray's direction of z.

    Returns
    -------
    bool
        True when y passes the three checks; False also for a zero or non-finite y.
    """
    size = float(np.abs(direction).sum())
    if size == 0.0 or not np.all(np.isfinite(direction)):
        return False
    if float(direction.min()) < -CERTIFICATE_TOL * size:
        return False
    y = np.maximum(direction, 0.0)
    q_scale = float(np.abs(Q).max(initial=0.0)) * size
    b_scale = float(np.abs(b).max(initial=0.0)) * size
    return bool(np.abs(fixed_order_dense.symmetric_product(Q, y)).max()
                <= CERTIFICATE_TOL * q_scale and dot(b, y) < -CERTIFICATE_TOL * b_scale)


def lemke(lcp: Lcp, tol: float, max_pivots: int) -> tuple[np.ndarray, bool, str, int]:
    """Lemke's method on the Jacobi-scaled impact LCP, polished and judged by qpbench.

    Parameters
    ----------
    lcp : Lcp
        The LCP to solve (its Q densified for the tableau).
    tol : float
        qpbench's relative residual to reach.
    max_pivots : int
        The most pivots.

    Returns
    -------
    l : np.ndarray
        The answer, shape (n,); zeros when ``b >= 0`` (no contact approaches).
    converged : bool
        Whether pivoting ended at a solution whose residual is at most ``tol``.
    status : str
        ``converged``, a certified or uncertified ray, the pivot limit, or an ending above
        tolerance.
    pivots : int
        The pivots done.
    """
    n = lcp.n
    b = lcp.b
    if n == 0 or np.all(b >= 0.0):
        return np.zeros(n), True, "converged", 0
    # Jacobi scaling, l = S l~ with S = D^-1/2: the LCP (S Q S, S b) has a unit diagonal and
    # the same complementary bases, so one pivot tolerance fits every mass ratio
    root = 1.0 / np.sqrt(lcp.safe_diag)
    Q = lcp.Q.toarray() * root[:, None] * root[None, :]
    b = b * root
    scaled, basic, status, pivots, ray = complementary_pivoting(Q, b, max_pivots)
    if status == RAY_TERMINATION and not no_solution_certified(Q, b, ray):
        status = UNCERTIFIED_RAY
    impulses = scaled * root
    impulses = _polish(lcp, impulses, basic, Q, root)
    converged = status == "converged" and lcp.converged(impulses, tol)
    if status == "converged" and not converged:
        status = "pivoting ended above tolerance"
    return impulses, converged, status, pivots


def _polish(lcp: Lcp, impulses: np.ndarray, basic: np.ndarray, scaled_Q: np.ndarray,
            root: np.ndarray) -> np.ndarray:
    """Re-solves the basic block ``Q~_FF l~_F = -b~_F`` of the scaled LCP (nonsingular at a
    basis of Lemke's) by Gaussian elimination, two rounds of iterative refinement from Lemke's
    l, in a fixed order (``fixed_order_dense``); keeps the answer with the smaller residual (a
    block singular to working precision stops the refinement)."""
    if basic.size == 0:
        return impulses
    block = scaled_Q[np.ix_(basic, basic)]
    rhs = -lcp.b[basic] * root[basic]
    solution = impulses[basic] / root[basic]
    for _ in range(2):
        residual = rhs - fixed_order_dense.symmetric_product(block, solution)
        try:
            solution = solution + fixed_order_dense.lu_solve(block, residual)
        except np.linalg.LinAlgError:
            break
    polished = np.zeros(lcp.n)
    polished[basic] = np.maximum(solution, 0.0) * root[basic]
    return polished if lcp.residual(polished) < lcp.residual(impulses) else impulses


def _polish_frictional(problem: FrictionalProblem, A: np.ndarray, c: np.ndarray,
                       z: np.ndarray, basic: np.ndarray, root: np.ndarray) -> np.ndarray:
    """As :func:`_polish`, on the scaled Stewart-Trinkle LCP (not symmetric):
    ``A~_FF z~_F = -c~_F`` on the final basic set F, kept when qpbench's Coulomb residual
    improves; returns r."""
    impulses = problem.from_stewart_trinkle(z * root)
    if basic.size == 0:
        return impulses
    block = A[np.ix_(basic, basic)]
    rhs = -c[basic]
    solution = z[basic]
    for _ in range(2):
        residual = rhs - fixed_order_dense.product(block, solution)
        try:
            solution = solution + fixed_order_dense.lu_solve(block, residual)
        except np.linalg.LinAlgError:
            break
    polished = np.zeros_like(z)
    polished[basic] = np.maximum(solution, 0.0)
    candidate = problem.from_stewart_trinkle(polished * root)
    if friction_metrics.residual(problem, candidate) < friction_metrics.residual(problem,
                                                                                impulses):
        return candidate
    return impulses


def solve_frictional(problem: FrictionalProblem, eps: float) -> SolverOutput:
    """Lemke on the Stewart-Trinkle LCP of a frictional problem.

    The LCP has 4n unknowns, is not symmetric and has a zero diagonal in the slip rows; it
    is Jacobi-scaled where the diagonal is positive. Converged means qpbench's Coulomb
    residual <= tol. The LCP is posed once and kept in ``problem.posed["lcp"]``.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    eps : float
        qpbench's accuracy level; the ``lemke`` row of the accuracy table follows from it.

    Returns
    -------
    SolverOutput
        r = (l_N, l_T) with the status and pivots; no impulses, declined, when 4n is above
        ``max_contacts``.
    """
    options = accuracy.options_for(NAME, eps, problem.scale)
    n = problem.n_contacts
    if 4 * n > options["max_contacts"]:
        return output(None, False, f"declined: {4 * n} Stewart-Trinkle unknowns > "
                      f"max_contacts {options['max_contacts']} (dense tableau)", 0)
    if "lcp" not in problem.posed:
        problem.posed["lcp"] = problem.stewart_trinkle()
    A, c = problem.posed["lcp"]
    if n == 0 or np.all(c >= 0.0):
        impulses = np.zeros(2 * n)
        return output(impulses, True, "converged", 0)
    diagonal = np.diag(A)
    root = 1.0 / np.sqrt(np.where(diagonal > 0.0, diagonal, 1.0))
    A = A * root[:, None] * root[None, :]
    c = c * root
    z, basic, status, pivots, _ = complementary_pivoting(
        A, c, options["max_pivots_per_contact"] * 4 * n + 100)
    if status == RAY_TERMINATION:
        status = STEWART_TRINKLE_RAY
    impulses = _polish_frictional(problem, A, c, z, basic, root)
    converged = status == "converged" and \
        friction_metrics.residual(problem, impulses) <= options["tol"]
    if status == "converged" and not converged:
        status = "pivoting ended above tolerance"
    return output(impulses, converged, status, pivots)


def solve(problem: ImpactProblem | FrictionalProblem, eps: float,
          warm_start: np.ndarray | None = None) -> SolverOutput:
    """Solve the impact LCP, or for a frictional problem its Stewart-Trinkle LCP, by Lemke.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem to solve.
    eps : float
        qpbench's accuracy level, the relative residual to reach; the ``lemke`` row of the
        accuracy table follows from it.
    warm_start : np.ndarray or None, optional
        Ignored: pivoting starts from its own basis.

    Returns
    -------
    SolverOutput
        The impulses (l, or r for a frictional problem), status, the algorithm's own test
        as claim and the pivots done; no impulses, declined, above ``max_contacts``.
    """
    if isinstance(problem, FrictionalProblem):
        return solve_frictional(problem, eps)
    lcp = Lcp.of(problem)
    options = accuracy.options_for(NAME, eps, lcp.scale)
    if lcp.n > options["max_contacts"]:
        return output(None, False, f"declined: {lcp.n} contacts > max_contacts "
                      f"{options['max_contacts']} (dense tableau)", 0)
    impulses, converged, status, pivots = lemke(
        lcp, options["tol"], options["max_pivots_per_contact"] * lcp.n + 100)
    return output(impulses, converged, status, pivots)


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=False, kinds=("impact", "frictional"),
                    prepare=fixed_order_dense.warm_up,
                    description="Lemke's method, lexicographic, dense tableau; for a "
                                "frictional problem on its Stewart-Trinkle LCP"))
