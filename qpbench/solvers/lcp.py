"""The impact LCP as the solvers written here see it, and the output they share.

``find l >= 0 with w = Q l + b >= 0 and l^T w = 0``. Every solver here stops on
qpbench's own measure, ``residual(l) = ||min(D l, Q l + b)||_inf / scale`` with
``D = diag(Q)`` and ``scale = max(||b||_inf, tiny)``, so that a solver's "converged"
means what qpbench's verdict means.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from qpbench import __version__
from qpbench.problem import metrics
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import fixed_order_dense
from qpbench.solvers.base import SolverOutput

BACKEND = "qpbench"
FORMULATION = "lcp"
VERSION = __version__


@dataclass
class Lcp:
    """Q (CSR), b, D = diag(Q) and the residual's scale of one problem; ``op`` is Q for
    products: a dense array on small problems (no sparse overhead), else Q itself. Products
    with Q go through :meth:`times`, which sums a dense one in a fixed order."""

    Q: sp.csr_matrix
    b: np.ndarray
    diag: np.ndarray
    scale: float
    op: np.ndarray | sp.csr_matrix | None = None
    problem: ImpactProblem | None = None

    def __post_init__(self) -> None:
        if self.op is None:
            self.op = self.Q

    @classmethod
    def of(cls, problem: ImpactProblem, dense_limit: int = 0) -> Lcp:
        """The LCP of ``problem``; ``op`` dense when it has at most ``dense_limit`` contacts.

        Parameters
        ----------
        problem : ImpactProblem
            The impact whose Q, b and diag(Q) are taken.
        dense_limit : int, optional
            The most contacts for which ``op`` is Q as a dense array; 0 (the default) keeps
            it sparse.

        Returns
        -------
        Lcp
            Q in CSR form, b, D, the residual's scale, ``op`` and the problem itself.
        """
        Q = sp.csr_matrix(problem.Q)
        b = np.asarray(problem.b, dtype=float)
        scale = metrics.vector_scale(b)
        op = Q.toarray() if Q.shape[0] <= dense_limit else Q
        return cls(Q=Q, b=b, diag=np.asarray(problem.diag_Q, dtype=float), scale=scale, op=op,
                   problem=problem)

    @property
    def dense(self) -> bool:
        return isinstance(self.op, np.ndarray)

    @property
    def n(self) -> int:
        return int(self.b.shape[0])

    @cached_property
    def safe_diag(self) -> np.ndarray:
        """D with zero entries (contacts that move nothing) replaced by 1, for divisions."""
        return np.where(self.diag > 0.0, self.diag, 1.0)

    def times(self, x: np.ndarray) -> np.ndarray:
        """Q x: by ``op``'s sparse product, or, with ``op`` dense, summed in an order that does
        not depend on the CPU (``fixed_order_dense.symmetric_product``, not the BLAS).

        Parameters
        ----------
        x : np.ndarray
            A vector of n entries.

        Returns
        -------
        np.ndarray
            Q x, n entries.
        """
        if self.dense:
            return fixed_order_dense.symmetric_product(self.op, x)
        return self.op @ x

    def w(self, impulses: np.ndarray) -> np.ndarray:
        """w = Q l + b.

        Parameters
        ----------
        impulses : np.ndarray
            l, shape (n,).

        Returns
        -------
        np.ndarray
            w, shape (n,).
        """
        return self.times(impulses) + self.b

    def residual_of(self, impulses: np.ndarray, w: np.ndarray) -> float:
        """||min(D l, w)||_inf / scale for a w already computed.

        Parameters
        ----------
        impulses : np.ndarray
            l, shape (n,).
        w : np.ndarray
            Q l + b for these impulses, shape (n,).

        Returns
        -------
        float
            The scaled residual; 0 for a problem without contacts.
        """
        if impulses.size == 0:
            return 0.0
        return float(np.max(np.abs(np.minimum(self.diag * impulses, w)))) / self.scale

    def residual(self, impulses: np.ndarray) -> float:
        """||min(D l, Q l + b)||_inf / scale (qpbench's residual).

        Parameters
        ----------
        impulses : np.ndarray
            l, shape (n,).

        Returns
        -------
        float
            The scaled residual.
        """
        return self.residual_of(impulses, self.w(impulses))

    def converged(self, impulses: np.ndarray, tol: float, w: np.ndarray | None = None) -> bool:
        """Whether qpbench's own ``metrics.residual(problem, l) <= tol``.

        A solver's "converged" is thus exactly qpbench's verdict (the same formula with other
        products can round differently near 1e-8 on extreme mass ratios); the fast residual
        only screens out answers ten times above tol. Without a problem the fast residual
        decides alone.

        Parameters
        ----------
        impulses : np.ndarray
            l, shape (n,).
        tol : float
            The residual to reach.
        w : np.ndarray or None, optional
            Q l + b when already computed; None computes it.

        Returns
        -------
        bool
            True when the residual is at most ``tol``.
        """
        fast = self.residual_of(impulses, self.w(impulses) if w is None else w)
        if self.problem is None:
            return fast <= tol
        if fast > 10.0 * tol:  # far above: no rounding difference can bridge that
            return False
        return bool(metrics.residual(self.problem, impulses) <= tol)

    def start(self, warm_start: np.ndarray | None) -> np.ndarray:
        """The warm start clipped to l >= 0 when it has the right size and is finite, else 0.

        Parameters
        ----------
        warm_start : np.ndarray or None
            A guess of l (flattened); None, a wrong size or a non-finite entry gives zeros.

        Returns
        -------
        np.ndarray
            The starting impulses, shape (n,), all >= 0.
        """
        if warm_start is not None:
            warm = np.asarray(warm_start, dtype=float).ravel()
            if warm.shape == (self.n,) and np.all(np.isfinite(warm)):
                return np.maximum(warm, 0.0)
        return np.zeros(self.n)


def output(impulses: np.ndarray | None, converged: bool, status: str, iterations: int,
           **info: object) -> SolverOutput:
    """A SolverOutput whose claim is the algorithm's own convergence test.

    Parameters
    ----------
    impulses : np.ndarray or None
        l, or None when the algorithm gave none.
    converged : bool
        The algorithm's own convergence test; it becomes ``claimed_success``.
    status : str
        The algorithm's status in its own words.
    iterations : int
        The iterations (or pivots) it took.
    **info : object
        Extra facts of the solve, stored as ``info``.

    Returns
    -------
    SolverOutput
        The output, with its times still unset.
    """
    return SolverOutput(impulses=impulses, status=status, claimed_success=bool(converged),
                        iterations=int(iterations), info=dict(info))
