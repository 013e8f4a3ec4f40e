"""Metrics of a frictional answer r = (l_N, l_T), computed from the impulses alone
(docs/design.md section 8).

Per contact k, with ``u = W r + q``, the De Saxce velocity
``u^_k = (u_N + mu |u_T|, u_T)`` (``coulomb``) or ``u^_k = u_k`` (``ccp``, Anitescu's
relaxation, in which sliding contacts separate), ``d_k = diag(W_NN)_k`` and the cone
``K = {|x_T| <= mu x_N}``, the natural map is

    F_k = d_k r_k - P_K(d_k r_k - u^_k)

and it is zero exactly at the solutions of that model. ``residual = ||F||_inf / scale`` with
the problem's ``scale`` (``max(||q_N||_inf, ||q_T||_inf on contacts with mu > 0, tiny)``).
At mu = 0, ``P_K(x) = (max(x_N, 0), 0)``, so ``F = (min(d l_N, u_N), d l_T)``: with l_T = 0
this is the frictionless residual of section 2, to the last bit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from qpbench.problem.friction import MODELS, FrictionalProblem
from qpbench.problem.metrics import TINY, dot


def project_on_cone(normal: np.ndarray, tangential: np.ndarray, mu: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """P_K(x) per contact, K = {|x_T| <= mu x_N}.

    x inside K; 0 where ``mu |x_T| <= -x_N`` (in the polar cone); otherwise the projection on
    the nearer edge, ``(x_N + mu |x_T|) / (1 + mu^2) * (1, mu sign x_T)``.

    Parameters
    ----------
    normal, tangential : np.ndarray
        x_N and x_T, shape (n,) each.
    mu : np.ndarray
        Friction coefficients, shape (n,).

    Returns
    -------
    projected_normal, projected_tangential : np.ndarray
        The normal and tangential parts of P_K(x), shape (n,) each.
    """
    magnitude = np.abs(tangential)
    inside = magnitude <= mu * normal
    polar = mu * magnitude <= -normal
    edge = (normal + mu * magnitude) / (1.0 + mu * mu)
    projected_normal = np.where(inside, normal, np.where(polar, 0.0, edge))
    projected_tangential = np.where(inside, tangential,
                                    np.where(polar, 0.0, edge * mu * np.sign(tangential)))
    return projected_normal, projected_tangential


def natural_map(problem: FrictionalProblem, impulses: np.ndarray, model: str = "coulomb"
                ) -> tuple[np.ndarray, np.ndarray]:
    """(F_N, F_T) of the scaled natural map (module docstring) for ``model``.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).
    model : str, optional
        ``coulomb`` (the default, De Saxce's u^) or ``ccp`` (u^ = u).

    Returns
    -------
    F_N, F_T : np.ndarray
        The normal and tangential parts of F, shape (n,) each.

    Raises
    ------
    ValueError
        When ``model`` is not one of :data:`MODELS`.
    """
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r} (known: {', '.join(MODELS)})")
    normal, tangential = problem.split(impulses)
    u_normal, u_tangential = problem.split(problem.u(impulses))
    if model == "coulomb":
        u_normal = u_normal + problem.mu * np.abs(u_tangential)
    d = problem.diag_N
    projected_normal, projected_tangential = project_on_cone(
        d * normal - u_normal, d * tangential - u_tangential, problem.mu)
    return d * normal - projected_normal, d * tangential - projected_tangential


def residual(problem: FrictionalProblem, impulses: np.ndarray, model: str = "coulomb") -> float:
    """||F||_inf / scale for ``model`` (module docstring).

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).
    model : str, optional
        ``coulomb`` (the default) or ``ccp``.

    Returns
    -------
    float
        The scaled residual; 0 for a problem without contacts.
    """
    if problem.n_contacts == 0:
        return 0.0
    F_normal, F_tangential = natural_map(problem, impulses, model)
    worst = max(float(np.max(np.abs(F_normal))), float(np.max(np.abs(F_tangential))))
    return worst / problem.scale


def infeasibility(problem: FrictionalProblem, impulses: np.ndarray) -> float:
    """max(0, -min(d l_N), max(d (|l_T| - mu l_N)), -min(u_N)) / scale.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).

    Returns
    -------
    float
        The scaled violation of l_N >= 0, the friction cone and u_N >= 0; 0 for a problem
        without contacts.
    """
    if problem.n_contacts == 0:
        return 0.0
    normal, tangential = problem.split(impulses)
    u_normal = problem.split(problem.u(impulses))[0]
    d = problem.diag_N
    worst = max(0.0, -float(np.min(d * normal)),
                float(np.max(d * (np.abs(tangential) - problem.mu * normal))),
                -float(np.min(u_normal)))
    return worst / problem.scale


def complementarity(problem: FrictionalProblem, impulses: np.ndarray) -> float:
    """|d r^T u^| / scale^2 with the De Saxce u^.

    That is the normal complementarity plus the dissipation gap ``mu l_N |u_T| + l_T u_T``
    (zero when sliding opposes the slip).

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).

    Returns
    -------
    float
        The scaled complementarity gap.
    """
    normal, tangential = problem.split(impulses)
    u_normal, u_tangential = problem.split(problem.u(impulses))
    d = problem.diag_N
    gap = d * normal * (u_normal + problem.mu * np.abs(u_tangential)) \
        + d * tangential * u_tangential
    return abs(float(np.sum(gap))) / problem.scale ** 2


def v_error(problem: FrictionalProblem, impulses: np.ndarray, v_plus_ref: np.ndarray) -> float:
    """||v+(r) - v+_ref||_M / ||v-||_M.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).
    v_plus_ref : np.ndarray
        The reference post-impact velocity, shape (d,).

    Returns
    -------
    float
        The relative error of v+ in the mass norm (||v-||_M replaced by tiny when zero).
    """
    difference = problem.m_norm(problem.v_plus(impulses) - v_plus_ref)
    return difference / max(problem.m_norm(problem.v_minus), TINY)


def energy_gain(problem: FrictionalProblem, impulses: np.ndarray) -> float:
    """(KE+ - KE-) / KE-, signed.

    With mu > 0 and e > 0 Newton's law may add energy when slip reverses, so it is a
    diagnostic there, not a verdict. NaN for a problem without degrees of freedom (a reduced
    one: W, q, mu only), whose energy is not known.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).

    Returns
    -------
    float
        The relative change of kinetic energy, or NaN.
    """
    if problem.v_minus.size == 0:
        return math.nan
    before = problem.kinetic_energy(problem.v_minus)
    after = problem.kinetic_energy(problem.v_plus(impulses))
    return (after - before) / max(before, TINY)


def is_finite(impulses: np.ndarray | None, problem: FrictionalProblem) -> bool:
    """r exists, has 2n entries and all are finite.

    Parameters
    ----------
    impulses : np.ndarray or None
        The answer r; None when the solver gave none.
    problem : FrictionalProblem
        The problem it answers.

    Returns
    -------
    bool
        Whether r has shape (2n,) and only finite entries.
    """
    return (impulses is not None and np.shape(impulses) == (2 * problem.n_contacts,)
            and bool(np.all(np.isfinite(impulses))))


def evaluate(problem: FrictionalProblem, impulses: np.ndarray | None, accuracy: float,
             model: str = "coulomb") -> dict[str, Any]:
    """Every metric of an answer and qpbench's verdict.

    The verdict is finite r and the residual of ``model`` (the one the formulation solves)
    <= accuracy. ``coulomb_residual`` is always the exact law's; for a ``ccp`` answer it is
    the model error, never the verdict. ``v_error`` only where the reference is verified and
    unique. A problem with no solution is marked (``solvable`` False) and no answer to it
    counts as a success or a failure.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray or None
        The answer r; None (or a wrong shape or non-finite entries) is a failure with NaN
        metrics.
    accuracy : float
        The largest residual that counts as a success.
    model : str, optional
        The law the formulation solves: ``coulomb`` (the default) or ``ccp``.

    Returns
    -------
    dict of str to Any
        ``success``, ``residual``, ``coulomb_residual``, ``model_error``, ``v_error``,
        ``energy_gain``, ``complementarity``, ``infeasibility``, ``energy_identity_gap``
        (NaN), ``model``, ``solvable`` and ``mu_max``.
    """
    nan = math.nan
    reference = problem.reference
    solvable = reference is None or reference.solvable
    if not is_finite(impulses, problem):
        return {"success": False, "residual": nan, "coulomb_residual": nan,
                "model_error": nan, "v_error": nan, "energy_gain": nan,
                "complementarity": nan, "infeasibility": nan, "energy_identity_gap": nan,
                "model": model, "solvable": solvable, "mu_max": problem.mu_max}
    assert impulses is not None
    own = residual(problem, impulses, model)
    coulomb = own if model == "coulomb" else residual(problem, impulses, "coulomb")
    return {
        "success": bool(own <= accuracy),
        "residual": own,
        "coulomb_residual": coulomb,
        "model_error": coulomb if model != "coulomb" else nan,
        "v_error": (v_error(problem, impulses, reference.v_plus)
                    if reference is not None and reference.verified and model == "coulomb"
                    else nan),
        "energy_gain": energy_gain(problem, impulses),
        "complementarity": complementarity(problem, impulses),
        "infeasibility": infeasibility(problem, impulses),
        "energy_identity_gap": nan,
        "model": model,
        "solvable": solvable,
        "mu_max": problem.mu_max,
    }


def fclib_merit(problem: FrictionalProblem, impulses: np.ndarray) -> float:
    """FCLIB's MERIT_1 for 2D: ``||F||_2 / (1 + ||q||_2)``.

    F is the unscaled natural map ``F_k = r_k - P_K(r_k - u^_k)`` (De Saxce's ``u^``, no
    ``d_k`` weights), over all contacts. (FCLIB's own 3D code divides by
    ``1 + sqrt(||q||_2)``; this is the documented form.)

    Parameters
    ----------
    problem : FrictionalProblem
        The problem.
    impulses : np.ndarray
        r = (l_N, l_T), shape (2n,).

    Returns
    -------
    float
        The merit.
    """
    normal, tangential = problem.split(impulses)
    u_normal, u_tangential = problem.split(problem.u(impulses))
    u_normal = u_normal + problem.mu * np.abs(u_tangential)
    projected_normal, projected_tangential = project_on_cone(
        normal - u_normal, tangential - u_tangential, problem.mu)
    F = np.concatenate([normal - projected_normal, tangential - projected_tangential])
    # 2-norms from fixed-order inner products (np.linalg.norm of a vector is a BLAS dot)
    return float(np.sqrt(dot(F, F))) / (1.0 + float(np.sqrt(dot(problem.q, problem.q))))
