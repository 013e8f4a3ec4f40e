"""Reference solutions of frictional problems (docs/design.md section 8).

Three methods, all on the Jacobi-scaled problem (``r = s r~``, ``s_k = 1 / sqrt(W_NN,kk)``
for both the normal and the tangential impulse of contact k, so every contact's cone is kept
and ``W~_NN`` has a unit diagonal), every answer polished and then judged on the original
problem by :func:`qpbench.problem.friction_metrics.residual`:

* ``enumeration`` (n <= ENUMERATION_LIMIT): every pattern of contact states, 4^n of them.
  Contact k is *separate* (``r_k = 0``), *stick* (``u_k = 0``), *slide+* (``u_N = 0``,
  ``l_T = -mu l_N``, ``u_T >= 0``) or *slide-* (``l_T = +mu l_N``, ``u_T <= 0``). Each
  pattern is one square linear system of 2n rows (the equalities of every contact's state),
  solved for all patterns at once with numpy; the inequalities of the states then decide
  which solutions are solutions of the law. A pattern whose system is singular but
  consistent is an affine set of candidates rather than one point; when its minimum-norm
  point fails the inequalities, a small LP (:func:`_pattern_lp`) decides whether another
  point of the set satisfies them. So every pattern is decided, and the list of solutions is
  complete up to the tolerances. ``unique`` is True when all solutions share one v+
  (M-norm, relative 1e-9); it is None where v+ could vary inside a singular pattern.
* ``lemke``: a dense Lemke method with lexicographic degeneracy resolution
  (:func:`~qpbench.problem.lexicographic_lemke.lemke`, qpbench's own, so that the reference
  does not depend on the solvers under test) on the Stewart-Trinkle LCP of
  :meth:`FrictionalProblem.stewart_trinkle`. It is the method for n > ENUMERATION_LIMIT
  (``unique`` None: nothing proves uniqueness there) and a cross-check of the enumeration
  below it: a Lemke solution that the enumeration did not list makes ``unique`` None.
* ``ccp_certificate``: the LP ``min q^T d`` over ``d in K_mu`` (``|d_T| <= mu d_N``),
  ``H d = 0`` (equivalently ``W d = 0``), ``0 <= d_N <= 1``. A negative optimum proves that
  Anitescu's relaxation has no solution (its QP is unbounded below: at a solution
  ``u in K*`` and ``d in K`` give ``d^T u >= 0``, yet ``d^T u = d^T W r + q^T d = q^T d``).
  For the exact law it proves less: a Coulomb solution would need
  ``sum_k mu_k d_N,k |u_T,k| >= -q^T d > 0``, so none exists in which the contacts of d all
  stick.

``solvable`` is False only when no method found a solution *and* the certificate holds.
Where n <= ENUMERATION_LIMIT the exhaustive enumeration is itself the proof that no
solution exists (to its tolerances); above it, Lemke's failure together with the
certificate is strong evidence, not proof. ``metadata["reference_no_solution_proven"]``
says which.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.sparse as sp

from qpbench.problem import friction_metrics as fm
from qpbench.problem.friction import REFERENCE_RESIDUAL, FrictionalProblem, FrictionalReference
from qpbench.problem.lexicographic_lemke import lemke
from qpbench.problem.metrics import TINY

ENUMERATION_LIMIT = 8
SAME_VELOCITY = 1e-9  # distinct solutions: ||v_a - v_b||_M / ||v||_M above this
SEPARATE, STICK, SLIDE_PLUS, SLIDE_MINUS = 0, 1, 2, 3
STATE_NAMES = ("separate", "stick", "slide+", "slide-")

_CHUNK = 4096  # patterns per batch of linear solves
_CANDIDATE = 1e-7  # scaled natural map below which a pattern's point is polished and judged
_SINGULAR = 1e-10  # |det| of a row-normalised pattern system below which it is treated by SVD
_RANK = 1e-10  # singular values below this (relative) span a singular pattern's null space
_CONSISTENT = 1e-9  # equation residual (relative) of a consistent pattern system
_CERTIFICATE = 1e-9  # q^T d below -this (relative to the scale) is a certificate
_MOVING_CHECKS = 200  # feasible patterns along which v+ may move, checked by LP; more: unproven
_LP_OPTIONS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}


@dataclass
class Scaled:
    """The Jacobi-scaled local problem: ``W~ = S W S``, ``q~ = S q``, ``r = S r~``."""

    W: np.ndarray  # (2n, 2n), dense
    q: np.ndarray  # (2n,)
    mu: np.ndarray  # (n,)
    s: np.ndarray  # (2n,), r = s * r~
    d: np.ndarray  # (n,), diag(W~_NN): 1, or 0 for a contact nothing can move
    scale: float  # max |q~| (a velocity unit for tolerances)

    @property
    def n(self) -> int:
        return self.mu.shape[0]


def scaled(problem: FrictionalProblem) -> Scaled:
    """The scaled local problem of ``problem``.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem (W is made dense).

    Returns
    -------
    Scaled
        ``W~ = S W S`` (symmetrized), ``q~ = S q``, mu, s, diag(W~_NN) and the scale.
    """
    d = problem.diag_N
    root = np.where(d > 0, 1.0 / np.sqrt(np.where(d > 0, d, 1.0)), 1.0)
    s = np.concatenate([root, root])
    W = problem.W.toarray() * s[:, None] * s[None, :]
    q = problem.q * s
    return Scaled(W=0.5 * (W + W.T), q=q, mu=problem.mu.copy(), s=s,
                  d=np.diag(W)[:problem.n_contacts].copy(),
                  scale=max(float(np.max(np.abs(q), initial=0.0)), TINY))


def scaled_residual(problem: Scaled, impulses: np.ndarray) -> np.ndarray:
    """The Coulomb natural map of the scaled problem, ``max |F| / scale``, per r~.

    Parameters
    ----------
    problem : Scaled
        The scaled problem.
    impulses : np.ndarray
        One r~ (2n,) or a stack of them (rows).

    Returns
    -------
    np.ndarray
        The residual of each r~, shape (rows,).
    """
    n = problem.n
    R = np.atleast_2d(impulses)
    U = R @ problem.W + problem.q
    normal, tangential = R[:, :n], R[:, n:]
    u_normal, u_tangential = U[:, :n], U[:, n:]
    hat = u_normal + problem.mu * np.abs(u_tangential)
    d = problem.d
    projected_normal, projected_tangential = fm.project_on_cone(
        d * normal - hat, d * tangential - u_tangential, problem.mu)
    worst = np.maximum(np.max(np.abs(d * normal - projected_normal), axis=1),
                       np.max(np.abs(d * tangential - projected_tangential), axis=1))
    return worst / problem.scale


# --- the pattern systems ----------------------------------------------------------------
def pattern_systems(problem: Scaled, patterns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, c) of each pattern (rows of ``patterns``, one state per contact), row-normalised.

    Row k is ``l_N = 0`` (separate) or ``u_N = 0``; row n + k is ``l_T = 0`` (separate),
    ``u_T = 0`` (stick) or ``l_T +- mu l_N = 0`` (slide+-).

    Parameters
    ----------
    problem : Scaled
        The scaled problem.
    patterns : np.ndarray
        States, shape (count, n) or (n,).

    Returns
    -------
    A, c : np.ndarray
        The systems ``A r~ = c``, shapes (count, 2n, 2n) and (count, 2n).
    """
    n = problem.n
    patterns = np.atleast_2d(patterns)
    identity = np.eye(2 * n)
    separate = patterns == SEPARATE
    stick = patterns == STICK
    A = np.empty((patterns.shape[0], 2 * n, 2 * n))
    A[:, :n] = np.where(separate[:, :, None], identity[:n], problem.W[:n])
    A[:, n:] = np.where(stick[:, :, None], problem.W[n:], identity[n:])
    sign = np.where(patterns == SLIDE_PLUS, 1.0, np.where(patterns == SLIDE_MINUS, -1.0, 0.0))
    index = np.arange(n)
    A[:, n + index, index] += sign * problem.mu
    c = np.concatenate([np.where(separate, 0.0, -problem.q[:n]),
                        np.where(stick, -problem.q[n:], 0.0)], axis=1)
    norms = np.linalg.norm(A, axis=2)
    norms[norms == 0] = 1.0
    return A / norms[:, :, None], c / norms


