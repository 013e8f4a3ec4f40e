"""References of problems imported from Siconos and FCLIB files (docs/design.md section 5b).

A reduced frictional problem (W, q, mu) has no velocities, so its reference is the impulses
``r`` alone, found one group of coupled contacts at a time: Lemke on the group's scaled
Stewart-Trinkle LCP, polished (``friction_reference.lemke_solution``), for groups of at most
``LEMKE_CONTACTS`` contacts; otherwise (or where Lemke finds nothing) the best, by the Coulomb
residual, of the solvers in ``ITERATIVE`` run at accuracy 1e-12. Its
uniqueness is never proven (``unique`` None), so it is flagged, and only a residual of at most
1e-12 counts as a solution (written to FCLIB's ``/solution``). Global problems and
frictionless ones get the references of every other problem of their kind. It runs solvers,
so it lives in bench.
"""

from __future__ import annotations

import numpy as np

from qpbench.problem import friction_metrics, friction_reference
from qpbench.problem.files import AnyProblem
from qpbench.problem.formulations import pose
from qpbench.problem.friction import FrictionalProblem, FrictionalReference, kind_of
from qpbench.problem.reduced import ReducedFrictionalProblem, reduced_subproblem
from qpbench.problem.reference import attach_reference as attach_impact_reference
from qpbench.solvers.registry import get

LEMKE_CONTACTS = 300
ITERATIVE = ("pi-robust/staggered", "nsgs")
ACCURACY = 1e-12


def _iterative(problem: ReducedFrictionalProblem) -> tuple[np.ndarray, str]:
    """The best answer, by the Coulomb residual, of the ``ITERATIVE`` solvers at 1e-12."""
    n = problem.n_contacts
    best, best_value, method = np.zeros(2 * n), np.inf, "none"
    for name in ITERATIVE:
        spec = get(name, kind_of(problem))
        if not spec.usable or spec.solve is None:
            continue
        copy = problem.blind_copy()
        pose(copy, spec.formulation)
        output = spec.solve(copy, ACCURACY, None)
        if friction_metrics.is_finite(output.impulses, problem):
            value = friction_metrics.residual(problem, output.impulses)
            if value < best_value:
                best, best_value = np.asarray(output.impulses, dtype=float), value
                method = spec.key
        if best_value <= ACCURACY:
            break
    return best, method


def reduced_reference(problem: ReducedFrictionalProblem) -> FrictionalReference:
    """Compute the reference of a reduced problem, one group of coupled contacts at a time.

    The groups are ``friction_reference.components``; each is solved by Lemke where it has at
    most ``LEMKE_CONTACTS`` contacts and Lemke finds a solution to 1e-12, else by the iterative
    solvers (module docstring). Uniqueness is never proven.

    Parameters
    ----------
    problem : ReducedFrictionalProblem
        The reduced frictional problem (W, q, mu).

    Returns
    -------
    FrictionalReference
        The impulses ``r`` (normal then tangential; no velocities), the methods used, the
        Coulomb residual and ``unique`` None.
    """
    n = problem.n_contacts
    if n == 0:
        return FrictionalReference(np.zeros(0), np.zeros(0), "none", 0.0, True)
    impulses, methods = np.zeros(2 * n), set()
    for contacts in friction_reference.components(problem):
        part = reduced_subproblem(problem, contacts)
        found = (friction_reference.lemke_solution(part)
                 if part.n_contacts <= LEMKE_CONTACTS else None)
        method = "lemke"
        if found is None:
            found, method = _iterative(part)
        methods.add(method)
        impulses[contacts] = found[:len(contacts)]
        impulses[n + contacts] = found[len(contacts):]
    method = "+".join(sorted(methods)) + " per component"
    return FrictionalReference(impulses, np.zeros(0), method,
                               friction_metrics.residual(problem, impulses), None)


def attach(problem: AnyProblem) -> AnyProblem:
    """Set the reference of any imported problem and record whether it is verified.

    A reduced problem gets :func:`reduced_reference` and the ``reference_verified``,
    ``reference_unique`` and ``reference_solvable`` metadata; global frictional and impact
    problems get the references of their kind.

    Parameters
    ----------
    problem : ImpactProblem, FrictionalProblem or ReducedFrictionalProblem
        The imported problem, changed in place.

    Returns
    -------
    ImpactProblem, FrictionalProblem or ReducedFrictionalProblem
        ``problem`` itself, with its reference.
    """
    if isinstance(problem, ReducedFrictionalProblem):
        problem.reference = reduced_reference(problem)
        problem.metadata["reference_verified"] = problem.reference.verified
        problem.metadata["reference_unique"] = None
        problem.metadata["reference_solvable"] = True
    elif isinstance(problem, FrictionalProblem):
        friction_reference.attach_reference(problem)
    else:
        attach_impact_reference(problem)
    return problem


def flag(problem: AnyProblem) -> str:
    """Say in a few words why the reference of ``problem`` is not verified.

    Parameters
    ----------
    problem : ImpactProblem, FrictionalProblem or ReducedFrictionalProblem
        A problem with or without a reference.

    Returns
    -------
    str
        ``no reference``, a frictional reference's description, ``references disagree (...)``
        with their agreement, or ``''`` when the reference is verified.
    """
    reference = problem.reference
    if reference is None:
        return "no reference"
    if isinstance(problem, FrictionalProblem):
        return friction_reference.describe(reference)
    return "" if reference.verified else f"references disagree ({reference.agreement:.1e})"
