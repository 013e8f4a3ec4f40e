"""A problem described as Acary, Bremond and Huber describe their benchmark's problems
("On solving contact problems with Coulomb friction: formulations and numerical
comparisons", 2018): contacts, degrees of freedom, contact density, rank deficiency of W,
cond(W) where computable, and mu.

* ``contacts``: n; ``dofs``: the degrees of freedom (None for a reduced problem: W alone);
* ``density``: ``d n / dofs``, the contact unknowns per degree of freedom (``d`` = 2 for a
  frictional problem, 1 for a frictionless one); above 1, W is singular;
* ``rank_deficiency``: ``size(W) - rank(W)``, the rank from W's eigenvalues (a tolerance of
  ``size eps lambda_max``);
* ``cond``: ``lambda_max / lambda_min`` of W (``inf`` when W is singular); both only up to
  ``DENSE_LIMIT`` unknowns (a dense eigenvalue computation), else None;
* ``mu``: the smallest and largest friction coefficient (0 for a frictionless problem).

W is the Delassus matrix ``H^T M^-1 H`` of a frictional problem (the given W of a reduced
one) and ``Q`` of a frictionless one.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import KIND as REDUCED
from qpbench.problem.reduced import ReducedFrictionalProblem

DENSE_LIMIT = 2_500  # unknowns: a dense symmetric eigenvalue problem of at most this size


def describe(problem: ImpactProblem | FrictionalProblem) -> dict[str, Any]:
    """The description of ``problem`` (module docstring), one dict of plain values.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        A frictionless, frictional or reduced frictional problem.

    Returns
    -------
    dict of str to Any
        ``problem``, ``kind`` (``impact``, ``frictional`` or the reduced kind), ``contacts``,
        ``dofs``, ``density``, ``rank_deficiency``, ``cond``, ``mu_min`` and ``mu_max``, as
        the module docstring defines them.
    """
    frictional = isinstance(problem, FrictionalProblem)
    n = problem.n_contacts
    W = problem.W if frictional else problem.Q
    size = W.shape[0]
    if isinstance(problem, ReducedFrictionalProblem):
        dofs, kind = None, REDUCED
    else:
        dofs = int(problem.G.shape[0])
        kind = "frictional" if frictional else "impact"
    unknowns_per_contact = 2 if frictional else 1
    mu = problem.mu if frictional else np.zeros(n)
    rank_deficiency: int | None = None
    cond: float | None = None
    if size == 0:
        rank_deficiency, cond = 0, 1.0
    elif size <= DENSE_LIMIT:
        eigenvalues = np.linalg.eigvalsh(W.toarray())
        largest = float(max(abs(eigenvalues[-1]), abs(eigenvalues[0])))
        tolerance = size * np.finfo(float).eps * largest
        rank_deficiency = int(np.count_nonzero(eigenvalues <= tolerance))
        smallest = float(eigenvalues[0])
        cond = math.inf if smallest <= tolerance else largest / smallest
    return {
        "problem": problem.name,
        "kind": kind,
        "contacts": n,
        "dofs": dofs,
        "density": (unknowns_per_contact * n / dofs) if dofs else None,
        "rank_deficiency": rank_deficiency,
        "cond": cond,
        "mu_min": float(np.min(mu, initial=math.inf)) if n else 0.0,
        "mu_max": float(np.max(mu, initial=0.0)),
    }
