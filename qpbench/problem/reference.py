"""Reference solutions: v+ from two independent methods that must agree.

* ``primal-ipm``: Clarabel's interior point on the velocity-space QP (its Hessian
  M is positive definite, so v+ is unique), at tight tolerances.
* ``enumeration`` (n <= ENUMERATION_LIMIT): every active set S, the minimum-norm
  solution of ``Q_SS l_S = -b_S``; the first (by size) that satisfies the LCP.
* ``dual-ipm+polish`` (larger n): Clarabel on the dual QP, then an active-set
  polish (minimum-norm solve of ``Q_AA l_A = -b_A`` on ``A = {D l > w}``).

``agreement = ||v+_a - v+_b||_M / ||v-||_M``; the reference is verified when it
is at most REFERENCE_TOLERANCE. Where the two disagree, or the better one's residual is above
REFERENCE_TOLERANCE (the finest accuracy level), the LCP is solved and certified in exact
rational arithmetic from the better one's active set
(``qpbench.problem.extended_reference``): that solution becomes the reference, checked
against the closer of the two, and its residual floor (the least residual known of a double
vector) is recorded. A problem whose references still disagree is flagged
(``Reference.verified`` is False) and its v_error is never computed.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import qpsolvers
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from qpbench.problem import metrics
from qpbench.problem.extended_reference import (
    FLOOR_KEY,
    ExtendedReference,
    extended_reference,
)
from qpbench.problem.formulations import primal_qp
from qpbench.problem.impact import ImpactProblem, Reference
from qpbench.problem.scaling import jacobi_scaled

REFERENCE_TOLERANCE = 1e-8
ENUMERATION_LIMIT = 12
# the active-set polish solves blocks of up to DENSE_POLISH_LIMIT contacts densely (the
# minimum-norm solution); larger ones by POLISH_REFINEMENTS refinement steps on one sparse
# factorization of the block shifted by POLISH_SHIFT of its largest diagonal entry
DENSE_POLISH_LIMIT = 3000
POLISH_SHIFT = 1e-8
POLISH_REFINEMENTS = 10
_TIGHT = {"tol_gap_abs": 1e-13, "tol_gap_rel": 1e-13, "tol_feas": 1e-13, "tol_ktratio": 1e-10,
          "max_iter": 400}
_TIGHT_OTHERS = {"piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12, "eps_duality_gap_abs": 1e-12,
                          "eps_duality_gap_rel": 1e-12}}
# interior points tried in turn; the answer with the smallest residual is kept
PRIMAL_SOLVERS = ("clarabel", "piqp")
DUAL_SOLVERS = ("clarabel", "piqp")


def _agreement(problem: ImpactProblem, v_a: np.ndarray, v_b: np.ndarray) -> float:
    """||v_a - v_b||_M / max(||v-||_M, tiny)."""
    return problem.m_norm(v_a - v_b) / max(problem.m_norm(problem.v_minus), metrics.TINY)


def _qp_solve(qp: qpsolvers.Problem, solver: str) -> qpsolvers.Solution | None:
    """qpsolvers' solution with tight options, or None when the backend raises."""
    options = _TIGHT if solver == "clarabel" else _TIGHT_OTHERS.get(solver, {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return qpsolvers.solve_problem(qp, solver=solver, **options)
        except Exception:  # a backend that fails is just not a candidate
            return None


def primal_ipm(problem: ImpactProblem, solver: str = "clarabel") -> tuple[np.ndarray, np.ndarray]:
    """(v+, l) from ``min 1/2 (v - v-)^T M (v - v-)  s.t.  A v >= lower`` (l = multipliers).

    Parameters
    ----------
    problem : ImpactProblem
        The problem; its QP is :func:`primal_qp`.
    solver : str, optional
        The qpsolvers backend, run at tight tolerances; ``clarabel`` by default.

    Returns
    -------
    v_plus : np.ndarray
        The post-impact velocities, shape (d,).
    impulses : np.ndarray
        The multipliers of the constraints, the impulses l, shape (n,).

    Raises
    ------
    ArithmeticError
        When the backend raises or returns no primal or dual solution.
    """
    qp = primal_qp(problem)
    solution = _qp_solve(qpsolvers.Problem(P=qp.P, q=qp.q, G=-qp.A, h=-qp.lower), solver)
    if solution is None or solution.x is None or solution.z is None:
        raise ArithmeticError(f"{problem.name}: primal {solver} found no solution")
    return qp.v_plus(problem, solution.x), np.asarray(solution.z, dtype=float)


def _min_norm_solve(Q_active: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The minimum-norm least-squares solution of Q_active x = rhs."""
    return np.linalg.lstsq(Q_active, rhs, rcond=None)[0]


def _least_change_solve(Q_active: sp.csc_matrix, rhs: np.ndarray) -> np.ndarray:
    """An x with ``Q_active x = rhs``, near the minimum-norm one, at the cost of one sparse
    factorization.

    Iterated Tikhonov regularization (Engl, Hanke and Neubauer, "Regularization of Inverse
    Problems", 1996, section 5.1): from x = 0, ``x <- x + (Q_active + s I)^-1 (rhs - Q_active
    x)`` with ``s = POLISH_SHIFT max diag(Q_active)``, POLISH_REFINEMENTS times, every step on
    one SuperLU factorization (minimum degree on ``A^T + A``, diagonal pivots: the shifted
    block is positive definite). On a consistent system the component of the error along an
    eigenvector of eigenvalue e shrinks by ``s / (s + e)`` a step, so x tends to the
    minimum-norm solution and moves little along the directions Q_active hardly sees, as
    :func:`_min_norm_solve` does densely.
    """
    shift = POLISH_SHIFT * float(Q_active.diagonal().max())
    if not shift > 0.0:
        return np.zeros(rhs.size)
    shifted = (Q_active + shift * sp.identity(rhs.size, format="csc")).tocsc()
    factor = splu(shifted, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0)
    solution = np.zeros(rhs.size)
    for _ in range(POLISH_REFINEMENTS):
        solution += factor.solve(rhs - Q_active @ solution)
    return solution


def enumeration(problem: ImpactProblem) -> np.ndarray:
    """l from the smallest active set S that solves the LCP.

    S is the first (by size) whose minimum-norm solution of Q_SS l_S = -b_S satisfies the LCP
    within 1e-12 (relative residual); exhaustive, so only for small n.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.

    Returns
    -------
    np.ndarray
        l, shape (n,): the candidate of smallest residual when no active set reaches 1e-12.
    """
    n = problem.n_contacts
    Q = problem.Q.toarray()
    best, best_residual = np.zeros(n), metrics.residual(problem, np.zeros(n))
    for size in range(1, n + 1):
        for active in itertools.combinations(range(n), size):
            index = list(active)
            impulses = np.zeros(n)
            impulses[index] = _min_norm_solve(Q[np.ix_(index, index)], -problem.b[index])
            value = metrics.residual(problem, impulses)
            if value < best_residual:
                best, best_residual = impulses, value
        if best_residual <= 1e-12:
            break
    return best


def active_set_polish(problem: ImpactProblem, impulses: np.ndarray, rounds: int = 5) -> np.ndarray:
    """Repeats an active-set solve while it lowers the residual.

    Each round: A = {i : D_i l_i > w_i}; l_A = min-norm solution of Q_AA l_A = -b_A, l = 0
    elsewhere; keeps the new l only while the residual decreases. Above DENSE_POLISH_LIMIT
    active contacts l_A comes from :func:`_least_change_solve`, so that a round costs one
    sparse factorization whatever the block's conditioning.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The starting l, shape (n,).
    rounds : int, optional
        The most rounds; 5 by default.

    Returns
    -------
    np.ndarray
        The l of smallest residual found, ``impulses`` itself when no round improves it.
    """
    best, best_residual = impulses, metrics.residual(problem, impulses)
    Q = problem.Q
    for _ in range(rounds):
        active = np.flatnonzero(problem.diag_Q * best > problem.w(best))
        candidate = np.zeros_like(best)
        if active.size:
            Q_active = Q[active][:, active]
            if active.size <= DENSE_POLISH_LIMIT:
                candidate[active] = _min_norm_solve(Q_active.toarray(), -problem.b[active])
            else:
                candidate[active] = _least_change_solve(Q_active.tocsc(), -problem.b[active])
        value = metrics.residual(problem, candidate)
        if not value < best_residual:
            break
        best, best_residual = candidate, value
    return best


def dual_ipm_polished(problem: ImpactProblem, solver: str = "clarabel") -> np.ndarray:
    """l from an interior point on ``min 1/2 l^T Q l + b^T l, l >= 0``, then polished.

    The polish is :func:`active_set_polish`.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    solver : str, optional
        The qpsolvers backend, run at tight tolerances; ``clarabel`` by default.

    Returns
    -------
    np.ndarray
        l, shape (n,).

    Raises
    ------
    ArithmeticError
        When the backend raises or returns no solution.
    """
    solution = _qp_solve(
        qpsolvers.Problem(P=problem.Q, q=problem.b, lb=np.zeros(problem.n_contacts)), solver
    )
    if solution is None or solution.x is None:
        raise ArithmeticError(f"{problem.name}: dual {solver} found no solution")
    return active_set_polish(problem, np.maximum(solution.x, 0.0))


def _best(problem: ImpactProblem, candidates: list[tuple[np.ndarray, np.ndarray, str]]
          ) -> tuple[np.ndarray, np.ndarray, str]:
    """The (v+, l, method) whose l has the smallest residual."""
    if not candidates:
        raise ArithmeticError(f"{problem.name}: no reference method found a solution")
    return min(candidates, key=lambda c: metrics.residual(problem, c[1]))


def compute_reference(problem: ImpactProblem) -> Reference:
    """The reference of ``problem`` from two independent methods (see the module docstring).

    Parameters
    ----------
    problem : ImpactProblem
        The problem.

    Returns
    -------
    Reference
        v+ and l of the method with the smaller residual, the other's v+ as the check, and
        their agreement; an :class:`ExtendedReference` (v+ and l certified in exact arithmetic,
        with the residual floor) where they disagree or the residual is above
        REFERENCE_TOLERANCE and the exact solve succeeds.

    Raises
    ------
    ArithmeticError
        When every backend of one method fails.
    """
    if problem.n_contacts == 0:
        return Reference(problem.v_minus.copy(), np.zeros(0), "none", problem.v_minus.copy(),
                         "none", 0.0, REFERENCE_TOLERANCE)
    # both methods work on the Jacobi/mass-scaled problem, so mass ratios stay manageable
    scaling = jacobi_scaled(problem)
    primal_candidates = []
    for solver in PRIMAL_SOLVERS:
        try:
            scaled_v, scaled_impulses = primal_ipm(scaling.scaled, solver)
        except ArithmeticError:
            continue
        primal_candidates.append((scaling.velocity(scaled_v), scaling.impulses(scaled_impulses),
                                  f"primal-ipm({solver})"))
    v_primal, impulses_primal, primal_method = _best(problem, primal_candidates)
    if problem.n_contacts <= ENUMERATION_LIMIT:
        impulses, method = enumeration(problem), "enumeration"
    else:
        dual_candidates = []
        for solver in DUAL_SOLVERS:
            try:
                scaled_impulses = dual_ipm_polished(scaling.scaled, solver)
            except ArithmeticError:
                continue
            candidate = active_set_polish(problem, scaling.impulses(scaled_impulses))
            dual_candidates.append((problem.v_plus(candidate), candidate,
                                    f"dual-ipm({solver})+polish"))
        _, impulses, method = _best(problem, dual_candidates)
    v_dual = problem.v_plus(impulses)
    agreement = _agreement(problem, v_dual, v_primal)
    if metrics.residual(problem, impulses_primal) < metrics.residual(problem, impulses):
        reference = Reference(v_primal, impulses_primal, primal_method, v_dual, method,
                              agreement, REFERENCE_TOLERANCE)
    else:
        reference = Reference(v_dual, impulses, method, v_primal, primal_method, agreement,
                              REFERENCE_TOLERANCE)
    if reference.verified and metrics.residual(problem, reference.impulses) <= REFERENCE_TOLERANCE:
        return reference
    # disagreement, or a residual above the finest level: the LCP certified exactly
    extended = extended_reference(problem, [(v_primal, impulses_primal, primal_method),
                                            (v_dual, impulses, method)], REFERENCE_TOLERANCE)
    if extended is not None and (extended.verified or not reference.verified):
        return extended
    return reference


def attach_reference(problem: ImpactProblem) -> ImpactProblem:
    """Sets ``problem.reference`` and records the agreement in its metadata; returns it.

    Parameters
    ----------
    problem : ImpactProblem
        The problem, changed in place.

    Returns
    -------
    ImpactProblem
        ``problem``, with ``reference_agreement`` and ``reference_verified`` in its metadata,
        and ``reference_residual_floor`` when the reference was certified in exact arithmetic
        (:class:`ExtendedReference`: the least residual a double vector is known to reach).
    """
    problem.reference = compute_reference(problem)
    problem.metadata["reference_agreement"] = problem.reference.agreement
    problem.metadata["reference_verified"] = problem.reference.verified
    if isinstance(problem.reference, ExtendedReference):
        problem.metadata[FLOOR_KEY] = problem.reference.floor
    return problem
