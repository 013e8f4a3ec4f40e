"""References verified in exact rational arithmetic, and the residual floor of double precision.

Where the double-precision reference methods disagree (or none reaches the finest accuracy
level), the LCP ``l >= 0, w = Q l + b >= 0, l^T w = 0`` is solved again from the problem's
primary data, G, M^-1, v-, c and nrel. Every double is an exact rational, so

    Q = G^T M^-1 G,   b = (1 + c) (G^T v- + nrel)

are formed exactly (``fractions.Fraction``) and every residual below is exact:

1. The active set A = {D l > w} of the best double answer (D = diag Q) is taken.
2. The block ``Q_AA l_A = -b_A`` is solved by mixed-precision iterative refinement (Higham,
   "Accuracy and Stability of Numerical Algorithms", 2nd ed., SIAM 2002, ch. 12): the
   residual in exact arithmetic, each correction by a truncated SVD of the Jacobi-scaled block
   in double precision, so that directions Q does not see (its null space: l need not be
   unique, v+ = v- + M^-1 G l is) are left alone and l_A moves by the least correction.
   When refinement stalls (a nearly singular block), the block is solved by exact Gaussian
   elimination in reverse Cuthill-McKee order; a zero pivot of the positive semi-definite
   block marks a free direction, set to zero. Its rationals grow with the pivots taken (to
   tens of thousands of bits on a grid's block of a few hundred contacts), so the eliminations
   of one problem may form entries of at most :data:`ELIMINATION_WORK` squared bits in all
   (the cost of an operation on rationals grows about as the square of their length); past
   that the problem is left uncertified, its time bounded by the same count on every
   machine.
3. Policy iteration in exact arithmetic: when an l_i of A is negative, the contact that
   reaches zero first on the segment from the last non-negative point to the new one leaves
   A (a ratio test, as in active-set methods); else every contact with w_i < 0 joins A.
4. The answer is certified when the exact natural residual
   ``||min(D l, w)||_inf / ||b||_inf`` is at most :data:`CERTIFIED_BELOW`.

Rounded to double, the certified l gives a double vector whose qpbench residual (evaluated
in double, as ``metrics.residual``) is the problem's *floor*: on problems with masses over
many decades the terms of ``Q l`` exceed ``||b||`` by many orders of magnitude, so rounding l
and summing those terms in double leaves a residual of about ``2^-53 max_i (|Q| |l|)_i /
||b||`` that no answer in double precision is known to beat. A level below the floor cannot
be decided in double precision.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from qpbench.problem import metrics
from qpbench.problem.impact import ImpactProblem, Reference

# the metadata key under which a problem keeps its floor (qpbench.problem.reference writes it,
# qpbench.solvers.run reads it)
FLOOR_KEY = "reference_residual_floor"

# the most contacts on which the exact solve runs (its elimination fallback grows fast)
EXTENDED_LIMIT = 600
# the exact natural residual (relative to ||b||_inf) that certifies an LCP solution
CERTIFIED_BELOW = Fraction(1, 10**30)
# refinement steps of one block at most, and the residual ratio below which a step counts
REFINEMENTS = 10
REFINEMENT_RATIO = 1e-3
# singular values of the Jacobi-scaled block below this fraction of the largest are dropped
SINGULAR_CUTOFF = 1e-14
# active-set changes at most
POLICY_CHANGES = 30
# the squared bit lengths, summed over the entries they form, of one problem's exact
# eliminations at most (a nearly singular block of a few hundred contacts needs more than this
# for one elimination, and a new one after each change of its active set)
ELIMINATION_WORK = 4e12
METHOD = "extended-precision(exact rational)"

Rows = list[dict[int, Fraction]]


@dataclass
class ExtendedReference(Reference):
    """A :class:`Reference` whose ``v_plus`` comes from an LCP solution certified exactly.

    ``floor`` is the least qpbench residual (double arithmetic) among the double vectors
    known for the problem: the certified solution rounded to double and the double answers it
    was started from. ``exact_residual`` is the certified solution's natural residual in
    exact arithmetic.
    """

    floor: float = 0.0
    exact_residual: float = 0.0


@dataclass
class ExactLcp:
    """Q (sparse rows), b and D = diag Q of a problem as exact rationals, and ||b||_inf."""

    rows: Rows
    b: list[Fraction]
    diag: list[Fraction]
    scale: Fraction

    @property
    def n(self) -> int:
        return len(self.b)


def exact_lcp(problem: ImpactProblem) -> ExactLcp:
    """Q = G^T M^-1 G and b = (1 + c) (G^T v- + nrel) of ``problem``, exactly.

    Parameters
    ----------
    problem : ImpactProblem
        The problem; its doubles are read as the rationals they are.

    Returns
    -------
    ExactLcp
        The exact Q (one dict per row), b, D and ``max(||b||_inf, TINY)``.
    """
    n = problem.n_contacts
    G_rows = sp.csr_matrix(problem.G)
    rows: Rows = [{} for _ in range(n)]
    for k in range(G_rows.shape[0]):
        start, end = G_rows.indptr[k], G_rows.indptr[k + 1]
        contacts = [int(j) for j in G_rows.indices[start:end]]
        entries = [Fraction(float(value)) for value in G_rows.data[start:end]]
        weight = Fraction(float(problem.m_inv[k]))
        if weight == 0:
            continue
        for i, g_i in zip(contacts, entries, strict=True):
            row = rows[i]
            for j, g_j in zip(contacts, entries, strict=True):
                row[j] = row.get(j, Fraction(0)) + g_i * weight * g_j
    G_columns = sp.csc_matrix(problem.G)
    b = []
    for i in range(n):
        start, end = G_columns.indptr[i], G_columns.indptr[i + 1]
        pairs = zip(G_columns.indices[start:end], G_columns.data[start:end], strict=True)
        normal_velocity = sum((Fraction(float(g)) * Fraction(float(problem.v_minus[k]))
                               for k, g in pairs), Fraction(0))
        b.append((1 + Fraction(float(problem.restitution[i])))
                 * (normal_velocity + Fraction(float(problem.n_rel[i]))))
    diag = [row.get(i, Fraction(0)) for i, row in enumerate(rows)]
    scale = max(max((abs(value) for value in b), default=Fraction(0)), Fraction(metrics.TINY))
    return ExactLcp(rows, b, diag, scale)


def slack(lcp: ExactLcp, impulses: list[Fraction]) -> list[Fraction]:
    """w = Q l + b, exactly.

    Parameters
    ----------
    lcp : ExactLcp
        The exact LCP.
    impulses : list of Fraction
        l, n entries.

    Returns
    -------
    list of Fraction
        w, n entries.
    """
    return [b_i + sum((q * impulses[j] for j, q in row.items() if impulses[j]), Fraction(0))
            for row, b_i in zip(lcp.rows, lcp.b, strict=True)]


def natural_residual(lcp: ExactLcp, impulses: list[Fraction]) -> Fraction:
    """``||min(D l, Q l + b)||_inf / max(||b||_inf, TINY)``, exactly.

    Parameters
    ----------
    lcp : ExactLcp
        The exact LCP.
    impulses : list of Fraction
        l, n entries.

    Returns
    -------
    Fraction
        qpbench's residual of l in exact arithmetic.
    """
    w = slack(lcp, impulses)
    worst = max((abs(min(d * l_i, w_i)) for d, l_i, w_i in zip(lcp.diag, impulses, w, strict=True)),
                default=Fraction(0))
    return worst / lcp.scale


def _refined_block(lcp: ExactLcp, Q: np.ndarray, active: np.ndarray,
                   impulses: list[Fraction]) -> tuple[list[Fraction], Fraction]:
    """l with ``Q_AA l_A = -b_A`` refined from ``impulses`` (zero off A), and the exact
    block residual ``||Q_AA l_A + b_A||_inf / scale`` it reached (module docstring, step 2)."""
    x = [value if active[i] else Fraction(0) for i, value in enumerate(impulses)]
    index = np.flatnonzero(active)
    if index.size == 0:
        return x, Fraction(0)
    root = 1.0 / np.sqrt(np.maximum(np.diag(Q)[index], metrics.TINY))
    U, singular, Vt = np.linalg.svd(root[:, None] * Q[np.ix_(index, index)] * root[None, :])
    keep = singular > SINGULAR_CUTOFF * singular[0]
    U, singular, Vt = U[:, keep], singular[keep], Vt[keep]
    residual = _block_residual(lcp, index, x)
    for _ in range(REFINEMENTS):
        if residual <= CERTIFIED_BELOW:
            break
        w = slack(lcp, x)
        scaled = np.array([-float(w[i]) for i in index]) * root
        correction = root * (Vt.T @ ((U.T @ scaled) / singular))
        for i, delta in zip(index, correction, strict=True):
            x[i] += Fraction(float(delta))
        previous, residual = residual, _block_residual(lcp, index, x)
        if residual > REFINEMENT_RATIO * previous:
            break  # stalled: a direction the truncated SVD does not resolve
    return x, residual


def _block_residual(lcp: ExactLcp, index: np.ndarray, impulses: list[Fraction]) -> Fraction:
    """``||Q_AA l_A + b_A||_inf / scale`` on the contacts ``index`` (A), exactly."""
    w = slack(lcp, impulses)
    return max(abs(w[i]) for i in index) / lcp.scale


class _WorkSpent(Exception):
    """The exact eliminations of one problem formed ELIMINATION_WORK squared bits."""


def _eliminated_block(lcp: ExactLcp, active: np.ndarray, spent: list[float]
                      ) -> list[Fraction] | None:
    """l with ``Q_AA l_A = -b_A`` exactly by sparse Gaussian elimination (reverse
    Cuthill-McKee order, diagonal pivots), zero off A; a zero pivot's variable is set to 0.
    None when the block system has no solution (a zero pivot whose right side is not 0).
    ``spent[0]`` counts the squared bit lengths of the entries formed; :class:`_WorkSpent`
    is raised once it passes ELIMINATION_WORK."""
    index = [int(i) for i in np.flatnonzero(active)]
    position = {i: k for k, i in enumerate(index)}
    size = len(index)
    pattern = sp.lil_matrix((size, size))
    for k, i in enumerate(index):
        for j in lcp.rows[i]:
            if j in position:
                pattern[k, position[j]] = 1.0
    order = [index[k] for k in reverse_cuthill_mckee(sp.csr_matrix(pattern),
                                                     symmetric_mode=True)]
    place = {i: k for k, i in enumerate(order)}
    block = [{place[j]: q for j, q in lcp.rows[i].items() if j in place} for i in order]
    rhs = [-lcp.b[i] for i in order]
    for k in range(size):
        pivot = block[k].get(k, Fraction(0))
        if pivot == 0:  # positive semi-definite: row and column k of the rest are zero too
            continue
        for i in [i for i in block[k] if i > k]:
            factor = block[i].pop(k) / pivot
            for j, q in block[k].items():
                if j > k:
                    entry = block[i].get(j, Fraction(0)) - factor * q
                    block[i][j] = entry
                    spent[0] += (entry.numerator.bit_length()
                                 + entry.denominator.bit_length()) ** 2
            rhs[i] -= factor * rhs[k]
            if spent[0] > ELIMINATION_WORK:
                raise _WorkSpent
    x = [Fraction(0)] * size
    for k in range(size - 1, -1, -1):
        rest = rhs[k] - sum((q * x[j] for j, q in block[k].items() if j > k), Fraction(0))
        pivot = block[k].get(k, Fraction(0))
        if pivot == 0:
            if rest != 0:
                return None
            continue
        x[k] = rest / pivot
    impulses = [Fraction(0)] * lcp.n
    for i, value in zip(order, x, strict=True):
        impulses[i] = value
    return impulses


def solve_exactly(problem: ImpactProblem, start: np.ndarray, lcp: ExactLcp | None = None
                  ) -> tuple[list[Fraction], Fraction] | None:
    """The LCP solution of ``problem`` certified in exact arithmetic, from a double answer.

    The algorithm is the module docstring's: the active set of ``start``, each block by
    exact-residual iterative refinement (exact elimination when it stalls), exact policy
    changes by a ratio test, until the exact natural residual is at most
    :data:`CERTIFIED_BELOW`.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    start : np.ndarray
        A double answer l, shape (n,), close to a solution (its active set is the first tried).
    lcp : ExactLcp or None, optional
        The problem's exact LCP when already formed; None (the default) forms it.

    Returns
    -------
    tuple of (list of Fraction, Fraction) or None
        The certified l and its exact natural residual; None when :data:`POLICY_CHANGES`
        active sets did not give one, a block had no solution, or the eliminations spent
        :data:`ELIMINATION_WORK`.
    """
    lcp = lcp or exact_lcp(problem)
    Q = problem.Q.toarray()
    start = np.maximum(np.asarray(start, dtype=float), 0.0)
    active = problem.diag_Q * start > problem.w(start)
    feasible = [Fraction(float(value)) for value in start]
    tolerance = CERTIFIED_BELOW * lcp.scale
    spent = [0.0]
    for _ in range(POLICY_CHANGES):
        impulses, block_residual = _refined_block(lcp, Q, active, feasible)
        if block_residual > CERTIFIED_BELOW:
            try:
                impulses = _eliminated_block(lcp, active, spent)
            except _WorkSpent:
                return None
            if impulses is None:
                return None
        w = slack(lcp, impulses)
        negative = [i for i in np.flatnonzero(active) if lcp.diag[i] * impulses[i] < -tolerance]
        violated = [i for i in np.flatnonzero(~active) if w[i] < -tolerance]
        if not negative and not violated:
            residual = natural_residual(lcp, impulses)
            return (impulses, residual) if residual <= CERTIFIED_BELOW else None
        active = active.copy()
        if negative:
            # the segment from the last non-negative point: the first to reach zero leaves A
            reach, leaving = min((feasible[i] / (feasible[i] - impulses[i]), i)
                                 for i in negative)
            feasible = [f + reach * (x - f) for f, x in zip(feasible, impulses, strict=True)]
            feasible[leaving] = Fraction(0)
            active[leaving] = False
        else:
            feasible = impulses
            active[violated] = True
        # the next start rounded to double (still >= 0): an exact elimination's rationals are
        # long, and refinement needs only a close start
        feasible = [Fraction(float(value)) for value in feasible]
    return None


def exact_velocity(problem: ImpactProblem, impulses: list[Fraction]) -> np.ndarray:
    """v+ = v- + M^-1 G l evaluated exactly, then rounded to double.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : list of Fraction
        l, n entries.

    Returns
    -------
    np.ndarray
        v+, shape (d,), each entry the double nearest to its exact value.
    """
    G_rows = sp.csr_matrix(problem.G)
    velocity = np.empty(problem.n_dofs)
    for k in range(problem.n_dofs):
        start, end = G_rows.indptr[k], G_rows.indptr[k + 1]
        pairs = zip(G_rows.indices[start:end], G_rows.data[start:end], strict=True)
        push = sum((Fraction(float(g)) * impulses[j] for j, g in pairs), Fraction(0))
        velocity[k] = float(Fraction(float(problem.v_minus[k]))
                            + Fraction(float(problem.m_inv[k])) * push)
    return velocity


def extended_reference(problem: ImpactProblem,
                       candidates: list[tuple[np.ndarray, np.ndarray, str]],
                       tolerance: float) -> ExtendedReference | None:
    """The reference of ``problem`` from its LCP solution certified in exact arithmetic.

    :func:`solve_exactly` starts from the candidate of least residual. The reference's v+ and
    l are the certified solution's, rounded to double; its check is the candidate whose v+ is
    closest to that v+ (``agreement`` as in ``qpbench.problem.reference``); its ``floor`` the
    least qpbench residual among the rounded solution and the candidates.

    Parameters
    ----------
    problem : ImpactProblem
        The problem, at most :data:`EXTENDED_LIMIT` contacts.
    candidates : list of (np.ndarray, np.ndarray, str)
        The double-precision methods' (v+, l, method name); at least one.
    tolerance : float
        The agreement within which the reference counts as verified.

    Returns
    -------
    ExtendedReference or None
        The reference; None above :data:`EXTENDED_LIMIT` contacts or when no solution was
        certified.
    """
    if not candidates or problem.n_contacts > EXTENDED_LIMIT:
        return None
    start = min(candidates, key=lambda candidate: metrics.residual(problem, candidate[1]))
    certified = solve_exactly(problem, start[1])
    if certified is None:
        return None
    impulses, exact_residual = certified
    v_plus = exact_velocity(problem, impulses)
    rounded = np.array([float(value) for value in impulses])
    unit = max(problem.m_norm(problem.v_minus), metrics.TINY)
    agreements = [problem.m_norm(candidate[0] - v_plus) / unit for candidate in candidates]
    closest = int(np.argmin(agreements))
    floor = min([metrics.residual(problem, rounded)]
                + [metrics.residual(problem, candidate[1]) for candidate in candidates])
    return ExtendedReference(v_plus, rounded, f"{METHOD} from {start[2]}",
                             candidates[closest][0], candidates[closest][2],
                             agreements[closest], tolerance, floor=floor,
                             exact_residual=float(exact_residual))
