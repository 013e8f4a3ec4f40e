"""One solve, judged: call a solver, never let it crash the caller, measure the answer.

The one timing boundary (docs/design.md section 7) is here, in :func:`call_solver`: every
solver, external or ours, is timed by the same stopwatch around the same call, on a blind
copy of the problem whose formulation was built before the clock started.
"""

from __future__ import annotations

import copy
import math
import traceback
from typing import Any

import numpy as np

from qpbench.problem import friction_metrics, metrics
from qpbench.problem.extended_reference import FLOOR_KEY
from qpbench.problem.formulations import pose
from qpbench.problem.friction import FrictionalProblem, model_of
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import (
    BACKEND_TIMES,
    OWN_TIME,
    ROUND_TRIP_TIME,
    SolverOutput,
    SolverSpec,
    Stopwatch,
)

# the key prefix of the posed blind copies kept on an original problem (``posed_blind_copy``)
TEMPLATE_KEY = "blind copy posed as"
# the verdict on a problem that has no solution (a wedged contact with e > 0): no solver is
# charged for it, and it counts neither as a success nor as a failure
NO_SOLUTION = "no-solution"
# the verdict at an accuracy level below the problem's residual floor (the least residual any
# double vector is known to reach on it, ``reference_residual_floor`` in its metadata): double
# precision cannot decide there, so no solver is charged for it either, and it counts neither as
# a success nor as a failure
BELOW_FLOOR = "below-floor"


def call_solver(spec: SolverSpec, problem: ImpactProblem | FrictionalProblem, accuracy: float,
                warm_start: np.ndarray | None = None) -> SolverOutput:
    """``spec.solve`` on a blind copy of ``problem``, timed, exceptions turned into outputs.

    An exception of the solve becomes an output with status ``error: ...``.

    The solver gets a blind copy (:meth:`ImpactProblem.blind_copy`: fresh arrays; no
    reference, no stored data) with its formulation's matrices already built, made afresh for
    this call by :func:`posed_blind_copy`, and a copy of the warm start. ``time_s`` is the
    wall time from there to l as a NumPy array; for a solver that ``reports_own_time`` (it
    solves in another process), the time it measured across that boundary, with this
    stopwatch's round trip kept as ``info[ROUND_TRIP_TIME]``.
    ``problem`` itself is never handed over, so it stays untouched for judging.

    Parameters
    ----------
    spec : SolverSpec
        A usable pair; its ``prepare`` runs first, outside the clock.
    problem : ImpactProblem or FrictionalProblem
        The problem, of a kind the pair takes.
    accuracy : float
        qpbench's accuracy level passed to the solver.
    warm_start : np.ndarray or None, optional
        A guess of the impulses, copied before it is handed over; None for none.

    Returns
    -------
    SolverOutput
        The solver's output with impulses as a flat float array, ``time_s`` and
        ``formulation_time_s`` set.
    """
    assert spec.solve is not None, f"{spec.key} is not usable: {spec.reason}"
    if spec.prepare is not None:
        spec.prepare()
    blind, posing_s = posed_blind_copy(problem, spec.formulation)
    start = None if warm_start is None else np.array(warm_start, dtype=float)
    output: SolverOutput | None = None
    failure: Exception | None = None
    with Stopwatch() as clock:
        try:
            output = spec.solve(blind, accuracy, start)
            if output.impulses is not None:
                output.impulses = np.asarray(output.impulses, dtype=float).ravel()
        except Exception as error:  # a backend that raises is a failed solve, not a failed run
            failure = error
    if failure is not None or output is None:
        output = SolverOutput(impulses=None, status=_error_status(failure),
                              claimed_success=False)
    output.time_s = clock.elapsed
    own = output.info.get(OWN_TIME)
    if spec.reports_own_time and isinstance(own, float) and 0.0 <= own <= clock.elapsed:
        output.info[ROUND_TRIP_TIME] = clock.elapsed
        output.time_s = own
    output.formulation_time_s = posing_s
    return output


def posed_blind_copy(problem: ImpactProblem | FrictionalProblem, formulation: str
                     ) -> tuple[ImpactProblem | FrictionalProblem, float]:
    """A fresh blind copy of ``problem`` posed in ``formulation``, and the seconds posing took.

    The first request per (problem, formulation) makes a blind copy, poses it (timed: the
    ``formulation_time_s`` of every call) and keeps it on ``problem.posed`` as a template that
    no solver ever sees; each request returns a deep copy of it, so every call still gets
    arrays of its own, written just before the call, as a posing writes them. A repeat so
    costs a copy instead of scipy.sparse's constructions of the formulation, which are many
    times dearer on small problems.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The original problem; only its ``posed`` cache gains the template.
    formulation : str
        The formulation the solver takes (see :func:`qpbench.problem.formulations.pose`).

    Returns
    -------
    blind : ImpactProblem or FrictionalProblem
        The copy to hand to a solver.
    posing_s : float
        Wall seconds the template's posing took.
    """
    key = f"{TEMPLATE_KEY} {formulation}"
    if key not in problem.posed:
        template = problem.blind_copy()
        with Stopwatch() as posing:
            pose(template, formulation)
        problem.posed[key] = (template, posing.elapsed)
    template, posing_s = problem.posed[key]
    return copy.deepcopy(template), posing_s


