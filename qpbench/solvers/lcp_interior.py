"""A primal-dual interior point for the monotone impact LCP: pi-robust's safe path.

Source: Mehrotra, "On the implementation of a primal-dual interior point method",
SIAM J. Optim. 2(4), 1992 (predictor-corrector); for LCPs: Wright, "Primal-Dual
Interior-Point Methods", SIAM 1997, chapter 8. Iterates keep ``l, w > 0`` and drive
``r = Q l + b - w`` and ``mu = l^T w / n`` to zero. Each step solves
``(Q + W L^-1) dl = rhs`` twice with one Cholesky factor (positive definite for
l, w > 0 even when Q is singular), then ``dw = Q dl + r``; one common step length
(0.99 of the way to the boundary) keeps ``r`` shrinking by ``1 - alpha``. Up to
``CENTRALITY_CORRECTORS`` more solves with the same factor then lengthen that step
(Gondzio's multiple centrality correctors, :func:`_centrality_corrected`): where a
factorization costs far more than a solve (large sparse problems), they take the place of
some iterations.

Those systems are solved over the contacts (:class:`NormalMatrix`), or, when the problem has
fewer moving degrees of freedom than contacts, over the degrees of freedom through Q's factor
``L = M^-1/2 G`` (:class:`FactoredNormalMatrix`, by :class:`WoodburyFactor`, which
pi-robust's policy blocks use too): the same directions, from a smaller and sparser matrix
(a dense pile of boxes has about 3 degrees of freedom a body against about 8 contacts).

It does not polish: the caller (pi-robust) hands each iterate, once close, to its
policy iteration, which ends on an exact active set.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from qpbench.problem import metrics
from qpbench.problem.metrics import dot
from qpbench.solvers import fixed_order_dense
from qpbench.solvers.lcp import Lcp
from qpbench.solvers.sparse_cholesky import PatternFactor, gram_factor

# what a try_finish of interior_point returns for an iterate it chose not to try
NOT_TRIED = np.empty(0)
# Gondzio's centrality correctors (_centrality_corrected): at most this many a step; each
# aims at a step STEP_GAIN longer and is kept when it gains ACCEPTED_GAIN of that; the
# products l_i w_i it steers into [CENTRAL_LOW, CENTRAL_HIGH] times sigma mu
CENTRALITY_CORRECTORS = 3
STEP_GAIN = 0.2
ACCEPTED_GAIN = 0.1
CENTRAL_LOW, CENTRAL_HIGH = 0.1, 10.0


def _step_to_boundary(value: np.ndarray, change: np.ndarray) -> float:
    """The largest alpha <= 1 with value + alpha * change >= 0."""
    shrinking = change < 0.0
    if not np.any(shrinking):
        return 1.0
    return float(min(1.0, np.min(-value[shrinking] / change[shrinking])))


def _longest_step(impulses: np.ndarray, slack: np.ndarray, dl: np.ndarray, dw: np.ndarray
                  ) -> float:
    """The largest alpha <= 1 with l + alpha dl >= 0 and w + alpha dw >= 0."""
    return min(_step_to_boundary(impulses, dl), _step_to_boundary(slack, dw))


def _centrality_corrected(impulses: np.ndarray, slack: np.ndarray, dl: np.ndarray,
                          dw: np.ndarray, target: float,
                          normal: NormalMatrix | FactoredNormalMatrix,
                          step_of_change: Callable[[np.ndarray], np.ndarray]
                          ) -> tuple[np.ndarray, np.ndarray, float]:
    """The direction (dl, dw) lengthened by Gondzio's multiple centrality correctors.

    Gondzio, "Multiple centrality corrections in a primal-dual method for linear
    programming", Comput. Optim. Appl. 6, 1996. Let alpha be the longest step to the boundary
    along (dl, dw). Each corrector looks at the point a step ``a = min(1, alpha + STEP_GAIN)``
    along the direction, where some products ``v_i = (l_i + a dl_i)(w_i + a dw_i)`` are far from
    the target ``sigma mu`` (too small ones stop the step), and asks for the change ``t - v``,
    t being v projected into ``[CENTRAL_LOW, CENTRAL_HIGH] * target`` (and no product cut by
    more than ``CENTRAL_HIGH * target``): ``(Q + W L^-1) c = (t - v) / l`` with the
    iteration's factor, ``dw`` changed by ``Q c`` (the linearized feasibility is kept).
    The corrected direction is kept while its step to the boundary grows by at least
    ``ACCEPTED_GAIN * STEP_GAIN``; at most ``CENTRALITY_CORRECTORS`` of them, none once the
    full step fits.

    Parameters
    ----------
    impulses, slack : np.ndarray
        The iterate's l > 0 and w > 0 (scaled), shape (n,).
    dl, dw : np.ndarray
        Mehrotra's predictor-corrector direction, shape (n,).
    target : float
        ``sigma mu``, the products' target.
    normal : NormalMatrix or FactoredNormalMatrix
        Holds this iteration's factor of ``Q~ + W L^-1`` (its ``solve``).
    step_of_change : callable
        ``dw``'s change for a change c of dl (``(Q~ + prox I) c``).

    Returns
    -------
    dl, dw : np.ndarray
        The direction, corrected or as given.
    step : float
        Its longest step to the boundary, at most 1.
    """
    step = _longest_step(impulses, slack, dl, dw)
    lower, upper = CENTRAL_LOW * target, CENTRAL_HIGH * target
    for _ in range(CENTRALITY_CORRECTORS):
        if step >= 1.0:
            break
        reach = min(1.0, step + STEP_GAIN)
        products = (impulses + reach * dl) * (slack + reach * dw)
        wanted = np.maximum(np.clip(products, lower, upper) - products, -upper)
        correction = normal.solve(wanted / impulses)
        corrected_dl, corrected_dw = dl + correction, dw + step_of_change(correction)
        corrected = _longest_step(impulses, slack, corrected_dl, corrected_dw)
        if corrected < step + ACCEPTED_GAIN * STEP_GAIN:
            break
        dl, dw, step = corrected_dl, corrected_dw, corrected
    return dl, dw, step


class NormalMatrix:
    """Factors ``Q~ + diag(d)`` of the scaled LCP (dense Cholesky in a fixed order,
    ``fixed_order_dense``, or sparse: one :class:`~qpbench.solvers.sparse_cholesky.PatternFactor`
    for every iteration's matrix) and solves with it; keeps the scaled LCP and its scaling
    ``root``."""

    over = "contacts"

    def __init__(self, lcp: Lcp, root: np.ndarray) -> None:
        self.lcp, self.root = lcp, root
        self.dense = lcp.dense
        self.Q_dense = lcp.op if self.dense else None
        self.Q_csc = None if self.dense else sp.csc_matrix(lcp.Q)
        self.pattern: PatternFactor | None = None  # made at the first sparse factorization
        self.factor: object = None

    def factorize(self, diagonal: np.ndarray) -> None:
        """Factors ``Q~ + diag(diagonal)`` for the next solves.

        Parameters
        ----------
        diagonal : np.ndarray
            d, shape (n,), positive.

        Raises
        ------
        np.linalg.LinAlgError
            When the matrix is not numerically positive definite.
        """
        if self.dense:
            matrix = self.Q_dense.copy()
            matrix[np.diag_indices_from(matrix)] += diagonal
            self.factor = fixed_order_dense.cholesky(matrix)
        else:
            if self.pattern is None:
                self.pattern = PatternFactor(self.Q_csc)
            self.factor = self.pattern.factorize(diagonal)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``(Q~ + diag(d))^-1 rhs`` with the last factor.

        Parameters
        ----------
        rhs : np.ndarray
            The right-hand side, shape (n,).

        Returns
        -------
        np.ndarray
            The solution, shape (n,).
        """
        if self.dense:
            return fixed_order_dense.cholesky_solve(self.factor, rhs)
        return self.factor.solve(rhs)


def moving_rows(factor: sp.spmatrix) -> sp.csr_matrix:
    """The rows of ``factor`` (L = M^-1/2 G, or some of its columns) that have an entry.

    They are the degrees of freedom that those contacts move.

    Parameters
    ----------
    factor : sp.spmatrix
        L or some of its columns, shape (d, k).

    Returns
    -------
    sp.csr_matrix
        Its nonzero rows, in order.
    """
    factor = sp.csr_matrix(factor)
    return factor[np.flatnonzero(np.diff(factor.indptr))]


class WoodburyFactor:
    """Solves ``(A^T A + diag(d)) x = rhs`` (d > 0) by the Sherman-Morrison-Woodbury identity

        (A^T A + D)^-1 = D^-1 - D^-1 A^T (I + A D^-1 A^T)^-1 A D^-1,

    factoring ``K = I + A D^-1 A^T`` (:mod:`qpbench.solvers.sparse_cholesky`, one row per row
    of A; K >= I is positive definite whatever d > 0 is), then ``refinements`` steps of
    iterative refinement, ``x += solve(rhs - (A^T A + D) x)``. Why refine: the subtraction
    loses about ``log10(max(A^T A) / min(d))`` digits when d is small beside A^T A (policy
    blocks ``Q_FF + rho D_F`` with rho = 1e-5), and each step wins them back."""

    def __init__(self, A: sp.csr_matrix, diagonal: np.ndarray, refinements: int = 0,
                 A_T: sp.csr_matrix | None = None, pattern: PatternFactor | None = None,
                 factor: object | None = None) -> None:
        """``A_T``: A's transpose in CSR, and ``pattern``: ``PatternFactor(A,
        symmetric=False)``, when the caller keeps them across factorizations; ``factor``: K's
        factor, when the caller has made it (by updating another's)."""
        self.A, self.A_T = A, sp.csr_matrix(A.T) if A_T is None else A_T
        self.diagonal, self.inverse = diagonal, 1.0 / diagonal
        self.refinements = refinements
        scales = np.sqrt(self.inverse)
        if factor is not None:
            self.factor = factor
        elif pattern is not None:
            self.factor = pattern.factorize(scales)
        else:
            self.factor = gram_factor(A @ sp.diags(scales))

    def _inverse_times(self, rhs: np.ndarray) -> np.ndarray:
        """``D^-1 rhs - D^-1 A^T K^-1 A D^-1 rhs``."""
        spread = self.inverse * rhs
        return spread - self.inverse * (self.A_T @ self.factor.solve(self.A @ spread))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``(A^T A + diag(d))^-1 rhs``, refined ``refinements`` times.

        Parameters
        ----------
        rhs : np.ndarray
            The right-hand side, one entry per column of A.

        Returns
        -------
        np.ndarray
            The solution, one entry per column of A.
        """
        x = self._inverse_times(rhs)
        for _ in range(self.refinements):
            x = x + self._inverse_times(rhs - self.A_T @ (self.A @ x) - self.diagonal * x)
        return x


class FactoredNormalMatrix:
    """Solves ``(Q~ + diag(d)) x = rhs`` for the scaled LCP, ``Q~ = S Q S = A^T A`` with
    ``A = L S`` (``L = M^-1/2 G``: its rows of the degrees of freedom that move, S = ``root``),
    over the degrees of freedom (:class:`WoodburyFactor`, without refinement: the interior
    point's steps need no more)."""

    over = "degrees of freedom"

    def __init__(self, lcp: Lcp, root: np.ndarray, rows: sp.csr_matrix) -> None:
        """``rows``: the rows of L with an entry (:meth:`when_smaller` selects them)."""
        self.lcp, self.root = lcp, root
        self.A = sp.csr_matrix(rows @ sp.diags(root))
        self.A_T = sp.csr_matrix(self.A.T)  # formed once, for every iteration's factor
        self.pattern: PatternFactor | None = None  # made at the first factorization
        self.factor: WoodburyFactor | None = None

    @classmethod
    def when_smaller(cls, lcp: Lcp, root: np.ndarray, factor: sp.spmatrix
                     ) -> FactoredNormalMatrix | None:
        """The matrix over the degrees of freedom that move, when fewer than the contacts.

        Those are the rows of ``factor`` = L with an entry.

        Parameters
        ----------
        lcp : Lcp
            The Jacobi-scaled LCP of n contacts.
        root : np.ndarray
            Its scaling S = D^-1/2, shape (n,).
        factor : sp.spmatrix
            L = M^-1/2 G, shape (d, n).

        Returns
        -------
        FactoredNormalMatrix or None
            The matrix when fewer than n degrees of freedom move; else None.
        """
        rows = moving_rows(factor)
        return cls(lcp, root, rows) if rows.shape[0] < lcp.n else None

    def factorize(self, diagonal: np.ndarray) -> None:
        """Factors ``Q~ + diag(diagonal)`` for the next solves.

        Parameters
        ----------
        diagonal : np.ndarray
            d, shape (n,), positive.
        """
        if self.pattern is None:
            self.pattern = PatternFactor(self.A, symmetric=False)
        self.factor = WoodburyFactor(self.A, diagonal, A_T=self.A_T, pattern=self.pattern)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``(Q~ + diag(d))^-1 rhs`` with the last factor.

        Parameters
        ----------
        rhs : np.ndarray
            The right-hand side, shape (n,).

        Returns
        -------
        np.ndarray
            The solution, shape (n,).
        """
        return self.factor.solve(rhs)


def jacobi_scaled(lcp: Lcp) -> tuple[Lcp, np.ndarray]:
    """The LCP in l~ = D^1/2 l, i.e. (S Q S, S b) with S = D^-1/2, unit diagonal; and S.

    Parameters
    ----------
    lcp : Lcp
        The LCP; zero diagonal entries count as 1.

    Returns
    -------
    scaled : Lcp
        The scaled LCP, with its own residual scale, dense ``op`` when ``lcp``'s is, and no
        problem attached.
    root : np.ndarray
        S's diagonal, shape (n,).
    """
    root = 1.0 / np.sqrt(lcp.safe_diag)
    Q = sp.csr_matrix(sp.diags(root) @ lcp.Q @ sp.diags(root))
    op = lcp.op * root[:, None] * root[None, :] if lcp.dense else Q
    b = lcp.b * root
    scale = metrics.vector_scale(b)
    return Lcp(Q=Q, b=b, diag=np.ones(lcp.n), scale=scale, op=op), root


def interior_point(lcp: Lcp, scaled: Lcp, root: np.ndarray,
                   normal: NormalMatrix | FactoredNormalMatrix, tol: float, max_iters: int,
                   try_finish: Callable[[np.ndarray, np.ndarray], np.ndarray | None],
                   finish_below: float, end_on_stall: bool = False, prox: float = 0.0,
                   stall_finish: Callable[[np.ndarray, np.ndarray], np.ndarray | None]
                   | None = None
                   ) -> tuple[np.ndarray, bool, int, int]:
    """Mehrotra's predictor-corrector on the Jacobi-scaled LCP, judged on the original.

    It iterates on the Jacobi-scaled LCP ``scaled`` (``l = root * l~``, ``w = w~ / root``;
    ``normal`` factors its matrices; each step lengthened by :func:`_centrality_corrected`),
    judging by the original ``lcp``. ``try_finish(l, w)`` is
    called on an iterate whose residual is below ``finish_below`` (then below a tenth of the last
    failed try's) and returns a converged l or None. ``end_on_stall``: once five iterations in a row
    have cut by 10% neither the best residual nor, while it is above ``tol`` (scaled), the
    infeasibility ``|Q~ l~ + b~ - w~|`` (complementarity can outrun feasibility on degenerate
    piles, after which the steps shrink to nothing; while the infeasibility still falls, the
    iterates are still on their way, however the residual wavers), the best iterate is handed
    to ``try_finish`` and the interior point ends there.

    ``prox`` > 0: the iterates solve the proximal LCP ``(Q~ + prox I) l~ + b~ = w~`` around
    0 instead (Rockafellar's proximal point; the regularization of PIQP's interior point).
    Its matrix is positive definite, so it has a strictly feasible point even where the LCP
    has none (a dense pile of boxes: no velocity separates every contact), and the iterates
    converge where the plain ones stall. Its solution misses the LCP by at most
    ``prox max(l~)`` (scaled): once the LCP's residual is 100 times the proximal one's, more
    iterations cannot lower it, and with ``end_on_stall`` the iterate is handed on as on a
    stall.

    Parameters
    ----------
    lcp : Lcp
        The original LCP, whose residual (and qpbench's test) judges the iterates.
    scaled : Lcp
        ``lcp`` Jacobi-scaled (:func:`jacobi_scaled`).
    root : np.ndarray
        The scaling S = D^-1/2, shape (n,).
    normal : NormalMatrix or FactoredNormalMatrix
        Factors and solves ``Q~ + diag(d)`` of ``scaled``.
    tol : float
        qpbench's relative residual to reach.
    max_iters : int
        The most interior iterations.
    try_finish : callable
        ``try_finish(l, w)`` on the original LCP: a converged l, or None; or
        :data:`NOT_TRIED`, when it chose not to try this iterate (the next one is offered
        again, with the same ``finish_below``).
    finish_below : float
        The residual below which an iterate is first handed to ``try_finish``.
    end_on_stall : bool, optional
        End on a stall (or the proximal floor) after one last ``stall_finish``; False by
        default.
    prox : float, optional
        The proximal shift of the scaled LCP; 0 (the default) solves the LCP itself.
    stall_finish : callable or None, optional
        What finishes the best iterate on a stall (as ``try_finish``; a :data:`NOT_TRIED`
        there ends the run as a failed try would); None (the default) for ``try_finish``.

    Returns
    -------
    l : np.ndarray
        The converged answer, else the best iterate by residual, shape (n,).
    converged : bool
        Whether ``l`` passed qpbench's test (directly or through ``try_finish``).
    iterations : int
        The interior iterations done (``max_iters`` when it ran out, or when an iterate
        stopped being finite).
    finishing : int
        1 when the run ended on a ``try_finish`` call (a success, or the one after a
        stall), else 0.
    """
    n = scaled.n
    impulses = np.full(n, scaled.scale)
    slack = np.maximum(scaled.w(impulses), scaled.scale)
    floor = 1e-14
    best, best_w, best_res = impulses * root, slack / root, np.inf
    progress, least_infeasible, stalled = np.inf, np.inf, 0

    def slack_change(change: np.ndarray) -> np.ndarray:
        """The change of w along a change of l: ``(Q~ + prox I) change``."""
        return scaled.times(change) + prox * change

    for iteration in range(1, max_iters + 1):
        plain_w = scaled.times(impulses) + scaled.b
        infeasibility = plain_w + prox * impulses - slack
        mu = dot(impulses, slack) / n
        original_l, original_w = impulses * root, plain_w / root
        res = lcp.residual_of(original_l, original_w)
        if res < best_res:
            best, best_w, best_res = original_l, original_w, res
        if res <= 10.0 * tol and lcp.converged(original_l, tol):
            return original_l, True, iteration - 1, 0
        if res <= finish_below:
            finished = try_finish(original_l, original_w)
            if finished is None:
                finish_below = 0.1 * res  # try again once the residual is ten times smaller
            elif finished is not NOT_TRIED:
                return finished, True, iteration - 1, 1
        infeasible = float(np.max(np.abs(infeasibility), initial=0.0)) / scaled.scale
        if res < 0.9 * progress or tol < infeasible < 0.9 * least_infeasible:
            progress, stalled = min(res, progress), 0
            least_infeasible = min(infeasible, least_infeasible)
        else:
            stalled += 1
        at_floor = prox > 0.0 and res > 100.0 * lcp.residual_of(
            original_l, (plain_w + prox * impulses) / root)
        if end_on_stall and (stalled >= 5 or at_floor):
            finished = (stall_finish or try_finish)(best, best_w)
            if finished is not None and finished is not NOT_TRIED:
                return finished, True, iteration - 1, 1
            return best, False, iteration - 1, 1
        normal.factorize(np.maximum(slack / impulses, floor) + prox)
        # predictor (affine scaling)
        dl = normal.solve(-slack - infeasibility)
        dw = slack_change(dl) + infeasibility
        alpha = _longest_step(impulses, slack, dl, dw)
        mu_affine = dot(impulses + alpha * dl, slack + alpha * dw) / n
        sigma = (mu_affine / mu) ** 3 if mu > 0 else 0.0
        # corrector
        rhs = sigma * mu / impulses - slack - infeasibility - dl * dw / impulses
        dl = normal.solve(rhs)
        dw = slack_change(dl) + infeasibility
        dl, dw, step = _centrality_corrected(impulses, slack, dl, dw, sigma * mu, normal,
                                             slack_change)
        alpha = min(1.0, 0.99 * step)
        impulses = np.maximum(impulses + alpha * dl, 1e-300)
        slack = np.maximum(slack + alpha * dw, 1e-300)
        if not (np.all(np.isfinite(impulses)) and np.all(np.isfinite(slack))):
            break
    return best, False, max_iters, 0
