"""The maps between a frictional problem and Anitescu's relaxation of it
(:meth:`FrictionalProblem.relaxed`, docs/design.md section 8) for a solve: a warm start in,
an output back. ``friction_ccp`` (every ``ccp`` twin) and ``pi_robust`` (its compiled twin)
both use them.

A warm start r = (l_N, l_T) enters as ``z+- = (l_N +- l_T / mu) / 2`` (``l_N / 2`` each where
mu = 0), clipped to z >= 0; an answer z leaves as r = ``problem.from_relaxed(z)``.
"""

from __future__ import annotations

import numpy as np

from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers.base import SolverOutput


def relaxed_start(problem: FrictionalProblem, warm_start: np.ndarray | None
                  ) -> np.ndarray | None:
    """z of the relaxed problem from a warm start r (module docstring), or None.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    warm_start : np.ndarray or None
        r = (l_N, l_T), flattened to shape (2n,).

    Returns
    -------
    np.ndarray or None
        z = (z+, z-), shape (2n,), z >= 0; None when there is no warm start or it has the
        wrong size or a non-finite entry.
    """
    n = problem.n_contacts
    if warm_start is None:
        return None
    warm = np.asarray(warm_start, dtype=float).ravel()
    if warm.shape != (2 * n,) or not np.all(np.isfinite(warm)):
        return None
    normal, tangential = warm[:n], warm[n:]
    mu = problem.mu
    ratio = np.divide(tangential, mu, out=np.zeros(n), where=mu > 0)
    return np.maximum(np.concatenate([normal + ratio, normal - ratio]) / 2.0, 0.0)


def mapped_back(problem: FrictionalProblem, output: SolverOutput) -> SolverOutput:
    """An output on ``problem.relaxed()`` (z) as an output on ``problem``.

    The impulses become r = from_relaxed(z) (none when z has the wrong shape); the claim,
    status, iterations and backend times stay as they are.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts whose relaxation was solved.
    output : SolverOutput
        The solve of ``problem.relaxed()``, impulses z of shape (2n,).

    Returns
    -------
    SolverOutput
        The same solve with impulses r = (l_N, l_T), and ``relaxed_contacts`` (2n) added to
        ``info``.
    """
    z = output.impulses
    impulses = None
    if z is not None and np.shape(z) == (2 * problem.n_contacts,):
        impulses = problem.from_relaxed(np.asarray(z, dtype=float))
    return SolverOutput(impulses=impulses, status=output.status,
                        claimed_success=output.claimed_success,
                        iterations=output.iterations, backend_times=output.backend_times,
                        info={**output.info, "relaxed_contacts": 2 * problem.n_contacts})
