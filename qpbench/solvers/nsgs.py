"""Nonsmooth Gauss-Seidel over contacts for 2D Coulomb friction (docs/design.md section 8).

The method of So-bogus, SCISim's friction engine (Jourdan, Alart and Jean, "A Gauss-Seidel
like algorithm to solve frictional contact problems", CMAME 155, 1998; the 2D local solver
as in So-bogus' ``LocalSOCSolver`` and Siconos' ``fc2d_nsgs``): sweep over the contacts and
give each, with every other contact's impulse fixed, the exact solution of its own 2x2
problem. With ``W_kk`` the contact's 2x2 block of W and ``b_k = u_k - W_kk r_k`` its local
free velocity (the other contacts' current impulses included), the local law is tried case
by case:

1. take-off: ``b_N >= 0`` gives ``r_k = 0``;
2. stick: ``W_kk r_k = -b_k``, accepted when ``|r_T| <= mu r_N``;
3. slide with ``u_T > 0``: ``l_T = -mu l_N``, so ``r_N = -b_N / (W_NN - mu W_NT)``, accepted
   when ``r_N >= 0`` and ``u_T = (W_TN - mu W_TT) r_N + b_T >= 0``;
4. slide with ``u_T < 0``: ``l_T = +mu l_N``, ``r_N = -b_N / (W_NN + mu W_NT)``, accepted when
   ``r_N >= 0`` and ``u_T = (W_TN + mu W_TT) r_N + b_T <= 0``.

(the sign convention of the law, ``l_T = -mu l_N sign(u_T)``, the one qpbench's natural map
measures). A contact where rounding leaves no case accepted takes the candidate with the
smallest local natural-map residual. At mu = 0 case 3 or 4 always applies with ``l_T = 0``,
so the method is projected Gauss-Seidel on the normal problem.

Sweep order: contacts are coloured greedily on their interaction graph (two contacts conflict
when they share a body of finite mass) and a sweep visits the colours in order; contacts of
one colour do not interact, so one colour is solved at once in numpy, which is exactly
Gauss-Seidel in that order. Unlike So-bogus there is no skipping of contacts that moved
little, and the stopping test is qpbench's own Coulomb residual
(``friction_metrics.residual <= tol``), checked at the start, after the first sweep and then
every ``check_every`` sweeps, at most ``max_sweeps``; the best iterate checked is returned.

Pivoting finish. Point Gauss-Seidel can stall on a cluster of contacts whose W block is
singular or, for a W printed with a few digits, slightly indefinite: each local solve is exact,
yet the cluster creeps along W's near-null directions. When the best residual has not halved
over ``stall_sweeps`` sweeps, the contacts whose own natural map exceeds ``tol`` and their
neighbours (whole rings of the contact graph, as long as the block stays within
``pivot_contacts``; a whole coupled group when it fits) are solved at once, every other contact
fixed, by Lemke's method (:func:`qpbench.solvers.lemke.complementary_pivoting`) on the block's
2D law as an LCP of three unknowns per contact (:func:`block_lcp`). Its answer is kept only
when qpbench's residual of the whole problem improves; the sweeps then go on from the better
iterate, and the finish runs again at the next stall (at most once per ``stall_sweeps``
sweeps), until one fails to improve.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from qpbench import __version__
from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import accuracy, colouring, fixed_order_dense
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.lemke import complementary_pivoting
from qpbench.solvers.registry import register

NAME = "nsgs"
FORMULATION = "nsgs"
BACKEND = "qpbench"
VERSION = __version__


def contact_graph(problem: FrictionalProblem) -> sp.csr_matrix:
    """The contact graph: k, j adjacent when W's 2x2 block (k, j) may be nonzero.

    It is :meth:`FrictionalProblem.contact_graph`.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.

    Returns
    -------
    sp.csr_matrix
        The graph's symmetric n x n pattern.
    """
    return problem.contact_graph()


def start_in_cone(problem: FrictionalProblem, warm_start: np.ndarray | None) -> np.ndarray:
    """The warm start clipped into the cone (l_N >= 0, |l_T| <= mu l_N), else 0.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    warm_start : np.ndarray or None
        r = (l_N, l_T), flattened; used when it has 2n finite entries.

    Returns
    -------
    np.ndarray
        The start r, shape (2n,), inside the cone; zeros for no usable warm start.
    """
    n = problem.n_contacts
    if warm_start is not None:
        warm = np.asarray(warm_start, dtype=float).ravel()
        if warm.shape == (2 * n,) and np.all(np.isfinite(warm)):
            normal = np.maximum(warm[:n], 0.0)
            bound = problem.mu * normal
            return np.concatenate([normal, np.clip(warm[n:], -bound, bound)])
    return np.zeros(2 * n)


def local_solve(block: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                b_normal: np.ndarray, b_tangential: np.ndarray, mu: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """The exact solution (r_N, r_T) of each contact's 2x2 Coulomb problem ``u = W_kk r + b``.

    The cases of the module docstring, vectorized over contacts.

    Parameters
    ----------
    block : tuple of np.ndarray
        (W_NN, W_NT, W_TN, W_TT) of each contact's W_kk, each of shape (k,).
    b_normal, b_tangential : np.ndarray
        Each contact's local free velocity b = (b_N, b_T), shape (k,).
    mu : np.ndarray
        Each contact's friction coefficient, shape (k,).

    Returns
    -------
    normal, tangential : np.ndarray
        r_N and r_T of each contact, shape (k,).
    """
    a, c_nt, c_tn, d = block
    with np.errstate(divide="ignore", invalid="ignore"):
        # stick: W_kk r = -b by Cramer's rule
        det = a * d - c_nt * c_tn
        stick_n = (-b_normal * d + c_nt * b_tangential) / det
        stick_t = (-a * b_tangential + c_tn * b_normal) / det
        # slide with u_T > 0 (l_T = -mu l_N) and with u_T < 0 (l_T = +mu l_N)
        plus_n = -b_normal / (a - mu * c_nt)
        plus_u = (c_tn - mu * d) * plus_n + b_tangential
        minus_n = -b_normal / (a + mu * c_nt)
        minus_u = (c_tn + mu * d) * minus_n + b_tangential
    take_off = b_normal >= 0.0
    sticks = (det > 0.0) & (stick_n >= 0.0) & (np.abs(stick_t) <= mu * stick_n)
    plus = (plus_n >= 0.0) & (plus_u >= 0.0)
    minus = (minus_n >= 0.0) & (minus_u <= 0.0)
    normal = np.where(take_off, 0.0, np.where(sticks, stick_n, np.where(plus, plus_n, minus_n)))
    tangential = np.where(take_off, 0.0, np.where(sticks, stick_t,
                                                  np.where(plus, -mu * plus_n, mu * minus_n)))
    lost = ~(take_off | sticks | plus | minus)
    if np.any(lost):
        normal, tangential = _least_residual(block, b_normal, b_tangential, mu, lost,
                                             normal, tangential,
                                             [(stick_n, stick_t), (plus_n, -mu * plus_n),
                                              (minus_n, mu * minus_n)])
    return normal, tangential


def _least_residual(block, b_normal, b_tangential, mu, lost, normal, tangential, candidates):
    """Where no case was accepted (rounding at a case boundary, or a singular W_kk): the
    candidate (0 included) with the smallest local natural-map residual."""
    a, c_nt, c_tn, d = (part[lost] for part in block)
    bn, bt, m = b_normal[lost], b_tangential[lost], mu[lost]
    options = [(np.zeros_like(bn), np.zeros_like(bn))] + [
        (np.nan_to_num(cn[lost], nan=0.0, posinf=0.0, neginf=0.0),
         np.nan_to_num(ct[lost], nan=0.0, posinf=0.0, neginf=0.0)) for cn, ct in candidates]
    best = np.full(bn.shape, np.inf)
    best_n, best_t = np.zeros_like(bn), np.zeros_like(bn)
    for rn, rt in options:
        rn = np.maximum(rn, 0.0)
        rt = np.clip(rt, -m * rn, m * rn)
        un = a * rn + c_nt * rt + bn
        ut = c_tn * rn + d * rt + bt
        pn, pt = friction_metrics.project_on_cone(a * rn - (un + m * np.abs(ut)), a * rt - ut, m)
        error = np.maximum(np.abs(a * rn - pn), np.abs(a * rt - pt))
        better = error < best
        best = np.where(better, error, best)
        best_n = np.where(better, rn, best_n)
        best_t = np.where(better, rt, best_t)
    normal, tangential = normal.copy(), tangential.copy()
    normal[lost], tangential[lost] = best_n, best_t
    return normal, tangential


class ContactSweep:
    """The colour classes of a problem, each with its rows of W (normal and tangential), q
    and 2x2 blocks, ready for sweeping."""

    def __init__(self, problem: FrictionalProblem) -> None:
        n = problem.n_contacts
        W = sp.csr_matrix(problem.W)
        q = problem.q
        diagonal = W.diagonal()
        normal_tangent = np.asarray(W[np.arange(n), np.arange(n) + n]).ravel() if n else \
            np.zeros(0)
        movable = problem.diag_N > 0.0  # a contact that moves nothing keeps r = 0
        self.colour = colouring.colours_of(contact_graph(problem))
        self.classes = []
        for c in range(int(self.colour.max(initial=-1)) + 1):
            index = np.flatnonzero((self.colour == c) & movable)
            if index.size == 0:
                continue
            rows = np.concatenate([index, index + n])
            coupling = normal_tangent[index]
            block = (diagonal[index], coupling, coupling, diagonal[index + n])
            self.classes.append((index, index + n, W[rows], q[rows], block,
                                 problem.mu[index]))

    def __call__(self, impulses: np.ndarray) -> None:
        """One sweep in place."""
        for normal_index, tangent_index, rows, q, block, mu in self.classes:
            k = normal_index.size
            u = rows @ impulses + q
            r_n, r_t = impulses[normal_index], impulses[tangent_index]
            a, c_nt, c_tn, d = block
            b_normal = u[:k] - a * r_n - c_nt * r_t
            b_tangential = u[k:] - c_tn * r_n - d * r_t
            normal, tangential = local_solve(block, b_normal, b_tangential, mu)
            impulses[normal_index] = normal
            impulses[tangent_index] = tangential


def contact_errors(problem: FrictionalProblem, impulses: np.ndarray) -> np.ndarray:
    """Each contact's own natural-map error ``max(|F_N|, |F_T|) / scale``.

    F is ``friction_metrics.natural_map``.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).

    Returns
    -------
    np.ndarray
        The errors, shape (n,), relative to the problem's scale.
    """
    F_normal, F_tangential = friction_metrics.natural_map(problem, impulses)
    return np.maximum(np.abs(F_normal), np.abs(F_tangential)) / problem.scale


def finish_block(problem: FrictionalProblem, errors: np.ndarray, tol: float, limit: int
                 ) -> np.ndarray:
    """The contacts of the pivoting finish.

    Those whose ``errors`` exceed ``tol`` (the ``limit`` largest when there are more) grown
    by whole rings of neighbours in the contact graph while the block stays within ``limit``
    contacts (it stops growing at the edge of its coupled groups).

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    errors : np.ndarray
        Each contact's error (:func:`contact_errors`), shape (n,).
    tol : float
        The error above which a contact is unsolved.
    limit : int
        The most contacts in the block.

    Returns
    -------
    np.ndarray
        The block's contact indices, ascending; empty when no contact is unsolved.
    """
    unsolved = np.flatnonzero(errors > tol)
    if unsolved.size > limit:
        unsolved = unsolved[np.argsort(-errors[unsolved], kind="stable")[:limit]]
    graph = sp.csr_matrix(problem.contact_graph())
    inside = np.zeros(problem.n_contacts, dtype=bool)
    inside[unsolved] = True
    while True:
        ring = (graph @ inside.astype(float) > 0.0) & ~inside
        if not ring.any() or inside.sum() + ring.sum() > limit:
            return np.flatnonzero(inside)
        inside |= ring


def block_lcp(W_block: np.ndarray, q_block: np.ndarray, mu: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """The 2D law of k contacts (``u = W_block r + q_block``, order ``(l_N, l_T)``) as one LCP
    ``w = A z + c``: ``z = (l_N, t, s)`` with ``t = l_T + mu l_N`` and the slack s, rows
    ``(u_N, u_T + s, 2 mu l_N - t)``. ``t`` complementary to ``u_T + s`` and ``s`` to
    ``mu l_N - l_T`` give stick (``u_T = 0``), slide with ``u_T > 0`` (``t = 0``) and slide
    with ``u_T < 0`` (``s = -u_T``, ``l_T = mu l_N``).

    Parameters
    ----------
    W_block : np.ndarray
        W on the k contacts' rows and columns, order ``(l_N, l_T)``, shape (2k, 2k).
    q_block : np.ndarray
        Their free velocity (the other contacts' impulses included), shape (2k,).
    mu : np.ndarray
        Their friction coefficients, shape (k,).

    Returns
    -------
    A : np.ndarray
        The LCP's matrix, shape (3k, 3k), not symmetric.
    c : np.ndarray
        Its constant term, shape (3k,).
    """
    k = mu.shape[0]
    NN, NT = W_block[:k, :k], W_block[:k, k:]
    TN, TT = W_block[k:, :k], W_block[k:, k:]
    identity, zero, friction = np.eye(k), np.zeros((k, k)), np.diag(mu)
    A = np.block([[NN - NT * mu[None, :], NT, zero],
                  [TN - TT * mu[None, :], TT, identity],
                  [2.0 * friction, -identity, zero]])
    return A, np.concatenate([q_block, np.zeros(k)])


def pivoting_finish(problem: FrictionalProblem, impulses: np.ndarray, tol: float,
                    limit: int, pivots_per_contact: int) -> np.ndarray | None:
    """The iterate with the finish's block replaced by Lemke's answer on its LCP.

    The block is :func:`finish_block`'s, its LCP :func:`block_lcp`'s (Jacobi-scaled, other
    contacts fixed).

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    impulses : np.ndarray
        The iterate r, shape (2n,); not changed.
    tol : float
        The contact error above which a contact joins the block.
    limit : int
        The most contacts in the block.
    pivots_per_contact : int
        Lemke's most pivots per unknown of the block's LCP (3 unknowns per contact).

    Returns
    -------
    np.ndarray or None
        The new iterate, shape (2n,); None when there is no block or the answer is not
        finite.
    """
    n = problem.n_contacts
    block = finish_block(problem, contact_errors(problem, impulses), tol, limit)
    if block.size == 0:
        return None
    rows = np.concatenate([block, block + n])
    W_rows = sp.csr_matrix(problem.W)[rows]
    W_block = W_rows[:, rows].toarray()
    q_block = (W_rows @ impulses + problem.q[rows]
               - fixed_order_dense.symmetric_product(W_block, impulses[rows]))
    A, c = block_lcp(W_block, q_block, problem.mu[block])
    diagonal = np.concatenate([np.diag(W_block), np.diag(W_block)[:block.size]])
    root = np.sqrt(np.where(diagonal > 0.0, diagonal, 1.0))
    z, _, _, _, _ = complementary_pivoting(A / root[:, None] / root[None, :], c / root,
                                           pivots_per_contact * 3 * block.size)
    z = z / root
    k = block.size
    finished = impulses.copy()
    finished[block] = z[:k]
    finished[block + n] = z[k:2 * k] - problem.mu[block] * z[:k]
    return finished if np.all(np.isfinite(finished)) else None


def nsgs(problem: FrictionalProblem, sweep: ContactSweep, start: np.ndarray, tol: float,
         max_sweeps: int, check_every: int, stall_sweeps: int = 0, pivot_contacts: int = 0,
         pivots_per_contact: int = 0) -> tuple[np.ndarray, bool, str, int, float]:
    """Sweep from ``start`` until qpbench's Coulomb residual reaches ``tol``.

    With the pivoting finish (module docstring) whenever the best residual has not halved
    over the last ``stall_sweeps`` sweeps, none of them before the previous finish (never
    when ``pivot_contacts`` is 0), until a finish fails to improve it.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    sweep : ContactSweep
        Its colour-ordered sweep, which updates r in place.
    start : np.ndarray
        The first iterate r, shape (2n,); copied, not changed.
    tol : float
        qpbench's relative Coulomb residual to reach.
    max_sweeps : int
        The most sweeps.
    check_every : int
        Sweeps between residual checks (the first check comes after one sweep).
    stall_sweeps : int, optional
        The sweeps over which the best residual must halve before a finish.
    pivot_contacts : int, optional
        The most contacts of a finish's block; 0 (the default) turns the finish off.
    pivots_per_contact : int, optional
        Lemke's most pivots per unknown of a finish's LCP.

    Returns
    -------
    r : np.ndarray
        The converged iterate, else the best checked one, shape (2n,).
    converged : bool
        Whether its residual is at most ``tol``.
    status : str
        ``converged`` (after a pivoting finish or not), a divergence or the sweep limit.
    sweeps : int
        The sweeps done.
    residual : float
        r's Coulomb residual.
    """
    impulses = start.copy()
    residual = friction_metrics.residual(problem, impulses)
    best, best_residual = impulses.copy(), residual
    if residual <= tol:
        return impulses, True, "converged", 0, residual
    history = [(0, residual)]  # (sweeps, best residual) at each check
    finishing = pivot_contacts > 0
    last_finish = 0
    sweeps = 0
    while sweeps < max_sweeps:
        # the first check comes after one sweep: all-stick and all-separating events end there
        for _ in range(min(1 if sweeps == 0 else check_every, max_sweeps - sweeps)):
            sweep(impulses)
            sweeps += 1
        if not np.all(np.isfinite(impulses)):
            return best, False, "diverged: non-finite impulses", sweeps, best_residual
        residual = friction_metrics.residual(problem, impulses)
        if residual < best_residual:
            best, best_residual = impulses.copy(), residual
        if residual <= tol:
            return impulses, True, "converged", sweeps, residual
        history.append((sweeps, best_residual))
        earlier = [value for count, value in history
                   if last_finish <= count <= sweeps - stall_sweeps]
        if finishing and earlier and best_residual > 0.5 * earlier[-1]:
            last_finish = sweeps
            candidate = pivoting_finish(problem, best, tol, pivot_contacts,
                                        pivots_per_contact)
            candidate_residual = np.inf if candidate is None else \
                friction_metrics.residual(problem, candidate)
            finishing = candidate_residual < best_residual
            if finishing:
                best, best_residual = candidate, candidate_residual
                impulses = candidate.copy()
                history.append((sweeps, best_residual))
                if candidate_residual <= tol:
                    return impulses, True, "converged after a pivoting finish", sweeps, \
                        candidate_residual
    return best, False, f"max_sweeps ({max_sweeps}) reached", sweeps, best_residual


def solve(problem: FrictionalProblem, eps: float, warm_start: np.ndarray | None = None
          ) -> SolverOutput:
    """Solve a frictional problem by nonsmooth Gauss-Seidel at accuracy level ``eps``.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem to solve.
    eps : float
        qpbench's accuracy level, the Coulomb residual to reach; the ``nsgs`` row of the
        accuracy table follows from it.
    warm_start : np.ndarray or None, optional
        A guess of r = (l_N, l_T), clipped into the cone when it has 2n finite entries;
        otherwise the start is 0.

    Returns
    -------
    SolverOutput
        r, status, the Coulomb residual's test as claim and the sweeps done; ``info``
        holds the sweeps, colours, residual and sweep order.
    """
    options = accuracy.options_for(NAME, eps, problem.scale)
    sweep = ContactSweep(problem)
    start = start_in_cone(problem, warm_start)
    impulses, converged, status, sweeps, residual = nsgs(
        problem, sweep, start, options["tol"], options["max_sweeps"], options["check_every"],
        options["stall_sweeps"], options["pivot_contacts"], options["pivots_per_contact"])
    return SolverOutput(impulses=impulses, status=status, claimed_success=bool(converged),
                        iterations=sweeps,
                        info={"outer_iterations": sweeps, "colours": len(sweep.classes),
                              "residual": residual,
                              "order": "greedy colouring of the contact graph, colours in "
                                       "increasing order"})


def prepare() -> None:
    """Compiles the colouring and the pivoting finish's fixed-order products, or loads them
    from numba's cache, outside any clock."""
    colouring.warm_up()
    fixed_order_dense.warm_up()


register(SolverSpec(name=NAME, formulation=FORMULATION, backend=BACKEND, solve=solve,
                    version=VERSION, warm_start=True, own_stopping_rule=True,
                    prepare=prepare, kinds=("frictional",),
                    description="nonsmooth Gauss-Seidel over contacts, exact 2x2 local solves "
                                "(take-off, stick, slide), colour-ordered sweeps"))
