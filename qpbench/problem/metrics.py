"""Metrics computed by qpbench from the impulses l alone, never taken from a solver's claim.

All scaled metrics divide by ``scale = max(||b||_inf, TINY)`` so that they are
relative velocities, comparable across problems.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from qpbench.problem.impact import ImpactProblem

TINY = 1e-300


def vector_scale(values: np.ndarray) -> float:
    """max(||values||_inf, TINY).

    Parameters
    ----------
    values : np.ndarray
        A vector, possibly empty.

    Returns
    -------
    float
        Its largest magnitude, at least TINY.
    """
    return max(float(np.max(np.abs(values), initial=0.0)), TINY)


def scale(problem: ImpactProblem) -> float:
    """max(||b||_inf, TINY): the velocity unit of every scaled metric.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.

    Returns
    -------
    float
        The scale.
    """
    return vector_scale(problem.b)


def dot(x: np.ndarray, y: np.ndarray) -> float:
    """``x^T y``, summed in an order that does not depend on the CPU.

    NumPy's ``x @ y`` calls BLAS, whose dot kernel (and so the order of its sums) the CPU
    chooses at run time; here the elementwise products, each rounded once on any CPU, are
    summed by NumPy's pairwise summation (Higham, "The accuracy of floating point
    summation", SIAM J. Sci. Comput. 14(4), 1993), whose order is fixed.

    Parameters
    ----------
    x, y : np.ndarray
        Vectors of one length.

    Returns
    -------
    float
        Their inner product.
    """
    return float(np.add.reduce(x * y))


def is_finite(impulses: np.ndarray | None, problem: ImpactProblem) -> bool:
    """True when l exists, has n entries and all are finite.

    Parameters
    ----------
    impulses : np.ndarray or None
        The answer l; None when the solver gave none.
    problem : ImpactProblem
        The problem it answers.

    Returns
    -------
    bool
        Whether l has shape (n,) and only finite entries.
    """
    return (
        impulses is not None
        and np.shape(impulses) == (problem.n_contacts,)
        and bool(np.all(np.isfinite(impulses)))
    )


def natural_map(problem: ImpactProblem, impulses: np.ndarray) -> np.ndarray:
    """F(l) = min(D l, w) elementwise, D = diag(Q), w = Q l + b; zero exactly at LCP solutions.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    np.ndarray
        F(l), shape (n,), in velocity units.
    """
    return np.minimum(problem.diag_Q * impulses, problem.w(impulses))


def residual(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """residual = ||min(D l, Q l + b)||_inf / max(||b||_inf, tiny).

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        The scaled residual; 0 for a problem without contacts.
    """
    if problem.n_contacts == 0:
        return 0.0
    return float(np.max(np.abs(natural_map(problem, impulses)))) / scale(problem)


def complementarity(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """complementarity = |(D l)^T w| / max(||b||_inf, tiny)^2 (velocity times velocity).

    It is divided by the scale twice, since its square underflows to 0 below 1e-154.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        The scaled complementarity gap.
    """
    unit = scale(problem)
    return abs(dot(problem.diag_Q * impulses, problem.w(impulses))) / unit / unit


def infeasibility(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """infeasibility = max(0, -min(D l), -min(w)) / max(||b||_inf, tiny).

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        The scaled violation of l >= 0 and w >= 0; 0 for a problem without contacts.
    """
    if problem.n_contacts == 0:
        return 0.0
    worst = max(0.0, -float(np.min(problem.diag_Q * impulses)), -float(np.min(problem.w(impulses))))
    return worst / scale(problem)


def v_error(problem: ImpactProblem, impulses: np.ndarray, v_plus_ref: np.ndarray) -> float:
    """v_error = ||v+(l) - v+_ref||_M / ||v-||_M (||v-||_M replaced by tiny when zero).

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).
    v_plus_ref : np.ndarray
        The reference post-impact velocity, shape (d,).

    Returns
    -------
    float
        The relative error of v+ in the mass norm.
    """
    difference = problem.m_norm(problem.v_plus(impulses) - v_plus_ref)
    return difference / max(problem.m_norm(problem.v_minus), TINY)


def energy_gain(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """energy_gain = (KE+ - KE-) / KE-, signed; KE = 1/2 v^T M v.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        The relative change of kinetic energy (KE- replaced by tiny when zero).
    """
    before = problem.kinetic_energy(problem.v_minus)
    after = problem.kinetic_energy(problem.v_plus(impulses))
    return (after - before) / max(before, TINY)


def energy_change_identity(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """KE+ - KE- from the impulses alone, true for ANY l.

    ``KE+ - KE- = l^T (b / (1 + c) - nrel) + 1/2 l^T Q l``; with nrel = 0 and one c this is
    ``l^T w / (1 + c) - (1 - c) / (2 (1 + c)) * l^T Q l``.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        KE+ - KE- by the identity.
    """
    Q_l = problem.Q @ impulses
    u_minus = problem.b / (1.0 + problem.restitution) - problem.n_rel
    return dot(impulses, u_minus) + 0.5 * dot(impulses, Q_l)


def energy_identity_gap(problem: ImpactProblem, impulses: np.ndarray) -> float:
    """|(KE(v+) - KE(v-)) - energy_change_identity(l)| / max(KE-, tiny): checks the assembly.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray
        The impulses l, shape (n,).

    Returns
    -------
    float
        The relative gap between the energy change computed from v+ and by the identity.
    """
    before = problem.kinetic_energy(problem.v_minus)
    direct = problem.kinetic_energy(problem.v_plus(impulses)) - before
    return abs(direct - energy_change_identity(problem, impulses)) / max(before, TINY)


def evaluate(
    problem: ImpactProblem, impulses: np.ndarray | None, accuracy: float
) -> dict[str, Any]:
    """Every metric of an answer, and qpbench's verdict: finite l and residual <= accuracy.

    ``v_error`` is NaN when the problem has no verified reference.

    Parameters
    ----------
    problem : ImpactProblem
        The problem.
    impulses : np.ndarray or None
        The answer l; None (or a wrong shape or non-finite entries) is a failure with NaN
        metrics.
    accuracy : float
        The largest residual that counts as a success.

    Returns
    -------
    dict of str to Any
        ``success``, ``residual``, ``v_error``, ``energy_gain``, ``complementarity``,
        ``infeasibility`` and ``energy_identity_gap``.
    """
    nan = math.nan
    if not is_finite(impulses, problem):
        return {
            "success": False, "residual": nan, "v_error": nan, "energy_gain": nan,
            "complementarity": nan, "infeasibility": nan, "energy_identity_gap": nan,
        }
    assert impulses is not None
    reference = problem.reference
    result_residual = residual(problem, impulses)
    return {
        "success": bool(result_residual <= accuracy),
        "residual": result_residual,
        "v_error": (
            v_error(problem, impulses, reference.v_plus)
            if reference is not None and reference.verified else nan
        ),
        "energy_gain": energy_gain(problem, impulses),
        "complementarity": complementarity(problem, impulses),
        "infeasibility": infeasibility(problem, impulses),
        "energy_identity_gap": energy_identity_gap(problem, impulses),
    }
