"""Impact operators: from an impact problem to the impulses l (so that v+ = v- + M^-1 G l).

* ``lcp``: one LCP ``l >= 0, w = Q l + b >= 0, l^T w = 0`` over every contact,
  ``b = (1 + c)(G^T v- + nrel)``, solved by the inner solver.
* ``gr`` (generalized reflections): while some contact approaches,
  ``G_k^T v + nrel_k < -v_tol``, solve the LCP restricted to those contacts at the
  current velocity with restitution c and add its impulses.
* ``grr``: ``l = (1 - c) l_inelastic + c l_elastic``, the inelastic operator run
  with c = 0 and the elastic one with c = 1.
* ``gauss_seidel``: pairwise sweeps; each approaching contact k in turn gets
  ``dl = -(1 + c_k) u_k / Q_kk`` (``u_k = G_k^T v + nrel_k``) until none approaches.

Every inner LCP is solved by an :data:`ImpactSolve` the caller hands in (the simulator
knows no solver registry; :mod:`qpbench.inner_solvers` builds one from a solver name), and
every answer is judged with qpbench's own residual (``qpbench.problem.metrics``): above
the accuracy asked it counts as inaccurate; not finite, or above :data:`REJECT_RESIDUAL`,
it is a failure that stops the run (:class:`InnerSolveFailed`), never used silently.

A frictional impact (a scene's friction solver with mu > 0) is one
:class:`~qpbench.problem.friction.FrictionalProblem`, solved whole by its inner solver and
judged the same way with the Coulomb natural-map residual
(``qpbench.problem.friction_metrics``); its impulses are ``r = (l_N, l_T)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from qpbench.problem import friction_metrics, metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes.model import FrictionSolver, ImpactOperator

REJECT_RESIDUAL = 1e-3
MAX_GR_ROUNDS = 1000
MAX_GAUSS_SEIDEL_SWEEPS = 10_000


@dataclass(frozen=True)
class SolvedImpulses:
    """One inner solve as the solver gave it, before qpbench judges it."""

    impulses: np.ndarray | None  # l in the problem's contact order; None when there is none
    time_s: float  # wall seconds of the whole solve (NaN when unknown)
    status: str  # the solver's own word, reported when the answer is rejected


ImpactSolve = Callable[[ImpactProblem | FrictionalProblem, float, np.ndarray | None],
                       SolvedImpulses]
"""``solve(problem, accuracy, warm_start)``: the impulses of the LCP of ``problem`` at the
residual ``accuracy`` (``r = (l_N, l_T)`` of a frictional problem); ``warm_start`` is a
guess of them (or None), which it may ignore."""


@dataclass(frozen=True)
class ChosenSolve:
    """The inner solve of one operator, the name the logs give it, and a note on the choice
    (a fallback from the scene's own solver), if any."""

    name: str
    solve: ImpactSolve
    note: str | None = None


ChooseSolve = Callable[[ImpactOperator | FrictionSolver], ChosenSolve]
"""The inner solve of each lcp/gr operator of a scene (nested in a grr too), or of its
friction solver when mu > 0."""


class InnerSolveFailed(Exception):
    """The inner solver gave no usable answer; ``detail`` says which solve and why."""

    def __init__(self, detail: dict[str, Any]) -> None:
        self.detail = detail
        super().__init__(detail.get("reason", "inner solve failed"))


@dataclass
class SolveLog:
    """Counts over a run: solves, trivial ones (b >= 0, so l = 0 exactly), inaccurate ones."""

    solves: int = 0
    trivial: int = 0
    inaccurate: int = 0
    max_residual: float = 0.0
    solve_time_s: float = 0.0
    gr_max_rounds: int = 0
    unconverged: int = 0
    solvers: set[str] = field(default_factory=set)

    def as_dict(self) -> dict[str, Any]:
        """The counts under the names a simulation's summary gives them.

        Returns
        -------
        dict
            ``solves``, ``trivial_solves``, ``inaccurate_solves``, ``max_residual``,
            ``solve_time_s``, ``gr_max_rounds``, ``unconverged_events`` and the sorted ``solvers``.
        """
        return {
            "solves": self.solves, "trivial_solves": self.trivial,
            "inaccurate_solves": self.inaccurate, "max_residual": self.max_residual,
            "solve_time_s": self.solve_time_s, "gr_max_rounds": self.gr_max_rounds,
            "unconverged_events": self.unconverged, "solvers": sorted(self.solvers),
        }


@dataclass
class InnerSolver:
    """The inner solve of one operator, its answers judged by qpbench."""

    chosen: ChosenSolve
    accuracy: float
    log: SolveLog

    def solve(self, problem: ImpactProblem | FrictionalProblem,
              warm_start: np.ndarray | None = None) -> np.ndarray:
        """Impulses of the LCP of ``problem`` (``r = (l_N, l_T)`` of a frictional one).

        A problem where nothing approaches (b >= 0) gives l = 0 without a solve. Otherwise the
        velocities are scaled by :func:`unit_scale`, the chosen solve runs at ``accuracy``, and the
        answer is judged by qpbench's residual and logged.

        Parameters
        ----------
        problem : ImpactProblem or FrictionalProblem
            The impact to solve.
        warm_start : np.ndarray or None, optional
            A guess of the impulses, in the problem's units; None (default) for a cold start.

        Returns
        -------
        np.ndarray
            The impulses, (n_contacts,) or (2 n_contacts,) for a frictional problem.

        Raises
        ------
        InnerSolveFailed
            When the answer is not finite or its residual is above REJECT_RESIDUAL.
        """
        frictional = isinstance(problem, FrictionalProblem)
        size = 2 * problem.n_contacts if frictional else problem.n_contacts
        if problem.n_contacts == 0:
            return np.zeros(0)
        b = problem.normal.b if frictional else problem.b
        if np.all(b >= 0):  # nothing approaches: l = 0 (r = 0) solves the problem exactly
            self.log.trivial += 1
            return np.zeros(size)
        measure = friction_metrics if frictional else metrics
        velocity_unit = problem.scale if frictional else metrics.scale(problem)
        factor = unit_scale(velocity_unit, problem.largest_velocity)
        answer = self.chosen.solve(problem.with_velocities_scaled(factor), self.accuracy,
                                   None if warm_start is None else factor * warm_start)
        self.log.solves += 1
        self.log.solvers.add(self.chosen.name)
        if math.isfinite(answer.time_s):
            self.log.solve_time_s += answer.time_s
        impulses = (None if answer.impulses is None
                    else np.asarray(answer.impulses, dtype=float) / factor)
        finite = measure.is_finite(impulses, problem)
        residual = measure.residual(problem, impulses) if finite else math.nan
        if finite:
            self.log.max_residual = max(self.log.max_residual, residual)
        if not finite or not residual <= REJECT_RESIDUAL:
            raise InnerSolveFailed({
                "solver": self.chosen.name, "solver_status": answer.status,
                "contacts": problem.n_contacts, "residual": residual,
                "reason": ("no finite answer" if not finite else
                           f"residual {residual:.3g} > {REJECT_RESIDUAL:g}"),
            })
        if residual > self.accuracy:
            self.log.inaccurate += 1
        assert impulses is not None
        return impulses


def unit_scale(velocity_unit: float, largest_velocity: float) -> float:
    """The power of two that brings an inner solve's velocities to unit scale.

    The factor f = 2^-e, ``velocity_unit`` = m 2^e with m in [1/2, 1), that brings the
    velocities of an inner solve (and so b and the impulses) to unit scale: the scaled problem's
    unit (max |b|, the scale of qpbench's residual) lies in [1/2, 1). A power of two, so that
    scaling and unscaling are exact. Solvers with absolute tolerances (the interior points)
    otherwise fail on slow contacts: at approach speeds of 1e-9 their answers miss qpbench's
    relative residual by orders of magnitude. f = 1 when the scaled velocities would leave
    floating-point range (a unit tiny by cancellation beside large velocities).

    Parameters
    ----------
    velocity_unit : float
        The problem's velocity unit (its residual's scale).
    largest_velocity : float
        The largest velocity magnitude of the problem.

    Returns
    -------
    float
        The factor f.
    """
    factor = 2.0 ** -math.frexp(velocity_unit)[1]
    return factor if factor * largest_velocity <= 1e300 else 1.0


def with_restitution(problem: ImpactProblem, restitution: float) -> ImpactProblem:
    """The same contacts and velocities with one restitution c for every contact.

    Parameters
    ----------
    problem : ImpactProblem
        The impact.
    restitution : float
        The coefficient c given to every contact.

    Returns
    -------
    ImpactProblem
        A new problem, built again with that restitution.
    """
    return ImpactProblem.build(problem.name, problem.G, problem.m_inv, problem.v_minus,
                               restitution, problem.n_rel, dofs_per_body=problem.dofs_per_body)


def apply(operator: ImpactOperator, problem: ImpactProblem,
          inner: dict[int, InnerSolver], log: SolveLog,
          warm_start: np.ndarray | None = None) -> np.ndarray:
    """The impulses ``operator`` gives for ``problem`` (whose restitution is the operator's).

    ``inner`` maps ``id(operator)`` to the inner solver of each lcp/gr operator.

    Parameters
    ----------
    operator : ImpactOperator
        The scene's impact operator: ``lcp``, ``gr``, ``grr`` or ``gauss_seidel``.
    problem : ImpactProblem
        The impact.
    inner : dict of int to InnerSolver
        The inner solver of each lcp/gr operator, nested ones included, by ``id``.
    log : SolveLog
        The run's counts, updated.
    warm_start : np.ndarray or None, optional
        A guess of the impulses for an ``lcp`` operator; None (default) for a cold start.

    Returns
    -------
    np.ndarray
        (n_contacts,) impulses l.

    Raises
    ------
    InnerSolveFailed
        When an inner solve gives no usable answer.
    ValueError
        For an unknown operator type.
    """
    if problem.n_contacts == 0:
        return np.zeros(0)
    if operator.type == "lcp":
        return inner[id(operator)].solve(problem, warm_start)
    if operator.type == "gr":
        return generalized_reflections(problem, operator.v_tol, inner[id(operator)], log)
    if operator.type == "grr":
        assert operator.elastic is not None and operator.inelastic is not None
        c = operator.restitution
        elastic = apply(operator.elastic, with_restitution(problem, 1.0), inner, log)
        inelastic = apply(operator.inelastic, with_restitution(problem, 0.0), inner, log)
        return (1.0 - c) * inelastic + c * elastic
    if operator.type == "gauss_seidel":
        return gauss_seidel(problem, operator.v_tol, log)
    raise ValueError(f"unknown impact operator {operator.type!r}")


def generalized_reflections(problem: ImpactProblem, v_tol: float, inner: InnerSolver,
                            log: SolveLog, max_rounds: int = MAX_GR_ROUNDS) -> np.ndarray:
    """Accumulated impulses of repeated LCPs over the contacts still approaching (see above).

    Each round solves the LCP restricted to the contacts with ``G_k^T v + nrel_k < -v_tol`` at
    the current velocity, adds its impulses, and recomputes the velocity from v- and the total.

    Parameters
    ----------
    problem : ImpactProblem
        The impact.
    v_tol : float
        The approach speed below which a contact counts as approaching.
    inner : InnerSolver
        The inner solver of each round's LCP.
    log : SolveLog
        The run's counts: the most rounds, and an unconverged event when the rounds run out.
    max_rounds : int, optional
        The rounds at most; MAX_GR_ROUNDS by default.

    Returns
    -------
    np.ndarray
        (n_contacts,) accumulated impulses.

    Raises
    ------
    InnerSolveFailed
        When an inner solve gives no usable answer.
    """
    velocity = problem.v_minus.copy()
    total = np.zeros(problem.n_contacts)
    G = problem.G
    for rounds in range(max_rounds + 1):
        approach = G.T @ velocity + problem.n_rel
        active = np.flatnonzero(approach < -v_tol)
        if active.size == 0:
            log.gr_max_rounds = max(log.gr_max_rounds, rounds)
            return total
        if rounds == max_rounds:
            break
        sub = ImpactProblem.build(problem.name, G[:, active], problem.m_inv, velocity,
                                  problem.restitution[active], problem.n_rel[active],
                                  dofs_per_body=problem.dofs_per_body)
        total[active] += inner.solve(sub)
        velocity = problem.v_plus(total)  # from v- each round, so increments do not drift
    log.gr_max_rounds = max(log.gr_max_rounds, max_rounds)
    log.unconverged += 1
    return total


def gauss_seidel(problem: ImpactProblem, v_tol: float, log: SolveLog,
                 max_sweeps: int = MAX_GAUSS_SEIDEL_SWEEPS) -> np.ndarray:
    """Pairwise sweeps over the contacts in order (see the module docstring).

    Parameters
    ----------
    problem : ImpactProblem
        The impact; its G is read column by column (CSC).
    v_tol : float
        The approach speed below which a contact counts as approaching.
    log : SolveLog
        The run's counts: an unconverged event when the sweeps run out.
    max_sweeps : int, optional
        The sweeps at most; MAX_GAUSS_SEIDEL_SWEEPS by default.

    Returns
    -------
    np.ndarray
        (n_contacts,) accumulated impulses.
    """
    G = problem.G
    velocity = problem.v_minus.copy()
    impulses = np.zeros(problem.n_contacts)
    columns = [(G.indices[G.indptr[k]:G.indptr[k + 1]], G.data[G.indptr[k]:G.indptr[k + 1]])
               for k in range(problem.n_contacts)]
    for _ in range(max_sweeps):
        changed = False
        for k, (rows, values) in enumerate(columns):
            approach = float(values @ velocity[rows]) + problem.n_rel[k]
            if approach >= -v_tol:
                continue
            weighted = problem.m_inv[rows] * values
            q_kk = float(values @ weighted)
            if q_kk <= 0.0:
                continue
            step = -(1.0 + problem.restitution[k]) * approach / q_kk
            velocity[rows] += weighted * step
            impulses[k] += step
            changed = True
        if not changed:
            return impulses
    log.unconverged += 1
    return impulses