def _error_status(error: Exception | None) -> str:
    """``error: TYPE: message at FILE:LINE`` (the innermost frame)."""
    if error is None:
        return "error: the solve function returned nothing"
    last = traceback.extract_tb(error.__traceback__)[-1:]
    where = f" at {last[0].filename.rsplit('/', 1)[-1]}:{last[0].lineno}" if last else ""
    return f"error: {type(error).__name__}: {error}{where}"


def residual_floor(problem: ImpactProblem | FrictionalProblem) -> float:
    """The least qpbench residual any double vector is known to reach on ``problem``.

    Read from its metadata (``reference_residual_floor``, recorded by
    ``qpbench.problem.reference.attach_reference`` when the reference was certified in exact
    arithmetic); 0 when none is recorded or the value is not a positive finite number.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem.

    Returns
    -------
    float
        The floor; 0.0 when unknown.
    """
    value = problem.metadata.get(FLOOR_KEY)
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        return 0.0
    floor = float(value)
    return floor if math.isfinite(floor) and floor > 0.0 else 0.0


def judge(spec: SolverSpec, problem: ImpactProblem | FrictionalProblem, output: SolverOutput,
          accuracy: float) -> dict[str, Any]:
    """The result row of one solve: qpbench's metrics and verdict next to the solver's claim.

    ``problem`` must be the untouched original (never the copy the solver was given).

    A frictional problem is judged by the natural map of the model its formulation solves
    (``ccp``: Anitescu's relaxation; every other: Coulomb's law), see
    ``qpbench.problem.friction_metrics``.

    ``status`` is qpbench's verdict (``solved`` / ``inaccurate`` / ``failed``, or
    ``no-solution`` for a problem known to have none, or ``below-floor`` when ``accuracy`` is
    below :func:`residual_floor`); ``solver_status`` is the backend's own; ``status_honest`` is
    whether its claim agreed with ``residual <= accuracy``.

    A ``below-floor`` row keeps every metric of the answer, finite or not, but its ``success``
    is False: no double vector is known to reach that level, and the residual is evaluated in
    double from terms as large as those that set the floor, so one under the level there is
    rounding, not merit. The verdict is undecided, like ``no-solution``; the statistics leave
    the row's (problem, level) out altogether (``qpbench.bench.stats.without_below_floor``),
    and False keeps any count of successes that does not from taking it. The solver's claim
    (``claimed_success``) is kept as it gave it, and ``status_honest`` compares it with the
    measured residual as on any row; the honesty table counts only decided verdicts.

    Parameters
    ----------
    spec : SolverSpec
        The pair that solved.
    problem : ImpactProblem or FrictionalProblem
        The untouched original problem.
    output : SolverOutput
        What :func:`call_solver` gave.
    accuracy : float
        qpbench's accuracy level the verdict is held to.

    Returns
    -------
    dict[str, Any]
        The row: the pair's name, formulation, backend and version, the accuracy, verdict,
        the solver's status and claim, its honesty, the metrics, iteration counts, times and
        backend-reported times (NaN where not reported).
    """
    if isinstance(problem, FrictionalProblem):
        model = model_of(spec.formulation)
        measured = friction_metrics.evaluate(problem, output.impulses, accuracy, model)
        finite = friction_metrics.is_finite(output.impulses, problem)
    else:
        measured = metrics.evaluate(problem, output.impulses, accuracy)
        finite = metrics.is_finite(output.impulses, problem)
    if not measured.pop("solvable", True):
        status = NO_SOLUTION
    elif accuracy < residual_floor(problem):
        status = BELOW_FLOOR
    elif measured["success"]:
        status = "solved"
    elif finite:
        status = "inaccurate"
    else:
        status = "failed"
    honest = bool(output.claimed_success == measured["success"])
    if status == BELOW_FLOOR:
        measured["success"] = False
    outer = output.info.get("outer_iterations")
    return {
        "solver": spec.name,
        "formulation": spec.formulation,
        "backend": spec.backend,
        "solver_version": spec.version,
        "accuracy": accuracy,
        "status": status,
        "solver_status": output.status,
        "claimed_success": output.claimed_success,
        "status_honest": honest,
        **measured,
        "iterations": output.iterations,
        "outer_iterations": int(outer) if isinstance(outer, int | np.integer) else None,
        "time_s": output.time_s,
        "formulation_time_s": output.formulation_time_s,
        **{column: output.backend_times.get(column, math.nan) for column in BACKEND_TIMES},
    }


def solve_and_judge(spec: SolverSpec, problem: ImpactProblem | FrictionalProblem,
                    accuracy: float,
                    warm_start: np.ndarray | None = None) -> tuple[dict[str, Any], SolverOutput]:
    """call_solver then judge.

    Parameters
    ----------
    spec : SolverSpec
        A usable pair.
    problem : ImpactProblem or FrictionalProblem
        The problem; the solver gets a blind copy, the verdict uses the original.
    accuracy : float
        qpbench's accuracy level.
    warm_start : np.ndarray or None, optional
        A guess of the impulses; None for none.

    Returns
    -------
    row : dict[str, Any]
        The result row of :func:`judge`.
    output : SolverOutput
        The solver's output of :func:`call_solver`.
    """
    output = call_solver(spec, problem, accuracy, warm_start)
    return judge(spec, problem, output, accuracy), output
