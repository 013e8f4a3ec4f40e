"""Anderson acceleration of a fixed-point iteration, compiled (numba): the start of the next
round of staggered projections.

For a map G and the last k rounds' starts ``x_i`` and answers ``g_i = G(x_i)`` (oldest
first), type-II Anderson acceleration (Anderson 1965; Walker and Ni, "Anderson acceleration
for fixed-point iterations", SIAM J. Numer. Anal. 49, 2011) starts the next round from

    x_next = g_k - dG gamma,   gamma = argmin ||f_k - dF gamma||_2,

with ``f_i = g_i - x_i``, and dF, dG the k - 1 differences of consecutive f_i and g_i. On an
affine map it is GMRES on ``(I - A) x = b`` in disguise: with a history of k rounds it is
exact on an affine map of k - 1 dimensions. The least-squares problem is solved by modified
Gram-Schmidt on dF's columns, dropping a column whose part orthogonal to those before it is
below ``DEPENDENT`` of its length (a nearly repeated difference), then back substitution.
Every sum runs in index order in plain loops (no BLAS), so the result is the same on every CPU,
and the same whichever compiled caller calls it: ``qpbench.solvers.friction_staggered``'s
Python loop and ``qpbench.solvers.staggered_compiled``'s compiled loop both do.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

DEPENDENT = 1e-10  # a difference whose new part is below this share of its length is dropped
# a mixed start longer than this many times the longest answer mixed is refused (the map's
# own answer starts the round instead): where the iteration has no fixed point (a problem
# without a solution) the fit extrapolates ever further, and the inner solves slow down;
# 2 and 10 refused mixes that rough boxes need (docs/notes/pi-robust.md)
GROWTH = 1e3


@njit(cache=True)
def step_length(start: np.ndarray, answer: np.ndarray) -> float:
    """``||answer - start||_2``, summed in index order: the fixed-point residual's size.

    Parameters
    ----------
    start, answer : np.ndarray
        x_k and G(x_k), shape (n,).

    Returns
    -------
    float
        The Euclidean length of their difference.
    """
    total = 0.0
    for i in range(start.size):
        difference = answer[i] - start[i]
        total += difference * difference
    return math.sqrt(total)


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b summed in index order."""
    total = 0.0
    for i in range(a.size):
        total += a[i] * b[i]
    return total


@njit(cache=True)
def anderson_start(starts: np.ndarray, answers: np.ndarray) -> np.ndarray:
    """The next round's start from the last rounds' starts and answers (module docstring).

    Parameters
    ----------
    starts, answers : np.ndarray
        x_i and G(x_i) of the last k >= 1 rounds, oldest first, shape (k, n).

    Returns
    -------
    np.ndarray
        ``g_k - dG gamma``, shape (n,); ``g_k`` itself when k = 1, when every difference is
        dropped, or when the mixed start is not finite or is more than ``GROWTH`` times as
        long as the longest of the answers.
    """
    rounds, n = starts.shape
    latest = answers[rounds - 1].copy()
    columns = rounds - 1
    if columns == 0:
        return latest
    residual = latest - starts[rounds - 1]  # f_k
    basis = np.empty((columns, n))  # dF's columns, made orthonormal in place
    answer_differences = np.empty((columns, n))  # dG's columns
    for j in range(columns):
        for i in range(n):
            basis[j, i] = ((answers[j + 1, i] - starts[j + 1, i])
                           - (answers[j, i] - starts[j, i]))
            answer_differences[j, i] = answers[j + 1, i] - answers[j, i]
    triangle = np.zeros((columns, columns))
    kept = np.zeros(columns, dtype=np.bool_)
    for j in range(columns):
        length = math.sqrt(_dot(basis[j], basis[j]))
        for m in range(j):
            if kept[m]:
                coefficient = _dot(basis[m], basis[j])
                triangle[m, j] = coefficient
                for i in range(n):
                    basis[j, i] -= coefficient * basis[m, i]
        remaining = math.sqrt(_dot(basis[j], basis[j]))
        if remaining > DEPENDENT * length and remaining > 0.0:
            kept[j] = True
            triangle[j, j] = remaining
            for i in range(n):
                basis[j, i] /= remaining
    gamma = np.zeros(columns)
    for j in range(columns - 1, -1, -1):
        if kept[j]:
            value = _dot(basis[j], residual)
            for m in range(j + 1, columns):
                value -= triangle[j, m] * gamma[m]
            gamma[j] = value / triangle[j, j]
    start = latest.copy()
    for j in range(columns):
        if gamma[j] != 0.0:
            for i in range(n):
                start[i] -= gamma[j] * answer_differences[j, i]
    longest = 0.0
    for k in range(rounds):
        longest = max(longest, math.sqrt(_dot(answers[k], answers[k])))
    length = math.sqrt(_dot(start, start))
    if not math.isfinite(length) or length > GROWTH * longest:
        return latest
    return start


@njit(cache=True)
def next_start(starts: np.ndarray, answers: np.ndarray, kept: int, last_step: float,
               start: np.ndarray, answer: np.ndarray) -> tuple[np.ndarray, int, float]:
    """The next round's start after the round from ``start`` to ``answer``, the history
    updated in place: the one rule of both staggered loops.

    The history restarts from this round when its step ``||answer - start||`` is longer than
    the round before's; it keeps the last ``depth + 1`` rounds (``depth + 1`` the history's
    rows), whose :func:`anderson_start` is the next start (a copy of ``answer`` at depth 0).

    Parameters
    ----------
    starts, answers : np.ndarray
        The history, shape (depth + 1, n), oldest first; its first ``kept`` rows are filled.
    kept : int
        The rounds the history holds.
    last_step : float
        The step of the round before (infinite before the first round).
    start, answer : np.ndarray
        This round's start x_k and answer G(x_k), shape (n,).

    Returns
    -------
    next_start : np.ndarray
        The start of the next round, shape (n,).
    kept : int
        The rounds the history now holds.
    step : float
        This round's step, the next call's ``last_step``.
    """
    depth = starts.shape[0] - 1
    step = step_length(start, answer)
    if step > last_step:
        kept = 0
    if kept == depth + 1:
        starts[:depth] = starts[1:]
        answers[:depth] = answers[1:]
        kept = depth
    starts[kept], answers[kept] = start, answer
    kept += 1
    return anderson_start(starts[:kept], answers[:kept]), kept, step


_warm = False


def warm_up() -> None:
    """Compiles (or loads from numba's cache) the functions once in this process."""
    global _warm
    if _warm:
        return
    history = np.zeros((2, 2))
    next_start(history, history.copy(), 0, np.inf, np.zeros(2), np.ones(2))
    _warm = True
