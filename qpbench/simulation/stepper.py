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

A scene with a friction solver follows that solver's ``staggering``, as SCISim's maps do
(``scisim/ConstrainedMaps/*ImpactFrictionMap.cpp``):

* ``geometric`` (``GeometricImpactFrictionMap``): as above;
* ``stabilized`` (``StabilizedImpactFrictionMap``): solve on the predicted velocity v1
  (forces included), with the contacts of (x0, x1) and their geometry at x0, then move
  ``x1 = x0 + h v1_new``;
* ``symplectic_euler`` (``SymplecticEulerImpactFrictionMap``, CoR 0): with the force
  increment ``dv = h M^-1 F`` (zero on kinematic bodies), predict ``x0 + h (v0 + dv)`` for
  the contacts, solve on v0 with ``n_rel = G^T dv`` and ``d_rel = T^T dv`` (plus ``g0 / h``
  with ``g0 = min(0, gap)`` for gaps deeper than ``penetration_threshold`` when
  ``stabilization="1"``), then ``v1 = v+ + dv`` and ``x1 = x0 + h v1``; without contacts
  ``v1 = v0 + dv``, ``x1 = x0 + h v1`` (this map never calls the scene's integrator).

With mu > 0 every impact is one :class:`~qpbench.problem.friction.FrictionalProblem`
(tangents ``t = (-n_y, n_x)``, rigid circles' arms on the rotation rows, mu per contact),
so rigid circles spin; with mu = 0 the problem is the frictionless ImpactProblem, exactly as
for an ``<impact_operator type="lcp">``. ``cache_impulses`` warm-starts each solve from the
previous step's impulses of the same contact (``normal``: l_N only, l_T from 0;
``normal_and_friction``: both); a step without contacts forgets them, as SCISim's does.

The inner solves come from a :data:`~qpbench.simulation.operators.ChooseSolve` the caller
hands in; the simulator knows no solver by name. A friction solver's own ``tol`` sets the
accuracy asked of its inner solve when the caller gives none: ``sqrt(tol)`` for So-bogus
(whose ``tol`` bounds a squared residual), never looser than :data:`DEFAULT_ACCURACY` and
never tighter than :data:`TIGHTEST_ACCURACY`.
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
from qpbench.memory import OutOfMemory, product_bytes, require
from qpbench.problem import files, metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes.model import FrictionSolver, ImpactOperator, Scene
from qpbench.simulation import boxes, checks, contacts, integrators, portals
from qpbench.simulation.operators import (
    ChooseSolve,
    InnerSolveFailed,
    InnerSolver,
    SolveLog,
    apply,
)

DEFAULT_ACCURACY = 1e-8
TIGHTEST_ACCURACY = 1e-13  # what the inner solvers reach in double precision
# a lower bound of the bytes of one body's state over a run (positions, velocities, inverse
# masses and their per-step copies)
BODY_BYTES = 256
# formulations whose inner solve never forms Q = G^T M^-1 G (the others do, as do frictional
# solves their Delassus operator)
WITHOUT_Q = ("primal", "dual-factored")


@dataclass
class StepEvent:
    """What one step did: its contacts at the start positions and the impulses they took."""

    step: int
    time: float
    positions: np.ndarray  # start-of-step positions (bodies, 2)
    contacts: contacts.Contacts
    impulses: np.ndarray  # l, or r = (l_N, l_T) of a frictional problem
    problem: ImpactProblem | FrictionalProblem | None = None
    velocity_shift: np.ndarray | None = None  # dv added after the impulses (symplectic_euler)
    orientations: np.ndarray | None = None  # start-of-step angles (bodies,) of rigid bodies

    @property
    def approaching(self) -> bool:
        """Some contact approaches (``b < 0``): an impact; otherwise l = 0 exactly."""
        if self.problem is None:
            return False
        return bool(np.any(_normal(self.problem).b < 0))

    def energy_gain(self) -> float:
        """(KE+ - KE-) / KE- of the impulses, measured on the velocities they act on.

        For symplectic_euler: ``v0 + dv`` before, ``v+ + dv`` after.

        Returns
        -------
        float
            The relative gain of kinetic energy (KE- floored at TINY).
        """
        assert self.problem is not None
        problem = self.problem
        shift = 0.0 if self.velocity_shift is None else self.velocity_shift
        before = problem.kinetic_energy(problem.v_minus + shift)
        after = problem.kinetic_energy(problem.v_plus(self.impulses) + shift)
        return (after - before) / max(before, metrics.TINY)


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
    theta_final: np.ndarray | None = None  # rigid bodies only
    omega_final: np.ndarray | None = None  # rigid bodies only
    operator: str | None = None
    solver: str | None = None
    failure: dict[str, Any] | None = None
    log: SolveLog = field(default_factory=SolveLog)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """The summary's fields by name, with the log's counts (docs/json-output.md).

        Returns
        -------
        dict
            Every field but ``log`` and ``notes``, ``success`` (no failure), and the counts of
            :meth:`SolveLog.as_dict`; ``theta_final`` and ``omega_final`` for rigid bodies only.
        """
        return {
            "scene": self.scene, "steps": self.steps, "time": self.time,
            "impacts": self.impacts, "max_contacts": self.max_contacts,
            "energy_initial": self.energy_initial, "energy_final": self.energy_final,
            "max_energy_gain": self.max_energy_gain, "momentum_drift": self.momentum_drift,
            "wall_s": self.wall_s, "captured": self.captured,
            "x_final": self.x_final, "v_final": self.v_final,
            **({"theta_final": self.theta_final, "omega_final": self.omega_final}
               if self.theta_final is not None else {}),
            "operator": self.operator, "solver": self.solver,
            "success": self.failure is None, "failure": self.failure,
            **self.log.as_dict(),
        }


def _normal(problem: ImpactProblem | FrictionalProblem) -> ImpactProblem:
    return problem.normal if isinstance(problem, FrictionalProblem) else problem


def inner_accuracy(scene: Scene, accuracy: float | None) -> float:
    """The residual asked of every inner solve.

    ``accuracy`` when given; else, for a frictional scene, its friction solver's own
    (``FrictionSolver.residual_asked``) within [TIGHTEST_ACCURACY, DEFAULT_ACCURACY]; else
    DEFAULT_ACCURACY.

    Parameters
    ----------
    scene : Scene
        The scene.
    accuracy : float or None
        The residual asked by the user; None to take it from the scene.

    Returns
    -------
    float
        The residual bound.
    """
    if accuracy is not None:
        return accuracy
    if scene.frictional:
        assert scene.friction is not None
        return min(DEFAULT_ACCURACY, max(scene.friction.residual_asked, TIGHTEST_ACCURACY))
    return DEFAULT_ACCURACY


def solver_operators(operator: ImpactOperator | None) -> list[ImpactOperator]:
    """The lcp/gr operators (nested in a grr too) that need an inner solver.

    Parameters
    ----------
    operator : ImpactOperator or None
        The scene's impact operator; None for none.

    Returns
    -------
    list of ImpactOperator
        Those operators, elastic before inelastic in a grr.
    """
    if operator is None:
        return []
    if operator.type == "grr":
        return [op for sub in (operator.elastic, operator.inelastic)
                for op in solver_operators(sub)]
    return [operator] if operator.type in ("lcp", "gr") else []


def choose_solvers(operator: ImpactOperator | FrictionSolver | None,
                   choose_solve: ChooseSolve | None, accuracy: float, log: SolveLog
                   ) -> tuple[dict[int, InnerSolver], list[str]]:
    """The inner solver of each operator that needs one, and the notes of the choice.

    Keyed by ``id(operator)``; a frictional scene's friction solver is one.

    Parameters
    ----------
    operator : ImpactOperator or FrictionSolver or None
        The scene's impact operator, or its friction solver when mu > 0.
    choose_solve : ChooseSolve or None
        Picks the inner solve of each operator.
    accuracy : float
        The residual asked of every inner solve.
    log : SolveLog
        The run's counts, shared by every inner solver.

    Returns
    -------
    tuple of (dict of int to InnerSolver, list of str)
        The inner solvers by ``id`` of their operator, and the sorted distinct notes.

    Raises
    ------
    ValueError
        When some operator needs an inner solver and ``choose_solve`` is None.
    """
    inner: dict[int, InnerSolver] = {}
    notes: list[str] = []
    needing = ([operator] if isinstance(operator, FrictionSolver)
               else solver_operators(operator))
    for op in needing:
        if choose_solve is None:
            raise ValueError(f"the <{op.declared_by}> operator needs an inner solver: "
                             "give the Simulator a choose_solve")
        chosen = choose_solve(op)
        if chosen.note is not None:
            notes.append(chosen.note)
        inner[id(op)] = InnerSolver(chosen=chosen, accuracy=accuracy, log=log)
    return inner, sorted(set(notes))


class Simulator:
    """Steps a scene; every impact event becomes an ImpactProblem, or a FrictionalProblem when
    the scene has friction (optionally captured)."""

    def __init__(self, scene: Scene, choose_solve: ChooseSolve | None = None,
                 accuracy: float | None = None, capture: str | Path | None = None) -> None:
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
        self.accuracy = inner_accuracy(scene, accuracy)
        self.friction = scene.friction if scene.frictional else None
        self.inner, self.notes = choose_solvers(
            self.friction if self.friction is not None else scene.impact, choose_solve,
            self.accuracy, self.log)
        self.capture = Path(capture) if capture is not None else None
        self.captured = 0
        self._cache: dict[int, Any] = {}
        gravity = scene.gravity
        self.gravity = gravity if gravity is not None and np.any(gravity != 0) else None
        self.acceleration = None
        if self.gravity is not None:
            self.acceleration = np.where(self.free[:, None], self.gravity[None, :], 0.0)
        self.m_inv = self._inverse_masses()
        self._where = f"{scene.path}: "
        self._coincident_noted = False
        self._offsets: list[float] = []  # each portal's dx this step
        self._kicks = np.zeros((0, 2))  # each contact's kinematic kick (Lees-Edwards portals)
        require(bodies.count * BODY_BYTES, f"{scene.path}: {bodies.count} bodies")
        self._forms_q = any(inner.chosen.name.rsplit("/", 1)[-1] not in WITHOUT_Q
                            for inner in self.inner.values())

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

    @property
    def collides(self) -> bool:
        """The scene has contacts to resolve: an impact operator or a friction solver."""
        return self.scene.impact is not None or self.friction is not None

    # --- state -------------------------------------------------------------------------
    def dof_velocity(self, velocities: np.ndarray | None = None,
                     omega: np.ndarray | None = None) -> np.ndarray:
        """v over all degrees of freedom, body by body: (vx, vy[, omega]).

        Parameters
        ----------
        velocities : np.ndarray or None, optional
            (bodies, 2) linear velocities; None (default) for the current state's.
        omega : np.ndarray or None, optional
            (bodies,) angular velocities of rigid bodies; None (default) for the current state's.

        Returns
        -------
        np.ndarray
            (bodies * dofs_per_body,) velocities.
        """
        velocities = self.velocities if velocities is None else velocities
        columns = [velocities[:, 0], velocities[:, 1]]
        if self.dofs_per_body == 3:
            omega = self.omega if omega is None else omega
            assert omega is not None
            columns.append(omega)
        return np.stack(columns, axis=1).ravel()

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy of the current state (:func:`checks.energy`).

        Returns
        -------
        float
            The energy of the free bodies.
        """
        bodies = self.scene.bodies
        return checks.energy(bodies.masses, bodies.inertia, self.free, self.positions,
                             self.velocities, self.omega, self.gravity)

    # --- one step ----------------------------------------------------------------------
    def find_contacts(self, x0: np.ndarray, x1: np.ndarray) -> contacts.Contacts:
        """The active contacts of the step (only the kinds the scene has).

        In order: ball-ball (those across portals after), box-box and circle-box, ball-plane,
        box-plane, ball-drum. Each contact's portal kick is kept for the problem; the first pair
        of coincident centres is noted once.

        Parameters
        ----------
        x0, x1 : np.ndarray
            (bodies, 2) centres at the start and predicted at the end of the step.

        Returns
        -------
        contacts.Contacts
            The contacts.

        Raises
        ------
        UnsupportedError
            For a kinematic box-box or circle-box pair, or a ball at a drum's centre.
        OutOfMemory
            When the candidate pairs would not fit in memory.
        """
        scene = self.scene
        radii, fixed = scene.bodies.radii, scene.bodies.fixed
        coincident: list[tuple[int, int]] = []
        if scene.bodies.has_boxes:  # the circle rules see circles only
            circles = np.flatnonzero(~scene.bodies.is_box)
            pairs = contacts.ball_ball(x0[circles], x1[circles], radii[circles],
                                       fixed[circles], coincident)
            pairs.body_a, pairs.body_b = circles[pairs.body_a], circles[pairs.body_b]
            coincident = [(int(circles[a]), int(circles[b])) for a, b in coincident]
            parts = [pairs]
        else:
            parts = [contacts.ball_ball(x0, x1, radii, fixed, coincident)]
        kicks = np.zeros((0, 2))
        if scene.portals:  # SCISim's broad phase with portals: boxes at x1 only
            pairs = parts[0]
            a, b = pairs.body_a, pairs.body_b
            gap = np.abs(x1[a] - x1[b])
            reach = radii[a] + radii[b]
            if scene.dialect == "ball2d":  # overlap at x1, no sweep
                keep = np.einsum("ij,ij->i", x1[a] - x1[b], x1[a] - x1[b]) <= reach**2
            else:
                keep = np.all(gap <= reach[:, None], axis=1)
            parts[0] = contacts.Contacts(a[keep], b[keep], pairs.kind[keep],
                                         pairs.boundary[keep], pairs.normals[keep])
            across, across_kicks = portals.teleported_contacts(
                scene.portals, self._offsets, x0, x1, radii, fixed,
                aabb=scene.dialect != "ball2d")
            parts.append(across)
            kicks = np.concatenate([np.zeros((parts[0].count, 2)), across_kicks])
        if coincident and not self._coincident_noted:
            a, b = coincident[0]
            self._coincident_noted = True
            self.notes.append(f"bodies #{a} and #{b} share a centre at step {self.step_index}: "
                              "their contact has a zero normal (an inert constraint, as in "
                              "SCISim) and is left out")
        box_planes = contacts.Contacts.empty()
        if scene.bodies.has_boxes:
            assert self.theta is not None and self.omega is not None
            assert scene.bodies.half_widths is not None
            theta1 = self.theta + self.dt * self.omega
            body_body, box_planes = boxes.box_contacts(
                x0, x1, self.theta, theta1, radii, scene.bodies.half_widths, fixed,
                scene.plane_points, scene.plane_normals, self._where)
            parts.append(body_body)
        if scene.has_planes:
            parts.append(contacts.ball_plane(x1, radii, fixed | scene.bodies.is_box,
                                             scene.plane_points, scene.plane_normals))
            parts.append(box_planes)
        if scene.has_drums:
            parts.append(contacts.ball_drum(x0, x1, radii, fixed, scene.drum_centers,
                                            scene.drum_radii, self._where))
        found = contacts.Contacts.concatenate(parts)
        self._kicks = np.zeros((found.count, 2))
        self._kicks[:kicks.shape[0]] = kicks
        return found

    def _check_contact_matrices(self, found: contacts.Contacts) -> None:
        """OutOfMemory before the problem is posed when the inner solve would form Q
        (``G^T M^-1 G``) and scipy's product for it needs more than the memory available:
        each contact puts one entry in each of its bodies' x and y rows of G, so body k's
        ``c_k`` contacts make ``2 c_k^2`` of the entries the product reserves (nearly
        coincident balls: O(n^2) contacts and O(n^3) entries)."""
        if not self._forms_q or found.count == 0:
            return
        count = self.scene.bodies.count
        per_body = np.bincount(found.body_a, minlength=count)
        per_body += np.bincount(found.body_b[found.body_b >= 0], minlength=count)
        require(product_bytes(np.repeat(per_body, 2)),
                f"{found.count} contacts (Q = G^T M^-1 G)")

    def _metadata(self, kind: str) -> dict[str, Any]:
        scene = self.scene
        data = {"scene": scene.path, "step": self.step_index, "time": self.step_index * self.dt,
                "operator": kind, "dialect": scene.dialect}
        if scene.friction is not None:
            data["staggering"] = scene.friction.staggering
        return data

    def impact_problem(self, found: contacts.Contacts, v_minus: np.ndarray | None = None,
                       n_rel: np.ndarray | None = None) -> ImpactProblem:
        """The impact problem of this step.

        G over every body's dofs, v- = start velocities (unless ``v_minus`` is given), with
        ``n_rel`` (default none).

        Parameters
        ----------
        found : contacts.Contacts
            The step's contacts.
        v_minus : np.ndarray or None, optional
            (bodies * dofs_per_body,) velocities before the impact; None (default) for the
            current state's.
        n_rel : np.ndarray or None, optional
            (n,) added normal velocities; None (default) for none.

        Returns
        -------
        ImpactProblem
            The problem, named ``SCENE_stepNNNNNN``, with the scene's restitution.
        """
        scene = self.scene
        assert scene.impact is not None
        name = f"{scene.name}_step{self.step_index:06d}"
        return ImpactProblem.build(
            name, found.jacobian(scene.bodies.count, self.dofs_per_body), self.m_inv,
            self.dof_velocity() if v_minus is None else v_minus, scene.impact.restitution,
            n_rel, family=f"scene:{scene.name}", source=scene.path,
            dofs_per_body=self.dofs_per_body, metadata=self._metadata(scene.impact.type),
        )

    def tangents(self, found: contacts.Contacts, x0: np.ndarray) -> Any:
        """T of this step's contacts at the start positions x0.

        Parameters
        ----------
        found : contacts.Contacts
            The step's contacts.
        x0 : np.ndarray
            (bodies, 2) centres at the start of the step.

        Returns
        -------
        sp.csc_matrix
            T, (bodies * dofs_per_body, n) (:meth:`contacts.Contacts.tangent_jacobian`).
        """
        bodies = self.scene.bodies
        return found.tangent_jacobian(x0, bodies.radii, bodies.fixed, bodies.count,
                                      self.dofs_per_body)

    def frictional_problem(self, found: contacts.Contacts, x0: np.ndarray,
                           v_minus: np.ndarray, n_rel: np.ndarray | None = None,
                           d_rel: np.ndarray | None = None, T: Any = None
                           ) -> FrictionalProblem:
        """The frictional problem of this step: G and T at x0, mu and CoR per contact.

        Parameters
        ----------
        found : contacts.Contacts
            The step's contacts.
        x0 : np.ndarray
            (bodies, 2) centres at the start of the step.
        v_minus : np.ndarray
            (bodies * dofs_per_body,) velocities before the impact.
        n_rel, d_rel : np.ndarray or None, optional
            (n,) added normal and tangential velocities; None (default) for none.
        T : sparse matrix or None, optional
            The tangents, when already computed; None (default) computes them.

        Returns
        -------
        FrictionalProblem
            The problem, named ``SCENE_stepNNNNNN``, with the friction solver's settings in its
            metadata.
        """
        scene = self.scene
        assert self.friction is not None
        name = f"{scene.name}_step{self.step_index:06d}"
        return FrictionalProblem.build(
            name, found.jacobian(scene.bodies.count, self.dofs_per_body),
            self.tangents(found, x0) if T is None else T, self.m_inv, v_minus,
            self.friction.mu, self.friction.restitution, n_rel, d_rel,
            family=f"scene:{scene.name}", source=scene.path, dofs_per_body=self.dofs_per_body,
            metadata={**self._metadata(self.friction.kind), "mu": self.friction.mu,
                      "tol": self.friction.tol, "max_iters": self.friction.max_iters,
                      "eval_every": self.friction.eval_every,
                      "cache_impulses": self.friction.cache_impulses},
        )

    def _symplectic_terms(self, found: contacts.Contacts, x0: np.ndarray, shift: np.ndarray,
                          T: Any) -> tuple[np.ndarray, np.ndarray | None]:
        """n_rel = G^T dv (+ g0 / h) and d_rel = T^T dv of the symplectic_euler map."""
        scene = self.scene
        assert scene.friction is not None
        G = found.jacobian(scene.bodies.count, self.dofs_per_body)
        n_rel = G.T @ shift
        if scene.friction.stabilization:
            gaps = found.gaps(x0, scene.bodies.radii, scene.plane_points, scene.plane_normals,
                              scene.drum_centers, scene.drum_radii)
            g0 = np.minimum(0.0, gaps)
            g0[np.abs(g0) < scene.friction.penetration_threshold] = 0.0
            n_rel = n_rel + g0 / self.dt
        return n_rel, (None if T is None else T.T @ shift)

    def _warm_start(self, keys: np.ndarray, frictional: bool) -> np.ndarray | None:
        """The previous step's impulses of the same contacts (zeros for new ones), or None
        when the scene caches nothing."""
        scene = self.scene
        if frictional:
            assert self.friction is not None
            mode = self.friction.cache_impulses
            if mode == "none":
                return None
            cached = np.array([self._cache.get(int(key), (0.0, 0.0)) for key in keys],
                              dtype=float).reshape(-1, 2)
            tangential = cached[:, 1] if mode == "normal_and_friction" else np.zeros(len(keys))
            return np.concatenate([cached[:, 0], tangential])
        if scene.impact is not None and scene.impact.cache_impulses:
            return np.array([self._cache.get(int(key), 0.0) for key in keys])
        return None

    def _remember(self, keys: np.ndarray, impulses: np.ndarray, frictional: bool) -> None:
        scene = self.scene
        if frictional:
            assert self.friction is not None
            if self.friction.cache_impulses != "none":
                n = len(keys)
                self._cache = {int(key): (float(impulses[k]), float(impulses[n + k]))
                               for k, key in enumerate(keys)}
        elif scene.impact is not None and scene.impact.cache_impulses:
            self._cache = dict(zip(keys.tolist(), impulses.tolist(), strict=True))

    def _solve(self, problem: ImpactProblem | FrictionalProblem,
               warm: np.ndarray | None) -> np.ndarray:
        if isinstance(problem, FrictionalProblem):
            assert self.friction is not None
            return self.inner[id(self.friction)].solve(problem, warm)
        assert self.scene.impact is not None
        return apply(self.scene.impact, problem, self.inner, self.log, warm)

    def step(self) -> StepEvent:
        """Advance one step; raises InnerSolveFailed when the inner solver fails.

        The unconstrained flow predicts x1; the contacts found over the step pose one problem
        (captured when asked and some contact approaches), whose impulses give the velocities
        after the impact and so the positions at the end of the step.

        Returns
        -------
        StepEvent
            What the step did.

        Raises
        ------
        InnerSolveFailed
            When the inner solve gives no usable answer.
        UnsupportedError
            For a contact SCISim does not support, or a state no longer finite.
        OutOfMemory
            When the contacts or their Q would not fit in memory.
        """
        scene = self.scene
        staggering = scene.staggering
        x0, v0 = self.positions, self.velocities
        shift: np.ndarray | None = None
        if scene.portals:
            self._offsets = portals.offsets(scene.portals, (self.step_index + 1) * self.dt)
        if staggering == "symplectic_euler":  # the map's own update, never the integrator
            v1 = v0 if self.acceleration is None else v0 + self.dt * self.acceleration
            x1 = x0 + self.dt * v1
        else:
            x1, v1 = integrators.flow(scene.integrator, x0, v0, self.dt, self.acceleration)
        found = contacts.Contacts.empty()
        impulses = np.zeros(0)
        problem: ImpactProblem | FrictionalProblem | None = None
        if self.collides and scene.bodies.count:
            try:
                found = self.find_contacts(x0, x1)
                self._check_contact_matrices(found)
            except OutOfMemory as error:
                raise OutOfMemory(f"{self._where}step {self.step_index}: {error}") from None
        if not found.count:
            self._cache.clear()  # as SCISim: a step without contacts forgets cached impulses
        if found.count:
            frictional = self.friction is not None
            T = self.tangents(found, x0) if frictional else None
            n_rel = d_rel = None
            # the stabilized map solves on the predicted velocity, the others on v0
            v_minus = self.dof_velocity(v1 if staggering == "stabilized" else None)
            if staggering == "symplectic_euler":
                increment = (np.zeros_like(v0) if self.acceleration is None
                             else self.dt * self.acceleration)
                shift = self.dof_velocity(increment, np.zeros(scene.bodies.count))
                n_rel, d_rel = self._symplectic_terms(found, x0, shift, T)
            if np.any(self._kicks):  # v_a - v_b - k across a Lees-Edwards portal
                kick_n = -np.einsum("ij,ij->i", found.normals, self._kicks)
                tangent = np.stack([-found.normals[:, 1], found.normals[:, 0]], axis=1)
                kick_t = -np.einsum("ij,ij->i", tangent, self._kicks)
                n_rel = kick_n if n_rel is None else n_rel + kick_n
                d_rel = kick_t if d_rel is None else d_rel + kick_t
            if frictional:
                problem = self.frictional_problem(found, x0, v_minus, n_rel, d_rel, T)
            elif staggering == "geometric":
                problem = self.impact_problem(found, None, n_rel)
            else:
                problem = self.impact_problem(found, v_minus, n_rel)
            keys = found.keys()
            warm = self._warm_start(keys, frictional)
            if self.capture is not None and np.any(_normal(problem).b < 0):  # else l = 0
                # each contact's identity, stored beside the numbers (never in G or any
                # fingerprint), so a replay can match the contacts of consecutive steps; and
                # the impulses carried from the previous step where the scene caches them
                # (``run --mode warm`` starts from these)
                _normal(problem).data["contact_keys"] = keys.copy()
                if warm is not None:
                    _normal(problem).data["warm_start"] = warm.copy()
                files.save(problem, self.capture / problem.name)
                self.captured += 1
            impulses = self._solve(problem, warm)
            self._remember(keys, impulses, frictional)
            v_plus = problem.v_plus(impulses)
            if shift is not None:
                v_plus = v_plus + shift
            v_plus = v_plus.reshape(-1, self.dofs_per_body)
            if staggering == "geometric":
                x1, v1 = integrators.flow(scene.integrator, x0, v_plus[:, :2], self.dt,
                                          self.acceleration)
            else:
                v1 = v_plus[:, :2].copy()
                x1 = x0 + self.dt * v1
            if self.omega is not None:
                self.omega = v_plus[:, 2].copy()
        event = StepEvent(self.step_index, self.step_index * self.dt, x0, found, impulses,
                          problem, shift, self.theta)
        if not (np.all(np.isfinite(x1)) and np.all(np.isfinite(v1))):
            raise UnsupportedError(f"{self._where}the state is no longer finite at step "
                                   f"{self.step_index} (values beyond floating point range)")
        if scene.portals:
            x1, v1 = x1.copy(), v1.copy()
            portals.enforce(scene.portals, self._offsets, x1, v1)
        self.positions, self.velocities = x1, v1
        if self.theta is not None and self.omega is not None:
            self.theta = self.theta + self.dt * self.omega
        self.step_index += 1
        return event

    # --- a run -------------------------------------------------------------------------
    def step_count(self, end_time: float | Fraction | None, max_steps: int | None) -> int:
        """Steps to reach ``end_time`` (or the scene's), capped by ``max_steps``.

        Parameters
        ----------
        end_time : float or Fraction or None
            Simulated seconds (a float read as the decimal it prints as); None for the scene's
            ``<end_time>``.
        max_steps : int or None
            The steps at most; None for no cap.

        Returns
        -------
        int
            ``ceil(end / dt)``, capped, at least 0.

        Raises
        ------
        QpbenchError
            When there is neither an end time nor a step cap.
        """
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
        """Step to the end time (or the step cap) and return the summary.

        An inner solve that fails ends the run early, recorded in the result's ``failure``.

        Parameters
        ----------
        end_time : float or Fraction or None, optional
            Simulated seconds; None (default) for the scene's ``<end_time>``.
        max_steps : int or None, optional
            The steps at most; None (default) for no cap.
        on_step : callable or None, optional
            Told every StepEvent; None (default) for none.

        Returns
        -------
        SimulationResult
            The run's summary.

        Raises
        ------
        QpbenchError
            When there is neither an end time nor a step cap, or a step meets an unsupported
            contact, a state no longer finite, or a lack of memory.
        """
        scene = self.scene
        total = self.step_count(end_time, max_steps)
        result = SimulationResult(scene=scene.path, log=self.log, notes=list(self.notes))
        result.operator = (self.friction.kind if self.friction is not None
                           else scene.impact.type if scene.impact is not None else None)
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
            if event.approaching:
                result.impacts += 1
                if isinstance(event.problem, FrictionalProblem) or event.velocity_shift is not None:
                    gain = event.energy_gain()
                else:
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
        result.notes = list(self.notes)
        result.x_final = self.positions.copy()
        result.v_final = self.velocities.copy()
        if self.theta is not None and self.omega is not None:
            result.theta_final = self.theta.copy()
            result.omega_final = self.omega.copy()
        return result
