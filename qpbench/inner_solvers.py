"""The simulator's inner solves, built from solver names through the registry.

This is the one place where the simulator (which knows no solver by name) meets the
solvers: :func:`choose_by_name` gives the ``choose_solve`` a
:class:`~qpbench.simulation.stepper.Simulator` takes. With a name (``--solver``) every
lcp/gr operator uses that solver; without one each uses the qpbench solver its scene's
SCISim solver maps to (:mod:`qpbench.scenes.solver_names`), or :data:`FALLBACK` when that
one is not registered or not usable here, with a note saying so.

A frictional scene (a friction solver with mu > 0) gets one solver for its whole frictional
problems: ``--solver`` when given (it must take frictional problems), else
:data:`SOBOGUS` for ``<sobogus_friction_solver>`` (So-bogus is a nonsmooth Gauss-Seidel) and,
for ``<staggered_projections_friction_solver>``, ``X/staggered`` with X the qpbench solver
its ``<lcp_impact_solver>`` maps to (as ``<solver>`` maps), or :data:`SOBOGUS` with a note
when that one cannot run here.
"""

from __future__ import annotations

import numpy as np

from qpbench.errors import QpbenchError
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes.model import FrictionSolver, ImpactOperator
from qpbench.scenes.solver_names import FALLBACK
from qpbench.simulation.operators import ChooseSolve, ChosenSolve, ImpactSolve, SolvedImpulses
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver


def solve_with(spec: SolverSpec) -> ImpactSolve:
    """An inner solve by ``spec`` through :func:`call_solver`.

    Calling through :func:`call_solver` makes a raising backend a failed answer; the warm start
    reaches only a solver that takes one.

    Parameters
    ----------
    spec : SolverSpec
        The registered solver and formulation to call.

    Returns
    -------
    ImpactSolve
        A function of (problem, accuracy, warm start or None) giving the
        :class:`SolvedImpulses`: impulses, whole solve time in seconds and status.
    """

    def solve(problem: ImpactProblem | FrictionalProblem, accuracy: float,
              warm_start: np.ndarray | None) -> SolvedImpulses:
        output = call_solver(spec, problem, accuracy, warm_start if spec.warm_start else None)
        # time_s is the whole solve; a SolverOutput from before it existed split it in two
        seconds = (output.time_s if hasattr(output, "time_s")
                   else output.solve_time_s + output.setup_time_s)
        return SolvedImpulses(impulses=output.impulses, time_s=seconds, status=output.status)

    return solve


def chosen(spec: SolverSpec, note: str | None = None) -> ChosenSolve:
    """``spec`` as the inner solve of an operator, named ``NAME/FORMULATION``.

    Parameters
    ----------
    spec : SolverSpec
        The solver to use.
    note : str or None, optional
        Why this solver stands in for the scene's own, shown to the user; None when it is the
        one asked for.

    Returns
    -------
    ChosenSolve
        The name ``spec.key``, the solve of :func:`solve_with` and the note.
    """
    return ChosenSolve(name=spec.key, solve=solve_with(spec), note=note)


SOBOGUS = "nsgs/nsgs"
FRICTIONAL = "frictional"


def choose_frictional(solver: FrictionSolver, override: str | None) -> ChosenSolve:
    """The inner solve of a frictional scene (see the module docstring).

    Parameters
    ----------
    solver : FrictionSolver
        The scene's friction solver element: So-bogus or staggered projections (with its
        ``<lcp_impact_solver>``).
    override : str or None
        The ``--solver`` name (``NAME[/FORMULATION]``), which must take frictional problems;
        None to map the scene's own solver.

    Returns
    -------
    ChosenSolve
        The solver for the scene's frictional problems, with a note when :data:`SOBOGUS`
        replaces a staggered solver that cannot run here.

    Raises
    ------
    QpbenchError
        When ``override`` is unknown or cannot take frictional problems.
    """
    if override is not None:
        return chosen(get(override, FRICTIONAL))
    if solver.kind == "sobogus":
        return chosen(get(SOBOGUS, FRICTIONAL))
    assert solver.impact_solver is not None
    inner = f"{solver.impact_solver.qpbench_name}/staggered"
    try:
        return chosen(get(inner, FRICTIONAL))
    except QpbenchError as error:
        spec = get(SOBOGUS, FRICTIONAL)
        return chosen(spec, f"<{solver.declared_by}> with <lcp_impact_solver "
                            f"name='{solver.impact_solver.scisim_name}'> maps to '{inner}', "
                            f"{error}; using {spec.key} instead")


def choose_by_name(override: str | None = None) -> ChooseSolve:
    """The inner solve of each operator.

    ``override`` (``NAME[/FORMULATION]``) everywhere when given, else the scene's own solver,
    mapped, with :data:`FALLBACK` when it cannot run here.

    An unknown or unusable ``override`` raises QpbenchError (one line) when first used.

    Parameters
    ----------
    override : str or None, optional
        The ``--solver`` name; None (the default) to map each operator's own solver.

    Returns
    -------
    ChooseSolve
        A function giving the :class:`ChosenSolve` of an :class:`ImpactOperator` or a
        :class:`FrictionSolver`.
    """

    def choose_solve(operator: ImpactOperator | FrictionSolver) -> ChosenSolve:
        if isinstance(operator, FrictionSolver):
            return choose_frictional(operator, override)
        if override is not None:
            return chosen(get(override))
        if operator.solver is None:  # a friction solver with mu = 0: no solver child
            spec = get(FALLBACK)
            return chosen(spec, f"<{operator.declared_by}> with mu = 0: frictionless lcp "
                                f"solved by {spec.key}")
        try:
            return chosen(get(operator.solver.qpbench_name))
        except QpbenchError as error:
            spec = get(FALLBACK)
            return chosen(spec, f"SCISim solver '{operator.solver.scisim_name}' maps to "
                                f"'{operator.solver.qpbench_name}', {error}; using "
                                f"{spec.key} instead")

    return choose_solve
