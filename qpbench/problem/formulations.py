"""The formulations of one impact problem (docs/design.md section 1), as plain arrays for backends.

* ``dual``: ``min 1/2 l^T Q l + b^T l  s.t.  l >= 0``.
* ``lcp``: find ``l >= 0`` with ``w = Q l + b >= 0`` and ``l^T w = 0`` (same data as dual).
* ``primal``: ``min 1/2 (v - v-)^T M (v - v-)  s.t.  G^T v + c (G^T v- + nrel) + nrel >= 0``
  over the degrees of freedom with finite mass (kinematic ones keep v = v-). Its
  multipliers are the impulses l.
* ``dual-factored``: the dual with ``Q = L^T L``, ``L = M^-1/2 G``:
  ``min 1/2 ||L l||^2 + b^T l  s.t.  l >= 0`` (Q never formed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem

FORMULATIONS = ("dual", "primal", "dual-factored", "lcp")


@dataclass(frozen=True)
class PrimalQP:
    """``min 1/2 v^T P v + q^T v  s.t.  A v >= lower`` on the free degrees of freedom.

    ``P = diag(M_free)``, ``q = -M_free v-_free``, ``A = G_free^T`` and
    ``lower = -(G_kin^T v-_kin + c (G^T v- + nrel) + nrel)``; ``free`` marks the
    degrees of freedom with m_inv > 0.
    """

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    lower: np.ndarray
    free: np.ndarray

    def v_plus(self, problem: ImpactProblem, v_free: np.ndarray) -> np.ndarray:
        """The full velocity: v_free on free degrees of freedom, v- elsewhere.

        Parameters
        ----------
        problem : ImpactProblem
            The problem this QP was posed from.
        v_free : np.ndarray
            The QP's solution, one entry per free degree of freedom.

        Returns
        -------
        np.ndarray
            v+, shape (d,).
        """
        velocity = problem.v_minus.copy()
        velocity[self.free] = v_free
        return velocity


def primal_qp(problem: ImpactProblem) -> PrimalQP:
    """The velocity-space QP of ``problem`` (see the module docstring), built once.

    Parameters
    ----------
    problem : ImpactProblem
        The problem; the QP is kept in ``problem.posed["primal"]``.

    Returns
    -------
    PrimalQP
        The QP.
    """
    if "primal" not in problem.posed:
        problem.posed["primal"] = _primal_qp(problem)
    return problem.posed["primal"]


def _primal_qp(problem: ImpactProblem) -> PrimalQP:
    free = problem.m_inv > 0
    G = sp.csr_matrix(problem.G)
    G_free = sp.csc_matrix(G[free])
    G_kin = sp.csc_matrix(G[~free])
    mass_free = 1.0 / problem.m_inv[free]
    u_minus = problem.G.T @ problem.v_minus
    lower = -(
        G_kin.T @ problem.v_minus[~free]
        + problem.restitution * (u_minus + problem.n_rel)
        + problem.n_rel
    )
    return PrimalQP(
        P=sp.csc_matrix(sp.diags(mass_free)),
        q=-mass_free * problem.v_minus[free],
        A=sp.csc_matrix(G_free.T),
        lower=np.asarray(lower, dtype=float),
        free=free,
    )


@dataclass(frozen=True)
class FactoredDualQP:
    """The dual with ``Q = L^T L`` as a QP in ``x = (l, y)`` that never forms Q.

    ``min 1/2 y^T y + b^T l  s.t.  L l - y = 0,  l >= 0``, with ``L = M^-1/2 G`` restricted
    to the degrees of freedom with finite mass (its other rows are zero). In qpsolvers'
    form: ``P = diag(0_n, I_k)``, ``q = (b, 0)``, ``A = [L, -I]``, ``A x = 0``,
    ``G = [-I, 0]``, ``G x <= 0``. The impulses are ``x[:n]``.
    """

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    b_eq: np.ndarray
    G: sp.csc_matrix
    h: np.ndarray
    n_contacts: int

    def impulses(self, x: np.ndarray) -> np.ndarray:
        """l = x[:n].

        Parameters
        ----------
        x : np.ndarray
            The QP's solution (l, y), shape (n + k,).

        Returns
        -------
        np.ndarray
            The impulses l, shape (n,).
        """
        return np.asarray(x[: self.n_contacts], dtype=float)


def factored_rows(problem: ImpactProblem) -> sp.csc_matrix:
    """L = M^-1/2 G without the rows of kinematic degrees of freedom, built once.

    L is k x n, with k the free degrees of freedom.

    Parameters
    ----------
    problem : ImpactProblem
        The problem; L is kept in ``problem.posed["factored_rows"]``.

    Returns
    -------
    sp.csc_matrix
        The rows of L of the degrees of freedom with m_inv > 0, k x n.
    """
    if "factored_rows" not in problem.posed:
        free = problem.m_inv > 0
        problem.posed["factored_rows"] = sp.csc_matrix(sp.csr_matrix(problem.L)[free])
    return problem.posed["factored_rows"]


def factored_dual_qp(problem: ImpactProblem) -> FactoredDualQP:
    """The dual-factored formulation as a QP (see :class:`FactoredDualQP`), built once.

    Parameters
    ----------
    problem : ImpactProblem
        The problem; the QP is kept in ``problem.posed["dual-factored"]``.

    Returns
    -------
    FactoredDualQP
        The QP.
    """
    if "dual-factored" not in problem.posed:
        problem.posed["dual-factored"] = _factored_dual_qp(problem)
    return problem.posed["dual-factored"]


def _factored_dual_qp(problem: ImpactProblem) -> FactoredDualQP:
    L = factored_rows(problem)
    k, n = L.shape
    P = sp.block_diag([sp.csc_matrix((n, n)), sp.identity(k)], format="csc")
    return FactoredDualQP(
        P=P,
        q=np.concatenate([problem.b, np.zeros(k)]),
        A=sp.csc_matrix(sp.hstack([L, -sp.identity(k)])),
        b_eq=np.zeros(k),
        G=sp.csc_matrix(sp.hstack([-sp.identity(n), sp.csc_matrix((n, k))])),
        h=np.zeros(n),
        n_contacts=n,
    )


def pose(problem: ImpactProblem | FrictionalProblem, formulation: str) -> None:
    """Builds the matrices ``formulation`` hands a solver, kept on ``problem``.

    These are ``Q``, ``b`` and ``diag(Q)`` for ``dual`` and ``lcp``; :func:`primal_qp` for
    ``primal``; :func:`factored_dual_qp` (with L) for ``dual-factored``. The same for every
    solver of a formulation, so it is timed apart (``formulation_time_s``). A frictional
    problem's formulations are posed by :func:`_pose_frictional`.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem; what is built is cached on it.
    formulation : str
        One of :data:`FORMULATIONS`, or of :data:`FRICTIONAL_FORMULATIONS` for a frictional
        problem.

    Raises
    ------
    ValueError
        When ``formulation`` is unknown for the problem's kind.
    """
    if isinstance(problem, FrictionalProblem):
        _pose_frictional(problem, formulation)
    elif formulation in ("dual", "lcp"):
        _ = problem.Q, problem.b, problem.diag_Q
    elif formulation == "primal":
        primal_qp(problem)
    elif formulation == "dual-factored":
        factored_dual_qp(problem)
    else:
        raise ValueError(f"unknown formulation {formulation!r}")


FRICTIONAL_FORMULATIONS = ("staggered", "lcp", "nsgs", "ccp", "fc2d")


def _pose_frictional(problem: FrictionalProblem, formulation: str) -> None:
    """``W``, ``q`` and ``diag(W_NN)`` for ``staggered``, ``nsgs`` and ``fc2d``, and for
    ``staggered`` W's blocks ``W_NT``, ``W_TT`` and ``W_TN`` of its two QPs; the relaxed impact
    problem with its ``Q``, ``b`` for ``ccp``; the Stewart-Trinkle LCP for ``lcp``."""
    if formulation == "staggered":
        _ = (problem.W, problem.q, problem.diag_N, problem.scale, problem.W_NT, problem.W_TT,
             problem.W_TN)
    elif formulation in ("nsgs", "fc2d"):
        _ = problem.W, problem.q, problem.diag_N, problem.scale
    elif formulation == "ccp":
        relaxed = problem.relaxed()
        _ = relaxed.Q, relaxed.b, relaxed.diag_Q
    elif formulation == "lcp":
        if "lcp" not in problem.posed:
            problem.posed["lcp"] = problem.stewart_trinkle()
    else:
        raise ValueError(f"unknown frictional formulation {formulation!r} (known: "
                         f"{', '.join(FRICTIONAL_FORMULATIONS)})")


@dataclass(frozen=True)
class PsdCertificate:
    """Evidence that Q is positive semi-definite, computed here rather than assumed.

    ``method`` is ``eigenvalues`` (the smallest eigenvalue of the symmetric Q, accepted
    when ``>= -tolerance``) or ``gram`` (for large n: ``||Q - L^T L||_max <= tolerance``,
    so Q is a Gram matrix up to rounding). ``tolerance = 100 n eps_machine max|Q_ij|``.
    """

    psd: bool
    method: str
    value: float
    tolerance: float


EIGENVALUE_LIMIT = 200  # beyond it the Gram check, O(nnz), bounds lambda_min(Q) >= -n max|E|


def certify_psd(problem: ImpactProblem) -> PsdCertificate:
    """Certifies Q = G^T M^-1 G positive semi-definite (see :class:`PsdCertificate`).

    Parameters
    ----------
    problem : ImpactProblem
        The problem whose Q is checked.

    Returns
    -------
    PsdCertificate
        Whether Q is PSD, by which method (``empty``, ``eigenvalues`` or ``gram``), the
        value found and the tolerance.
    """
    Q = problem.Q
    n = problem.n_contacts
    largest = float(np.max(np.abs(Q.data), initial=0.0))
    tolerance = 100.0 * max(n, 1) * np.finfo(float).eps * max(largest, np.finfo(float).tiny)
    if n == 0:
        return PsdCertificate(True, "empty", 0.0, tolerance)
    symmetric = float(np.max(np.abs((Q - Q.T).data), initial=0.0)) == 0.0
    if n <= EIGENVALUE_LIMIT:
        smallest = float(np.linalg.eigvalsh(Q.toarray())[0])
        return PsdCertificate(symmetric and smallest >= -tolerance, "eigenvalues", smallest,
                              tolerance)
    gram = problem.L.T @ problem.L
    difference = sp.csr_matrix(Q - gram)
    gap = float(np.max(np.abs(difference.data), initial=0.0))
    return PsdCertificate(symmetric and gap <= tolerance, "gram", gap, tolerance)


def regularized(Q: sp.spmatrix, delta: float) -> sp.csc_matrix:
    """Q + delta I: a different problem, used only by variants named ``*-reg``.

    Parameters
    ----------
    Q : sp.spmatrix
        A square matrix.
    delta : float
        The shift added to its diagonal.

    Returns
    -------
    sp.csc_matrix
        Q + delta I.
    """
    return sp.csc_matrix(Q + delta * sp.identity(Q.shape[0], format="csc"))