def pattern_inequalities(problem: Scaled, pattern: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(B, h) with ``B r + h >= 0`` the inequalities of the states of ``pattern``.

    Separate ``u_N >= 0``; stick ``mu l_N -+ l_T >= 0``, ``l_N >= 0``; slide+ ``l_N >= 0``,
    ``u_T >= 0``; slide- ``l_N >= 0``, ``-u_T >= 0``.

    Parameters
    ----------
    problem : Scaled
        The scaled problem.
    pattern : np.ndarray
        One state per contact, shape (n,).

    Returns
    -------
    B, h : np.ndarray
        One row of B and one entry of h per inequality.
    """
    n = problem.n
    W, q, mu = problem.W, problem.q, problem.mu
    identity = np.eye(2 * n)
    rows, offsets = [], []
    for k, state in enumerate(pattern):
        if state == SEPARATE:
            rows.append(W[k])
            offsets.append(q[k])
            continue
        rows.append(identity[k])
        offsets.append(0.0)
        if state == STICK:
            rows += [mu[k] * identity[k] - identity[n + k], mu[k] * identity[k] + identity[n + k]]
            offsets += [0.0, 0.0]
        else:
            sign = 1.0 if state == SLIDE_PLUS else -1.0
            rows.append(sign * W[n + k])
            offsets.append(sign * q[n + k])
    return np.array(rows), np.array(offsets)


def _pattern_lp(problem: Scaled, pattern: np.ndarray, start: np.ndarray, null: np.ndarray
                ) -> np.ndarray | None:
    """A point ``start + null y`` that satisfies the inequalities of ``pattern`` with the
    largest common margin, or None when no point of the affine set satisfies them."""
    B, h = pattern_inequalities(problem, pattern)
    Bn = B @ null
    slack = B @ start + h
    k = null.shape[1]
    # max t  s.t.  Bn y + slack >= t,  t <= scale;  variables (y, t)
    A_ub = np.hstack([-Bn, np.ones((B.shape[0], 1))])
    bound = 1e6 * problem.scale
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = scipy.optimize.linprog(
            np.concatenate([np.zeros(k), [-1.0]]), A_ub=A_ub, b_ub=slack,
            bounds=[(-bound, bound)] * k + [(None, problem.scale)], method="highs",
            options=_LP_OPTIONS)
    if result.status != 0 or result.x[-1] < -_CONSISTENT * problem.scale:
        return None
    return start + null @ result.x[:k]


def _null_space(matrix: np.ndarray) -> np.ndarray:
    """An orthonormal basis (columns) of the null space of a square matrix."""
    _, sigma, right = np.linalg.svd(matrix)
    keep = sigma > _RANK * max(float(sigma[0]), TINY)
    return right[~keep].T


def _velocity_lp(problem: Scaled, start: np.ndarray, null_W: np.ndarray) -> np.ndarray | None:
    """An r with ``W r + q = u`` (u that of ``start``: r = start + null(W) y) that obeys the
    law given u, with the largest margin; None when there is none. Given u the law is
    convex in r: ``r_k = 0`` where u_N > 0; ``r_k in K`` where u_k = 0; ``l_T = -+ mu l_N``,
    ``l_N >= 0`` where u_N = 0 and u_T is positive (negative); nothing where u_N < 0."""
    n = problem.n
    tol = 1e-9 * problem.scale
    u = problem.W @ start + problem.q
    identity = np.eye(2 * n)
    equal, inequal = [], []
    for k in range(n):
        u_normal, u_tangential, mu = u[k], u[n + k], problem.mu[k]
        if u_normal < -tol:
            return None
        if u_normal > tol:
            equal += [identity[k], identity[n + k]]
            continue
        inequal.append(identity[k])
        if u_tangential > tol:
            equal.append(identity[n + k] + mu * identity[k])
        elif u_tangential < -tol:
            equal.append(identity[n + k] - mu * identity[k])
        else:
            inequal += [mu * identity[k] - identity[n + k], mu * identity[k] + identity[n + k]]
    k = null_W.shape[1]
    B = np.array(inequal).reshape(-1, 2 * n)
    E = np.array(equal).reshape(-1, 2 * n)
    bound = 1e6 * problem.scale
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = scipy.optimize.linprog(
            np.concatenate([np.zeros(k), [-1.0]]),
            A_ub=np.hstack([-B @ null_W, np.ones((B.shape[0], 1))]) if len(B) else None,
            b_ub=B @ start if len(B) else None,
            A_eq=np.hstack([E @ null_W, np.zeros((E.shape[0], 1))]) if len(E) else None,
            b_eq=-E @ start if len(E) else None,
            bounds=[(-bound, bound)] * k + [(None, problem.scale)], method="highs",
            options=_LP_OPTIONS)
    if result.status != 0 or result.x[-1] < -tol:
        return None
    return start + null_W @ result.x[:k]


def _velocity_varies(problem: Scaled, velocity_map: np.ndarray, pattern: np.ndarray,
                     start: np.ndarray, null: np.ndarray) -> bool:
    """Whether v+ takes more than one value on the points ``start + null y`` that satisfy the
    inequalities of ``pattern``: the range of a seeded random component of ``M^1/2 v+`` over
    them (two LPs); a range of zero in a random direction means v+ is fixed there (with
    probability one)."""
    B, h = pattern_inequalities(problem, pattern)
    direction = np.random.default_rng(1).standard_normal(velocity_map.shape[0])
    objective = direction @ velocity_map @ null
    bound = 1e6 * problem.scale
    values = []
    for sign in (1.0, -1.0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = scipy.optimize.linprog(sign * objective, A_ub=-B @ null, b_ub=B @ start + h,
                                            bounds=[(-bound, bound)] * null.shape[1],
                                            method="highs", options=_LP_OPTIONS)
        if result.status != 0:
            return True  # undecided counts as varying: uniqueness stays unproven
        values.append(sign * result.fun)
    spread = abs(values[1] - values[0])
    unit = max(float(np.linalg.norm(velocity_map @ start)), problem.scale, TINY)
    return spread > SAME_VELOCITY * unit


def classify(problem: Scaled, impulses: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """The state of each contact read off r~.

    Separate where l_N is (relatively) zero, slide where |l_T| reaches mu l_N (sign: slide+
    when l_T < 0), stick otherwise.

    Parameters
    ----------
    problem : Scaled
        The scaled problem.
    impulses : np.ndarray
        r~, shape (2n,).
    tol : float, optional
        The tolerance, relative to max |r~|.

    Returns
    -------
    np.ndarray
        The state of each contact, shape (n,).
    """
    n = problem.n
    normal, tangential = impulses[:n], impulses[n:]
    size = max(float(np.max(np.abs(impulses), initial=0.0)), TINY)
    states = np.full(n, STICK)
    edge = np.abs(tangential) >= problem.mu * normal - tol * size
    states[edge & (tangential < 0)] = SLIDE_PLUS
    states[edge & (tangential >= 0)] = SLIDE_MINUS
    states[normal <= tol * size] = SEPARATE
    return states


def polish(problem: Scaled, impulses: np.ndarray, rounds: int = 3) -> np.ndarray:
    """Newton steps on the linear system of the contact states read off r~.

    The tight inequalities are extra rows; each step is the minimum-norm correction, so a point
    of a singular pattern stays where it is; the best iterate is kept.

    Parameters
    ----------
    problem : Scaled
        The scaled problem.
    impulses : np.ndarray
        The starting r~, shape (2n,).
    rounds : int, optional
        The most steps.

    Returns
    -------
    np.ndarray
        The r~ of smallest scaled residual.
    """
    best, best_value = impulses, float(scaled_residual(problem, impulses)[0])
    current = impulses
    for _ in range(rounds):
        if best_value == 0.0:
            break
        pattern = classify(problem, current)
        A, c = pattern_systems(problem, pattern)
        B, h = pattern_inequalities(problem, pattern)
        tight = np.abs(B @ current + h) <= 1e-9 * problem.scale
        system = np.vstack([A[0], B[tight]])
        rhs = np.concatenate([c[0], -h[tight]])
        step = np.linalg.lstsq(system, rhs - system @ current, rcond=None)[0]
        current = current + step
        value = float(scaled_residual(problem, current)[0])
        if value < best_value:
            best, best_value = current, value
    return best


# --- enumeration --------------------------------------------------------------------------
@dataclass
class Enumeration:
    """What the enumeration found: the solutions (impulses of the original problem, each
    residual <= 1e-12), their patterns, and whether v+ may vary inside a pattern."""

    solutions: list[np.ndarray]
    patterns: list[np.ndarray]
    velocity_may_vary: bool
    lp_solves: int


def _all_patterns(n: int) -> np.ndarray:
    return np.stack(np.unravel_index(np.arange(4 ** n), (4,) * n), axis=1).astype(np.int8)


def enumerate_solutions(problem: FrictionalProblem) -> Enumeration:
    """Every solution of the law reachable by the patterns of contact states (module docstring).

    Exhaustive, so only for n <= ENUMERATION_LIMIT (ValueError above it).

    Regular patterns are solved in batches. A singular, consistent pattern whose
    minimum-norm point fails the inequalities is decided by an LP, except where v+ is the
    same at every point of its affine set (its null space leaves ``H r`` alone) and equals
    the v+ of a solution already found: it cannot add a distinct v+, so it is skipped.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.

    Returns
    -------
    Enumeration
        The solutions, their patterns, whether v+ may vary and the LPs solved.
    """
    n = problem.n_contacts
    if n > ENUMERATION_LIMIT:
        raise ValueError(f"{problem.name}: enumeration is for n <= {ENUMERATION_LIMIT}, "
                         f"not {n}")
    local = scaled(problem)
    patterns = _all_patterns(n)
    found: list[tuple[np.ndarray, np.ndarray]] = []
    pending: list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]] = []
    moving: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for start in range(0, len(patterns), _CHUNK):
        chunk = patterns[start:start + _CHUNK]
        A, c = pattern_systems(local, chunk)
        _, logdet = np.linalg.slogdet(A)
        regular = logdet > math.log(_SINGULAR)
        X = np.zeros((len(chunk), 2 * n))
        if regular.any():
            X[regular] = np.linalg.solve(A[regular], c[regular][:, :, None])[:, :, 0]
        values = np.full(len(chunk), np.inf)
        values[regular] = scaled_residual(local, X[regular])
        for i in np.flatnonzero(regular & (values <= _CANDIDATE)):
            found.append((chunk[i], X[i]))
        singular = np.flatnonzero(~regular)
        if singular.size == 0:
            continue
        # singular systems: minimum-norm points (batched SVD); the inconsistent ones drop out
        left, sigma, right = np.linalg.svd(A[singular])
        keep = sigma > _RANK * np.maximum(sigma[:, :1], TINY)
        coefficients = np.where(keep, np.einsum("pji,pj->pi", left, c[singular])
                                / np.where(keep, sigma, 1.0), 0.0)
        points = np.einsum("pji,pj->pi", right, coefficients)
        gaps = np.linalg.norm(np.einsum("pij,pj->pi", A[singular], points) - c[singular], axis=1)
        consistent = gaps <= _CONSISTENT * np.maximum(1.0, np.linalg.norm(c[singular], axis=1))
        feasible = scaled_residual(local, points) <= _CANDIDATE
        for j in np.flatnonzero(consistent):
            pattern, x, null = chunk[singular[j]], points[j], right[j][~keep[j]].T
            moves = bool(null.size and np.max(np.abs(local.W @ null)) > _RANK)
            if feasible[j]:
                found.append((pattern, x))
                if moves:  # v+ = v- + M^-1 H r may move along this pattern's null space
                    moving.append((pattern, x, null))
            else:
                pending.append((pattern, x, null, moves))
    solutions, kept = _accepted(problem, local, found)
    known = _Velocities(problem, local)
    known.add(solutions)
    lp_solves = 0
    # v+ (and so u) is the same all over a pending pattern that does not move it: one LP per
    # distinct such v+ decides whether any r with that u obeys the law (_velocity_lp)
    still: list[np.ndarray] = []
    for pattern, x, null, moves in pending:
        if not moves:
            still.append(x)
            continue
        lp_solves += 1
        point = _pattern_lp(local, pattern, x, null)
        more, more_patterns = _accepted(problem, local, [] if point is None
                                        else [(pattern, point)])
        solutions += more
        kept += more_patterns
        known.add(more)
        if more:
            moving.append((pattern, point, null))
    starts = _Velocities(problem, local)
    if still:
        points = np.array(still)
        keys = starts.base + points @ starts.map.T
        # one start per v+ (rounded far below SAME_VELOCITY, so equal v+ share a bin)
        grid = SAME_VELOCITY * 1e-2 * max(starts.unit, float(np.max(np.abs(keys))), TINY)
        _, first = np.unique(np.round(keys / grid), axis=0, return_index=True)
        for i in np.sort(first):
            if not known.holds(keys[i]) and not starts.holds(keys[i]):
                starts.keys.append(keys[i])
                starts.points.append(points[i])
    null_W = _null_space(local.W)
    for x, key in zip(starts.points, starts.keys, strict=True):
        if known.holds(key):
            continue
        lp_solves += 1
        point = _velocity_lp(local, x, null_W)
        more, more_patterns = _accepted(problem, local, [] if point is None
                                        else [(classify(local, point), point)])
        solutions += more
        kept += more_patterns
        known.add(more)
    may_vary = len(moving) > _MOVING_CHECKS or any(
        _velocity_varies(local, known.map, pattern, x, null) for pattern, x, null in moving)
    return Enumeration(solutions, kept, may_vary, lp_solves + 2 * min(len(moving),
                                                                       _MOVING_CHECKS))


class _Velocities:
    """A set of v+, kept as ``M^1/2 v+`` so that :func:`same_velocity` is a Euclidean test."""

    def __init__(self, problem: FrictionalProblem, local: Scaled) -> None:
        finite = problem.m_inv > 0
        root = np.sqrt(problem.m_inv[finite])
        self.base = problem.v_minus[finite] / root
        self.map = (sp.diags(root) @ sp.csr_matrix(problem.H)[finite] @ sp.diags(local.s)
                    ).toarray()
        self.unit = float(np.linalg.norm(self.base))
        self.s = local.s
        self.keys: list[np.ndarray] = []
        self.points: list[np.ndarray] = []

    def key(self, scaled_impulses: np.ndarray) -> np.ndarray:
        return self.base + self.map @ scaled_impulses

    def holds(self, key: np.ndarray) -> bool:
        if not self.keys:
            return False
        keys = np.array(self.keys)
        distance = np.linalg.norm(keys - key, axis=1)
        unit = np.maximum(np.maximum(self.unit, np.linalg.norm(key)),
                          np.linalg.norm(keys, axis=1))
        return bool(np.any(distance <= SAME_VELOCITY * np.maximum(unit, TINY)))

    def add(self, impulses: list[np.ndarray]) -> None:
        """Adds solutions given in original units."""
        for r in impulses:
            self.keys.append(self.base + self.map @ (r / self.s))


def _accepted(problem: FrictionalProblem, local: Scaled,
              found: list[tuple[np.ndarray, np.ndarray]]
              ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The polished points (original units) that reach the reference residual, with their
    patterns."""
    solutions, kept = [], []
    for pattern, x in found:
        impulses = local.s * polish(local, x)
        if fm.residual(problem, impulses) <= REFERENCE_RESIDUAL:
            solutions.append(impulses)
            kept.append(pattern)
    return solutions, kept


def distinct_velocities(problem: FrictionalProblem, solutions: list[np.ndarray]
                        ) -> list[np.ndarray]:
    """One representative r per distinct v+ (M-norm, relative SAME_VELOCITY).

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    solutions : list of np.ndarray
        Impulses r, shape (2n,) each.

    Returns
    -------
    list of np.ndarray
        The first r of each distinct v+.
    """
    representatives: list[np.ndarray] = []
    velocities: list[np.ndarray] = []
    for impulses in solutions:
        v = problem.v_plus(impulses)
        if not any(same_velocity(problem, v, other) for other in velocities):
            representatives.append(impulses)
            velocities.append(v)
    return representatives


def same_velocity(problem: FrictionalProblem, v_a: np.ndarray, v_b: np.ndarray) -> bool:
    """||v_a - v_b||_M <= SAME_VELOCITY * max(||v-||_M, ||v_a||_M, ||v_b||_M, tiny).

    Parameters
    ----------
    problem : FrictionalProblem
        The problem, whose masses give the norm.
    v_a, v_b : np.ndarray
        Velocities, shape (d,) each.

    Returns
    -------
    bool
        Whether they are the same v+.
    """
    unit = max(problem.m_norm(problem.v_minus), problem.m_norm(v_a), problem.m_norm(v_b), TINY)
    return problem.m_norm(v_a - v_b) <= SAME_VELOCITY * unit


# --- Lemke ------------------------------------------------------------------------------------
def stewart_trinkle_scaled(problem: Scaled) -> tuple[np.ndarray, np.ndarray]:
    """The Stewart-Trinkle LCP (as :meth:`FrictionalProblem.stewart_trinkle`) of ``problem``.

    Parameters
    ----------
    problem : Scaled
        The scaled problem.

    Returns
    -------
    A, c : np.ndarray
        The LCP's dense matrix (4n x 4n) and vector (4n,).
    """
    n = problem.n
    W = problem.W
    NN, NT, TN, TT = W[:n, :n], W[:n, n:], W[n:, :n], W[n:, n:]
    identity, zero = np.eye(n), np.zeros((n, n))
    A = np.block([[NN, NT, -NT, zero], [TN, TT, -TT, identity], [-TN, -TT, TT, identity],
                  [np.diag(problem.mu), -identity, -identity, zero]])
    q_N, q_T = problem.q[:n], problem.q[n:]
    return A, np.concatenate([q_N, q_T, -q_T, np.zeros(n)])


def lemke_solution(problem: FrictionalProblem, attempts: int = 3) -> np.ndarray | None:
    """r from Lemke on the scaled Stewart-Trinkle LCP, polished.

    Tries the covering vector 1 and then seeded random positive ones; None when no attempt
    reaches 1e-12.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    attempts : int, optional
        The most covering vectors tried.

    Returns
    -------
    np.ndarray or None
        r, shape (2n,), or None.
    """
    n = problem.n_contacts
    local = scaled(problem)
    A, c = stewart_trinkle_scaled(local)
    rng = np.random.default_rng(0)
    best, best_value = None, np.inf
    for attempt in range(attempts):
        covering = np.ones(4 * n) if attempt == 0 else rng.uniform(0.5, 2.0, 4 * n)
        z = lemke(A, c / local.scale, covering)
        if z is None:
            continue
        impulses = local.s * polish(local, local.scale * np.concatenate(
            [z[:n], z[n:2 * n] - z[2 * n:3 * n]]))
        value = fm.residual(problem, impulses)
        if value < best_value:
            best, best_value = impulses, value
        if value <= REFERENCE_RESIDUAL:
            break
    return best if best_value <= REFERENCE_RESIDUAL else None


# --- the existence certificate -----------------------------------------------------------------
def ccp_certificate(problem: FrictionalProblem) -> tuple[float, np.ndarray | None]:
    """(min q^T d / scale, d) over ``d in K_mu``, ``H d = 0``, ``0 <= d_N <= 1``.

    The LP of the module docstring, on the scaled problem; d returned in original units. A
    negative value below -1e-9 is a certificate that the relaxed problem is unbounded.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.

    Returns
    -------
    tuple of (float, np.ndarray or None)
        The optimum and d; (0.0, None) without contacts or when the LP fails.
    """
    n = problem.n_contacts
    if n == 0:
        return 0.0, None
    local = scaled(problem)
    moving = problem.m_inv > 0
    H = sp.csr_matrix(sp.diags(np.sqrt(problem.m_inv)) @ problem.H @ sp.diags(local.s))[moving]
    norms = np.sqrt(np.asarray(H.multiply(H).sum(axis=1)).ravel())
    H = sp.csr_matrix(sp.diags(1.0 / np.where(norms > 0, norms, 1.0)) @ H)
    mu = local.mu
    identity = sp.identity(n, format="csr")
    cone = sp.vstack([sp.hstack([-sp.diags(mu), identity]), sp.hstack([-sp.diags(mu), -identity])])
    bounds = [(0.0, 1.0)] * n + [(-m, m) for m in mu]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = scipy.optimize.linprog(local.q / local.scale, A_ub=cone, b_ub=np.zeros(2 * n),
                                        A_eq=H, b_eq=np.zeros(H.shape[0]), bounds=bounds,
                                        method="highs", options=_LP_OPTIONS)
    if result.status != 0:
        return 0.0, None
    direction = result.x
    if np.max(np.abs(H @ direction), initial=0.0) > 1e-8:
        return 0.0, None
    return float(result.fun), local.s * direction


# --- the reference ---------------------------------------------------------------------------
def components(problem: FrictionalProblem) -> list[np.ndarray]:
    """Groups of contacts that W couples: independent local problems, each solved alone.

    Coupled: |W_ij| above 1e-14 sqrt(W_ii W_jj) between any of their normal or tangential
    entries.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.

    Returns
    -------
    list of np.ndarray
        The contact indices of each group.
    """
    n = problem.n_contacts
    W = sp.coo_matrix(problem.W)
    diagonal = np.abs(problem.W.diagonal())
    strong = np.abs(W.data) > 1e-14 * np.sqrt(diagonal[W.row] * diagonal[W.col])
    graph = sp.coo_matrix((np.ones(int(strong.sum())), (W.row[strong] % n, W.col[strong] % n)),
                          shape=(n, n))
    count, labels = sp.csgraph.connected_components(graph, directed=False)
    return [np.flatnonzero(labels == label) for label in range(count)]


def subproblem(problem: FrictionalProblem, contacts: np.ndarray) -> FrictionalProblem:
    """The contacts ``contacts`` of ``problem`` alone (same bodies, v- and masses).

    Parameters
    ----------
    problem : FrictionalProblem
        The whole problem.
    contacts : np.ndarray
        Indices of the contacts to keep, not empty.

    Returns
    -------
    FrictionalProblem
        The subproblem, named ``NAME[FIRST..]``.
    """
    normal = problem.normal
    return FrictionalProblem.build(
        f"{problem.name}[{contacts[0]}..]", normal.G[:, contacts], problem.T[:, contacts],
        normal.m_inv, normal.v_minus, problem.mu[contacts], normal.restitution[contacts],
        normal.n_rel[contacts], problem.d_rel[contacts], dofs_per_body=normal.dofs_per_body)


@dataclass
class _Part:
    """The answer for one component: its distinct solutions, uniqueness, and how."""

    solutions: list[np.ndarray]
    unique: bool | None
    exhaustive: bool
    method: str


def _solve_part(part: FrictionalProblem) -> _Part:
    if part.n_contacts > ENUMERATION_LIMIT:
        found = lemke_solution(part)
        return _Part([] if found is None else [found], None, False, "lemke")
    enumeration = enumerate_solutions(part)
    distinct = distinct_velocities(part, enumeration.solutions)
    checked = lemke_solution(part)
    if checked is not None and not any(
            same_velocity(part, part.v_plus(checked), part.v_plus(other)) for other in distinct):
        # Lemke found a solution the enumeration missed: its list is not complete
        return _Part(distinct + [checked], None, False, "enumeration(incomplete)+lemke")
    unique: bool | None = len(distinct) == 1
    if enumeration.velocity_may_vary and len(distinct) == 1:
        unique = None
    return _Part(distinct, unique if distinct else None, True, "enumeration")


def compute_reference(problem: FrictionalProblem) -> FrictionalReference:
    """The reference of ``problem`` (module docstring), one component of coupled contacts at a time.

    It also fills ``problem.metadata`` with ``reference_solutions`` (the number of distinct v+
    where the enumeration was complete, else None), ``ccp_certificate`` (the LP's value),
    ``ccp_unbounded`` and, where nothing was found, ``reference_no_solution_proven``.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.

    Returns
    -------
    FrictionalReference
        The solution found, or zero impulses marked unsolved.
    """
    n = problem.n_contacts
    metadata = problem.metadata
    if n == 0:
        return FrictionalReference(np.zeros(0), problem.v_minus.copy(), "none", 0.0, True)
    groups = components(problem)
    parts = [_solve_part(subproblem(problem, contacts)) for contacts in groups]
    value, _ = ccp_certificate(problem)
    metadata["ccp_certificate"] = value
    metadata["ccp_unbounded"] = bool(value < -_CERTIFICATE)
    exhaustive = all(part.exhaustive for part in parts)
    metadata["reference_solutions"] = (int(np.prod([len(part.solutions) for part in parts]))
                                       if exhaustive else None)
    methods = sorted({part.method for part in parts})
    method = "+".join(methods) if len(groups) == 1 else \
        f"{'+'.join(methods)} per component ({len(groups)})"
    impulses = np.zeros(2 * n)
    if all(part.solutions for part in parts):
        for contacts, part in zip(groups, parts, strict=True):
            sub = subproblem(problem, contacts)
            best = min(part.solutions, key=lambda r, sub=sub: fm.residual(sub, r))
            impulses[contacts] = best[:len(contacts)]
            impulses[n + contacts] = best[len(contacts):]
        residual = fm.residual(problem, impulses)
        if residual <= REFERENCE_RESIDUAL:
            flags = [part.unique for part in parts]
            unique = False if False in flags else (None if None in flags else True)
            return FrictionalReference(impulses, problem.v_plus(impulses), method, residual,
                                       unique)
        if len(groups) > 1:  # the neglected couplings mattered after all: the whole at once
            found = lemke_solution(problem)
            if found is not None:
                metadata["reference_solutions"] = None
                return FrictionalReference(found, problem.v_plus(found), "lemke",
                                           fm.residual(problem, found), None)
    # nothing found: zero impulses are kept for the record, and the problem marked unsolved
    certified = value < -_CERTIFICATE
    metadata["reference_no_solution_proven"] = bool(certified and exhaustive)
    impulses = np.zeros(2 * n)
    return FrictionalReference(impulses, problem.v_plus(impulses),
                               f"{method}: no solution" + (" (ccp certificate)" if certified
                                                           else ""),
                               fm.residual(problem, impulses), None, solvable=not certified)


def attach_reference(problem: FrictionalProblem) -> FrictionalProblem:
    """Sets ``problem.reference`` and records ``reference_verified`` in its metadata.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem; ``reference_unique`` and ``reference_solvable`` are recorded too.

    Returns
    -------
    FrictionalProblem
        ``problem``.
    """
    problem.reference = compute_reference(problem)
    problem.metadata["reference_verified"] = problem.reference.verified
    problem.metadata["reference_unique"] = problem.reference.unique
    problem.metadata["reference_solvable"] = problem.reference.solvable
    return problem


def describe(reference: FrictionalReference) -> str:
    """Why a reference is not verified, in a few words ('' when it is).

    Parameters
    ----------
    reference : FrictionalReference
        The reference.

    Returns
    -------
    str
        The reason, or ''.
    """
    if reference.verified:
        return ""
    if not reference.solvable:
        return "no solution (ccp certificate); no solver is charged for it"
    if reference.residual > REFERENCE_RESIDUAL:
        return f"no solution found (best residual {reference.residual:.1e})"
    if reference.unique is False:
        return "several solutions with different v+; v_error will not be computed"
    return "uniqueness not proven; v_error will not be computed"
