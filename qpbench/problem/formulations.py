"""The formulations of one impact problem (DESIGN section 1), as plain arrays for backends.

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
        """The full velocity: v_free on free degrees of freedom, v- elsewhere."""
        velocity = problem.v_minus.copy()
        velocity[self.free] = v_free
        return velocity


def primal_qp(problem: ImpactProblem) -> PrimalQP:
    """The velocity-space QP of ``problem`` (see the module docstring)."""
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


def impulses_from_velocity(problem: ImpactProblem, v_plus: np.ndarray) -> np.ndarray:
    """The least-squares l with M^-1 G l = v+ - v- (for a primal solver that gives no multipliers)."""
    from scipy.sparse.linalg import lsqr

    return lsqr(problem.M_inv_G, v_plus - problem.v_minus, atol=1e-15, btol=1e-15)[0]
