"""The stepper: SCISim's geometric splitting, with only the effects a scene declares.

One step from (x0, v0) with step h:

1. predict ``(x1, v1) = flow(x0, v0)`` with the scene's integrator (gravity only
   if the scene declares it);
2. find the contacts (ball-ball over the step, planes and drums at x1), only if
   the scene has an impact operator and only the kinds of boundary it has;
3. if there are any, pose the impact problem on the start-of-step velocity v0
   (one :class:`~qpbench.problem.impact.ImpactProblem`; written to the capture folder
   when some contact approaches, ``b < 0``, since otherwise l = 0 exactly),
   let the impact operator find l, and re-integrate from x0 with
   ``v0 + M^-1 G l``.

The inner solves come from a :data:`~qpbench.simulation.operators.ChooseSolve` the caller
hands in; the simulator knows no solver by name.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from qpbench.errors import QpbenchError, UnsupportedError
from qpbench.problem import files, metrics
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes.model import ImpactOperator, Scene
from qpbench.simulation import checks, contacts, integrators
from qpbench.simulation.operators import (
    ChooseSolve,
    InnerSolveFailed,
    InnerSolver,
    SolveLog,
    apply,
)

DEFAULT_ACCURACY = 1e-8


@dataclass
class StepEvent:
    """What one step did: its contacts at the start positions and the impulses they took."""

    step: int
    time: float
    positions: np.ndarray  # start-of-step positions (bodies, 2)
    contacts: contacts.Contacts
    impulses: np.ndarray
    problem: ImpactProblem | None = None


@dataclass
class SimulationResult:
    """The summary ``qpbench simulate`` prints (docs/design.md section 6) and a few more facts.

    ``impacts`` counts the steps where some contact approaches (``b < 0``; the others have
    l = 0 exactly); ``max_contacts`` the most contacts found in one step;
    ``max_energy_gain`` the largest ``(KE+ - KE-) / KE-`` of one impact; ``momentum_drift``
    is None unless only balls meet (no boundary, no kinematic body).
    """

    scene: str
    steps: int = 0
    time: float = 0.0
    impacts: int = 0
    max_contacts: int = 0
    energy_initial: float = 0.0
    energy_final: float = 0.0
    max_energy_gain: float | None = None
    momentum_drift: float | None = None
    wall_s: float = 0.0
    captured: int = 0
    x_final: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    v_final: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    operator: str | None = None
    solver: str | None = None
    failure: dict[str, Any] | None = None
    log: SolveLog = field(default_factory=SolveLog)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {
            "scene": self.scene, "steps": self.steps, "time": self.time,
            "impacts": self.impacts, "max_contacts": self.max_contacts,
            "energy_initial": self.energy_initial, "energy_final": self.energy_final,
            "max_energy_gain": self.max_energy_gain, "momentum_drift": self.momentum_drift,
            "wall_s": self.wall_s, "captured": self.captured,
            "x_final": self.x_final, "v_final": self.v_final,
            "operator": self.operator, "solver": self.solver,
            "success": self.failure is None, "failure": self.failure,
            **self.log.as_dict(),
        }


def solver_operators(operator: ImpactOperator | None) -> list[ImpactOperator]:
    """The lcp/gr operators (nested in a grr too) that need an inner solver."""
    if operator is None:
        return []
    if operator.type == "grr":
        return [op for sub in (operator.elastic, operator.inelastic)
                for op in solver_operators(sub)]
    return [operator] if operator.type in ("lcp", "gr") else []


def choose_solvers(operator: ImpactOperator | None, choose_solve: ChooseSolve | None,
                   accuracy: float, log: SolveLog) -> tuple[dict[int, InnerSolver], list[str]]:
    """The inner solver of each operator that needs one (keyed by ``id(operator)``), and the
    notes of the choice; ValueError when some operator needs one and ``choose_solve`` is None."""
    inner: dict[int, InnerSolver] = {}
    notes: list[str] = []
    for op in solver_operators(operator):
        if choose_solve is None:
            raise ValueError(f"the <{op.declared_by}> operator needs an inner solver: "
                             "give the Simulator a choose_solve")
        chosen = choose_solve(op)
        if chosen.note is not None:
            notes.append(chosen.note)
        inner[id(op)] = InnerSolver(chosen=chosen, accuracy=accuracy, log=log)
    return inner, sorted(set(notes))


class Simulator:
    """Steps a scene; every impact event becomes an ImpactProblem (optionally captured)."""

    def __init__(self, scene: Scene, choose_solve: ChooseSolve | None = None,
                 accuracy: float = DEFAULT_ACCURACY, capture: str | Path | None = None) -> None:
        self.scene = scene
        bodies = scene.bodies
        self.positions = bodies.positions.copy()
        self.velocities = bodies.velocities.copy()
        self.theta = None if bodies.theta is None else bodies.theta.copy()
        self.omega = None if bodies.omega is None else bodies.omega.copy()
        self.free = ~bodies.fixed
        self.dofs_per_body = scene.dofs_per_body
        self.dt = float(scene.dt)
        self.step_index = 0
        self.log = SolveLog()
        self.inner, self.notes = choose_solvers(scene.impact, choose_solve, accuracy,
                                                self.log)
        self.capture = Path(capture) if capture is not None else None
        self.captured = 0
        self._cache: dict[int, float] = {}
        gravity = scene.gravity
        self.gravity = gravity if gravity is not None and np.any(gravity != 0) else None
        self.acceleration = None
        if self.gravity is not None:
            self.acceleration = np.where(self.free[:, None], self.gravity[None, :], 0.0)
        self.m_inv = self._inverse_masses()
        self._where = f"{scene.path}: "

    def _inverse_masses(self) -> np.ndarray:
        """Diagonal of M^-1 per degree of freedom (x, y[, theta]); 0 for kinematic bodies."""
        bodies = self.scene.bodies
        per_body = [1.0 / bodies.masses, 1.0 / bodies.masses]
        if self.dofs_per_body == 3:
            per_body.append(1.0 / bodies.inertia)
        table = np.stack(per_body, axis=1) * self.free[:, None]
        return table.ravel()

    @property
    def solver_names(self) -> str | None:
        """The names of the inner solvers, sorted and comma-separated; None when there is none."""
        return ", ".join(sorted({inner.chosen.name for inner in self.inner.values()})) or None

    # --- state -------------------------------------------------------------------------
    def dof_velocity(self) -> np.ndarray:
        """v over all degrees of freedom, body by body: (vx, vy[, omega])."""
        columns = [self.velocities[:, 0], self.velocities[:, 1]]
        if self.dofs_per_body == 3:
            assert self.omega is not None
            columns.append(self.omega)
        return np.stack(columns, axis=1).ravel()

    def energy(self) -> float:
        bodies = self.scene.bodies
        return checks.energy(bodies.masses, bodies.inertia, self.free, self.positions,
                             self.velocities, self.omega, self.gravity)

    # --- one step ----------------------------------------------------------------------
    def find_contacts(self, x0: np.ndarray, x1: np.ndarray) -> contacts.Contacts:
        """The active contacts of the step (only the kinds the scene has)."""
        scene = self.scene
        radii, fixed = scene.bodies.radii, scene.bodies.fixed
        parts = [contacts.ball_ball(x0, x1, radii, fixed, self._where)]
        if scene.has_planes:
            parts.append(contacts.ball_plane(x1, radii, fixed, scene.plane_points,
                                             scene.plane_normals))
        if scene.has_drums:
            parts.append(contacts.ball_drum(x0, x1, radii, fixed, scene.drum_centers,
                                            scene.drum_radii, self._where))
        return contacts.Contacts.concatenate(parts)

    def impact_problem(self, found: contacts.Contacts) -> ImpactProblem:
        """The impact problem of this step: G over every body's dofs, v- = start velocities."""
        scene = self.scene
        assert scene.impact is not None
        name = f"{scene.name}_step{self.step_index:06d}"
        return ImpactProblem.build(
            name, found.jacobian(scene.bodies.count, self.dofs_per_body), self.m_inv,
            self.dof_velocity(), scene.impact.restitution, None,
            family=f"scene:{scene.name}", source=scene.path, dofs_per_body=self.dofs_per_body,
            metadata={"scene": scene.path, "step": self.step_index,
                      "time": self.step_index * self.dt, "operator": scene.impact.type,
                      "dialect": scene.dialect},
        )

    def step(self) -> StepEvent:
        """Advances one step; raises InnerSolveFailed when the inner solver fails."""
        scene = self.scene
        x0, v0 = self.positions, self.velocities
        x1, v1 = integrators.flow(scene.integrator, x0, v0, self.dt, self.acceleration)
        found = contacts.Contacts.empty()
        impulses = np.zeros(0)
        problem = None
        if scene.impact is not None and scene.bodies.count:
            found = self.find_contacts(x0, x1)
        if not found.count:
            self._cache.clear()  # as SCISim: a step without contacts forgets cached impulses
        if found.count:
            problem = self.impact_problem(found)
            if self.capture is not None and np.any(problem.b < 0):  # b >= 0: l = 0, no impact
                files.save(problem, self.capture / problem.name)
                self.captured += 1
            keys = found.keys()
            warm = None
            if scene.impact is not None and scene.impact.cache_impulses:
                warm = np.array([self._cache.get(int(key), 0.0) for key in keys])
            assert scene.impact is not None
            impulses = apply(scene.impact, problem, self.inner, self.log, warm)
            if scene.impact.cache_impulses:
                self._cache = dict(zip(keys.tolist(), impulses.tolist(), strict=True))
            v_plus = problem.v_plus(impulses).reshape(-1, self.dofs_per_body)
            x1, v1 = integrators.flow(scene.integrator, x0, v_plus[:, :2], self.dt,
                                      self.acceleration)
            if self.omega is not None:
                self.omega = v_plus[:, 2].copy()
        event = StepEvent(self.step_index, self.step_index * self.dt, x0, found, impulses,
                          problem)
        if not (np.all(np.isfinite(x1)) and np.all(np.isfinite(v1))):
            raise UnsupportedError(f"{self._where}the state is no longer finite at step "
                                   f"{self.step_index} (values beyond floating point range)")
        self.positions, self.velocities = x1, v1
        if self.theta is not None and self.omega is not None:
            self.theta = self.theta + self.dt * self.omega
        self.step_index += 1
        return event

    # --- a run -------------------------------------------------------------------------
    def step_count(self, end_time: float | Fraction | None, max_steps: int | None) -> int:
        """Steps to reach ``end_time`` (or the scene's), capped by ``max_steps``."""
        if end_time is None:
            end = self.scene.end_time
        elif isinstance(end_time, float):  # the decimal the user typed, not its binary value
            end = Fraction(repr(end_time))
        else:
            end = Fraction(end_time)
        if end is None and max_steps is None:
            raise QpbenchError(f"{self.scene.path}: the scene has no <end_time>; give "
                               "--end-time or --steps")
        count = math.ceil(end / self.scene.dt) if end is not None else max_steps
        assert count is not None
        return max(0, min(count, max_steps) if max_steps is not None else count)

    def run(self, end_time: float | Fraction | None = None, max_steps: int | None = None,
            on_step: Callable[[StepEvent], None] | None = None) -> SimulationResult:
        """Steps to the end time (or the step cap) and returns the summary."""
        scene = self.scene
        total = self.step_count(end_time, max_steps)
        result = SimulationResult(scene=scene.path, log=self.log, notes=list(self.notes))
        result.operator = scene.impact.type if scene.impact is not None else None
        result.solver = self.solver_names
        v_start = self.velocities.copy()
        result.energy_initial = self.energy()
        start = time.perf_counter()
        for _ in range(total):
            try:
                event = self.step()
            except InnerSolveFailed as failure:
                result.failure = {**failure.detail, "step": self.step_index,
                                  "time": self.step_index * self.dt}
                break
            if event.problem is not None:
                result.max_contacts = max(result.max_contacts, event.contacts.count)
            if event.problem is not None and np.any(event.problem.b < 0):
                result.impacts += 1
                gain = metrics.energy_gain(event.problem, event.impulses)
                if result.max_energy_gain is None or gain > result.max_energy_gain:
                    result.max_energy_gain = gain
            if on_step is not None:
                on_step(event)
        result.wall_s = time.perf_counter() - start
        result.steps = self.step_index
        result.time = self.step_index * self.dt
        result.energy_final = self.energy()
        if scene.balls_alone:
            result.momentum_drift = checks.momentum_drift(
                scene.bodies.masses, self.free, v_start, self.velocities, self.gravity,
                result.time)
        result.captured = self.captured
        result.x_final = self.positions.copy()
        result.v_final = self.velocities.copy()
        return result
