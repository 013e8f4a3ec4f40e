"""The policy blocks of pi-robust's Python path: their factors, kept and updated.

Each policy solve of ``qpbench.solvers.pi_robust`` solves ``(Q_FF + rho D_F) x_F = r`` for
the free contacts F of a policy. :class:`BlockSolver` factors those blocks, densely on dense
LCPs (``fixed_order_dense``: Cholesky, or on a few contacts Gaussian elimination, in an order
that does not depend on the CPU), and on sparse ones over the degrees of freedom in Woodbury
form when fewer of them move than F has contacts (``lcp_interior.WoodburyFactor``), else over
the contacts (``sparse_cholesky.symmetric_factor``). It keeps the last factors by (policy,
rho), so prox steps on a settled policy cost triangular solves only, and it makes a Woodbury
block whose policy differs in a few contacts from the last one's by a low-rank update of that
block's factor (``sparse_cholesky.updated_gram_factor``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import fixed_order_dense, sparse_cholesky
from qpbench.solvers.lcp import Lcp
from qpbench.solvers.lcp_interior import WoodburyFactor, moving_rows
from qpbench.solvers.sparse_cholesky import symmetric_factor, updated_gram_factor

# iterative-refinement steps of a policy block solved over the degrees of freedom
# (lcp_interior.WoodburyFactor)
BLOCK_REFINEMENTS = 1
# a policy block over the degrees of freedom whose policy differs from the last one's in at
# most this many contacts (at the same rho) is factored by updating that block's factor
UPDATE_CONTACTS = 64


class SmallBlock(NamedTuple):
    """A dense policy block of at most ``BlockSolver.small`` contacts, kept as it is and solved
    by Gaussian elimination at each use (cheaper there than a factor kept)."""

    block: np.ndarray


class BlockSolver:
    """Solves ``(Q_FF + rho D_F) x = r`` for a policy F, keeping the last ``keep`` factors."""

    def __init__(self, lcp: Lcp, keep: int = 2, small: int = 64) -> None:
        self.lcp = lcp
        self.dense = lcp.dense
        self.small = small  # blocks up to this size are solved by LU each time (cheapest)
        self.Q_dense = lcp.op if self.dense else None
        self.Q_csc = None if self.dense else sp.csc_matrix(lcp.Q)
        # Q's factor L = M^-1/2 G, whose columns give a sparse block's Woodbury form
        self.L = None if self.dense or not isinstance(lcp.problem, ImpactProblem) \
            else lcp.problem.L
        self.keep = keep
        self.cache: dict[tuple[bytes, float], object] = {}
        self.factorizations = 0
        self.factorizations_over_dofs = 0  # of them, blocks factored through L (Woodbury)
        self.factor_updates = 0  # of those, made by updating the block before's factor
        # the rows of L that some contact moves (made at the first Woodbury block), and the
        # last Woodbury block made over them: its policy, rho and factor
        self.moving: sp.csc_matrix | None = None
        self.last_woodbury: tuple[np.ndarray, float, WoodburyFactor] | None = None
        # L's stored entries as ones (made at the first question of :meth:`_over_dofs`): its
        # product with a policy's indicator is non-zero on the rows those contacts move
        self.pattern: sp.csc_matrix | None = None

    def counts(self) -> dict[str, int]:
        """The factorizations so far, and how many of them ran over the degrees of freedom.

        Returns
        -------
        dict[str, int]
            ``factorizations``, every block factored (or, up to ``small`` contacts, formed
            for LU) since construction; ``factorizations_over_dofs``, those of them factored
            through Q's factor L in Woodbury form; ``factor_updates``, those of these made by
            a low-rank update of the block before's factor.
        """
        return {"factorizations": self.factorizations,
                "factorizations_over_dofs": self.factorizations_over_dofs,
                "factor_updates": self.factor_updates}

    def solve(self, policy: np.ndarray, index: np.ndarray, rho: float, rhs: np.ndarray
              ) -> np.ndarray:
        """Solve ``(Q_FF + rho D_F) x_F = rhs`` on the policy's free contacts F.

        The factor of the block is taken from the cache under the key (policy, rho), or made
        and counted; it becomes the most recently used, and the least recently used beyond
        ``keep`` are dropped. D_F is ``lcp.safe_diag`` (zeros replaced).

        Parameters
        ----------
        policy : np.ndarray
            Boolean, n entries: the free contacts F (part of the cache key).
        index : np.ndarray
            The indices of F, ``np.flatnonzero(policy)``.
        rho : float
            The prox weight (part of the cache key).
        rhs : np.ndarray
            The right side, one entry per free contact (in the order of ``index``).

        Returns
        -------
        np.ndarray
            x_F, one entry per free contact.

        Raises
        ------
        np.linalg.LinAlgError
            When the block cannot be factored (or, up to ``small`` contacts, is singular).
        """
        key = (np.packbits(policy).tobytes(), rho)
        factor = self.cache.pop(key, None)
        if factor is None:
            factor = self._factor(policy, index, rho)
            self.factorizations += 1
        self.cache[key] = factor  # the most recently used last
        while len(self.cache) > self.keep:
            self.cache.pop(next(iter(self.cache)))
        if isinstance(factor, SmallBlock):
            return fixed_order_dense.lu_solve(factor.block, rhs)
        if self.dense:
            return fixed_order_dense.cholesky_solve(factor, rhs)
        return factor.solve(rhs)

    def _factor(self, policy: np.ndarray, index: np.ndarray, rho: float) -> object:
        shift = rho * self.lcp.safe_diag[index]
        if self.dense:
            block = self.Q_dense[np.ix_(index, index)]
            block[np.diag_indices_from(block)] += shift
            if index.size <= self.small:
                return SmallBlock(block)
            return fixed_order_dense.cholesky(block)
        if self._over_dofs(index):
            self.factorizations_over_dofs += 1
            return self._woodbury(policy, index, rho, shift)
        return symmetric_factor(self.Q_csc[:, index][index, :] + sp.diags(shift))

    def updatable(self, policy: np.ndarray) -> bool:
        """Whether the block of ``policy`` goes in Woodbury form, which later blocks update.

        Parameters
        ----------
        policy : np.ndarray
            Boolean, n entries: the free contacts F.

        Returns
        -------
        bool
            The LCP is sparse with Q's factor L, fewer degrees of freedom move under F than F
            has contacts, and the factors can be updated (CHOLMOD).
        """
        return sparse_cholesky.cholmod is not None and self._over_dofs(np.flatnonzero(policy))

    def _over_dofs(self, index: np.ndarray) -> bool:
        """Whether the block of the contacts ``index`` goes over the degrees of freedom: the LCP
        is sparse with Q's factor L, and fewer degrees of freedom move than it has contacts (the
        rows of ``L[:, index]`` with a stored entry, counted as one product with L's pattern
        rather than by slicing L)."""
        if self.dense or self.L is None:
            return False
        if self.pattern is None:
            self.pattern = sp.csc_matrix(self.L, copy=True)
            self.pattern.data[:] = 1.0
        chosen = np.zeros(self.pattern.shape[1])
        chosen[index] = 1.0
        return int(np.count_nonzero(self.pattern @ chosen)) < index.size

    def _woodbury(self, policy: np.ndarray, index: np.ndarray, rho: float, shift: np.ndarray
                  ) -> WoodburyFactor:
        """The block in Woodbury form over every degree of freedom that some contact moves.

        ``K = I + A_F D_F^-1 A_F^T`` (A = the moving rows of L, D_F = ``shift``) is made by
        updating the last Woodbury block's K when it had the same rho and its policy differs
        from this one in at most ``UPDATE_CONTACTS`` contacts: contact j entering F adds
        ``a_j a_j^T / D_j``, one leaving subtracts it
        (``sparse_cholesky.updated_gram_factor``); else, or when the update fails, K is
        factored afresh. The refinement step of :class:`WoodburyFactor` works with A and D
        themselves, so it corrects what an update's rounding leaves."""
        if self.moving is None:
            self.moving = sp.csc_matrix(moving_rows(self.L))
        factor = None
        if self.last_woodbury is not None and self.last_woodbury[1] == rho:
            last_policy, _, last = self.last_woodbury
            added = np.flatnonzero(policy & ~last_policy)
            removed = np.flatnonzero(last_policy & ~policy)
            if added.size + removed.size <= UPDATE_CONTACTS:
                try:
                    factor = updated_gram_factor(last.factor, self._columns(added, rho),
                                                 self._columns(removed, rho))
                except np.linalg.LinAlgError:
                    factor = None
        woodbury = WoodburyFactor(sp.csr_matrix(self.moving[:, index]), shift,
                                  refinements=BLOCK_REFINEMENTS, factor=factor)
        self.factor_updates += factor is not None
        self.last_woodbury = (policy.copy(), rho, woodbury)
        return woodbury

    def _columns(self, contacts: np.ndarray, rho: float) -> sp.csc_matrix:
        """``a_j / sqrt(rho D_j)`` for the given contacts j: the columns of a K update."""
        return sp.csc_matrix(self.moving[:, contacts]
                             @ sp.diags(1.0 / np.sqrt(rho * self.lcp.safe_diag[contacts])))
