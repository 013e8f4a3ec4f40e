"""Jacobi and mass scaling of an impact problem.

With ``S = diag(Q)^-1/2`` and velocities measured in ``v' = M^1/2 v`` on the free
degrees of freedom, the scaled problem has ``G' = M^-1/2 G S`` (unit columns),
``M' = I``, ``Q' = S Q S`` (unit diagonal), ``b' = S b`` and impulses
``l = S l'``; kinematic degrees of freedom (m_inv = 0) move into nrel:
``nrel' = S (nrel + G_kin^T v-_kin)``. Mass ratios of 1e12 become harmless.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem


@dataclass(frozen=True)
class ScaledProblem:
    """The scaled problem and the maps back to the original."""

    scaled: ImpactProblem
    contact_scale: np.ndarray  # S, so that l = S l'
    free: np.ndarray
    original: ImpactProblem

    def impulses(self, scaled_impulses: np.ndarray) -> np.ndarray:
        """l = S l'.

        Parameters
        ----------
        scaled_impulses : np.ndarray
            Impulses l' of the scaled problem, shape (n,).

        Returns
        -------
        np.ndarray
            The impulses l of the original problem, shape (n,).
        """
        return self.contact_scale * scaled_impulses

    def velocity(self, scaled_velocity: np.ndarray) -> np.ndarray:
        """v = M^-1/2 v' on the free degrees of freedom, v- on the kinematic ones.

        Parameters
        ----------
        scaled_velocity : np.ndarray
            Velocities v' of the scaled problem, one per free degree of freedom.

        Returns
        -------
        np.ndarray
            The velocities of the original problem, shape (d,).
        """
        velocity = self.original.v_minus.copy()
        velocity[self.free] = scaled_velocity * np.sqrt(self.original.m_inv[self.free])
        return velocity


def jacobi_scaled(problem: ImpactProblem) -> ScaledProblem:
    """The scaled form of ``problem`` (see the module docstring).

    Parameters
    ----------
    problem : ImpactProblem
        The problem to scale.

    Returns
    -------
    ScaledProblem
        The scaled problem, S, the mask of free degrees of freedom and the original.
    """
    free = problem.m_inv > 0
    diagonal = problem.diag_Q
    contact_scale = np.where(diagonal > 0, 1.0 / np.sqrt(np.where(diagonal > 0, diagonal, 1.0)),
                             1.0)
    G = sp.csr_matrix(problem.G)
    root_m_inv = np.sqrt(problem.m_inv[free])
    G_scaled = sp.diags(root_m_inv) @ G[free] @ sp.diags(contact_scale)
    n_rel = contact_scale * (problem.n_rel + G[~free].T @ problem.v_minus[~free])
    scaled = ImpactProblem(
        name=problem.name,
        G=sp.csc_matrix(G_scaled),
        m_inv=np.ones(int(free.sum())),
        v_minus=problem.v_minus[free] / root_m_inv,
        restitution=problem.restitution,
        n_rel=np.asarray(n_rel, dtype=float),
        family=problem.family,
        source=problem.source,
    )
    return ScaledProblem(scaled, contact_scale, free, problem)
