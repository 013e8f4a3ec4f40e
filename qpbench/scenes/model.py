"""What a scene declares: bodies, effects, integrator, impact operator and end time.

A scene holds exactly what its file says; the simulator composes its step from
these parts only (no gravity term without gravity, no plane test without planes).
Bodies are circles, and in ``rigidbody2d`` also boxes (half-widths ``hx hy``, mass
``rho 4 hx hy``, ``I = m (hx^2 + hy^2) / 3``). ``ball2d`` bodies have 2 degrees of freedom
(x, y); ``rigidbody2d`` bodies have a third, rotation, circles with moment of inertia
``I = m r^2 / 2``, which frictionless impacts never touch and friction does (through the
arm ``r x t`` of each contact).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

INTEGRATORS = ("symplectic_euler", "verlet")
OPERATORS = ("lcp", "gr", "grr", "gauss_seidel")
STAGGERINGS = ("geometric", "stabilized", "symplectic_euler")
CACHE_MODES = ("none", "normal", "normal_and_friction")


@dataclass
class Bodies:
    """Circles in file order. Fixed bodies are kinematic: infinite mass, constant velocity
    (rigidbody2d's ``fixed="1"``; a ball2d scene has none, as in SCISim)."""

    positions: np.ndarray  # (bodies, 2)
    velocities: np.ndarray  # (bodies, 2)
    masses: np.ndarray  # (bodies,)
    radii: np.ndarray  # (bodies,)
    fixed: np.ndarray  # (bodies,) bool
    theta: np.ndarray | None = None  # (bodies,) rigidbody2d only
    omega: np.ndarray | None = None  # (bodies,) rigidbody2d only
    # (bodies, 2) half-widths of rigidbody2d boxes, NaN rows for circles; None: no box.
    # A box's entry in ``radii`` is its circumradius |r| (for drawing and bounds only).
    half_widths: np.ndarray | None = None

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def rotates(self) -> bool:
        """True for rigidbody2d circles (a third degree of freedom per body)."""
        return self.theta is not None

    @property
    def is_box(self) -> np.ndarray:
        """(bodies,) bool: the body is a box (rigidbody2d ``<geometry type="box">``)."""
        if self.half_widths is None:
            return np.zeros(self.count, dtype=bool)
        return ~np.isnan(self.half_widths[:, 0])

    @property
    def has_boxes(self) -> bool:
        return bool(np.any(self.is_box))

    @property
    def inertia(self) -> np.ndarray:
        """I = m r^2 / 2 of a solid disc, m (hx^2 + hy^2) / 3 of a box (SCISim's
        ``BoxGeometry::computeMassAndInertia``); zeros when bodies do not rotate."""
        if not self.rotates:
            return np.zeros(self.count)
        inertia = 0.5 * self.masses * self.radii**2
        if self.half_widths is not None:
            box = self.is_box
            inertia[box] = (self.masses[box] * np.sum(self.half_widths[box] ** 2, axis=1)
                            / 3.0)
        return inertia


@dataclass
class SolverChoice:
    """The inner solver a scene names: SCISim's name, its qpbench name, and its options."""

    scisim_name: str
    qpbench_name: str
    options: dict[str, str] = field(default_factory=dict)


@dataclass
class ImpactOperator:
    """``<impact_operator type CoR v_tol cache_impulses>`` and its solver or sub-operators.

    ``lcp``: one LCP over every active contact. ``gr``: generalized reflections,
    repeated LCPs over the contacts still approaching faster than ``v_tol``.
    ``grr``: ``l = (1 - c) l_inelastic + c l_elastic``. ``gauss_seidel``: pairwise
    sweeps. ``declared_by`` names the element it came from (a friction solver with
    mu = 0 declares a frictionless ``lcp``).
    """

    type: str
    restitution: float
    v_tol: float = 1e-9
    cache_impulses: bool = False
    solver: SolverChoice | None = None
    elastic: ImpactOperator | None = None
    inelastic: ImpactOperator | None = None
    declared_by: str = "impact_operator"


@dataclass
class FrictionSolver:
    """``<sobogus_friction_solver>`` or ``<staggered_projections_friction_solver>``.

    ``mu`` and ``restitution`` hold for every contact. ``staggering`` picks SCISim's step map
    (``geometric``: solve on the start-of-step velocity, then re-integrate from the start
    positions; ``stabilized``: solve on the velocity after the forces, positions moved with
    the new velocity; ``symplectic_euler``: solve on the start-of-step velocity with the force
    increment in ``n_rel``/``d_rel``, plus ``g0/dt`` for gaps deeper than
    ``penetration_threshold`` when ``stabilization``). ``cache_impulses`` warm-starts each
    solve from the previous step's impulses of the same contact (``normal``: l_N only).
    ``tol`` is So-bogus' bound on a SQUARED Fischer-Burmeister residual (so ``1e-12`` asks
    for about ``1e-6``), ``max_iters`` its cap on Gauss-Seidel sweeps, ``eval_every`` how
    often it measures. Staggered projections name their inner solvers: ``impact_solver``
    (the normal QP, mapped like ``<solver>``) and ``friction_solver_name`` (the box QP).
    """

    kind: str  # "sobogus" or "staggered_projections"
    mu: float
    restitution: float
    staggering: str
    tol: float
    max_iters: int
    eval_every: int | None = None
    cache_impulses: str = "none"
    stabilization: bool = False
    penetration_threshold: float = 0.0
    impact_solver: SolverChoice | None = None
    friction_solver_name: str | None = None
    declared_by: str = "sobogus_friction_solver"

    @property
    def frictional(self) -> bool:
        """mu > 0: the scene needs the frictional path (mu = 0 is frictionless impact)."""
        return self.mu > 0

    @property
    def residual_asked(self) -> float:
        """The residual the scene's own ``tol`` asks for: sqrt(tol) for So-bogus (a squared
        measure), tol itself for staggered projections."""
        return self.tol ** 0.5 if self.kind == "sobogus" else self.tol


@dataclass
class Portal:
    """A planar portal (v = 0) or a Lees-Edwards portal (planes sliding at v within bounds)."""

    point_a: np.ndarray  # (2,)
    normal_a: np.ndarray  # (2,) unit
    point_b: np.ndarray
    normal_b: np.ndarray
    v: float = 0.0
    bounds: float = 0.0


@dataclass
class Scene:
    """One SCISim 2D scene, parsed as it is."""

    path: str
    dialect: str
    bodies: Bodies
    integrator: str
    dt: Fraction
    gravity: np.ndarray | None = None  # (2,) acceleration; None when the scene declares none
    plane_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    plane_normals: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    drum_centers: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    drum_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    portals: list[Portal] = field(default_factory=list)  # planar first, then Lees-Edwards
    impact: ImpactOperator | None = None
    friction: FrictionSolver | None = None  # a friction solver element (any mu)
    end_time: Fraction | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        """The file stem: ``newtons_cradle`` for ``.../newtons_cradle.xml``."""
        return Path(self.path).stem

    @property
    def dofs_per_body(self) -> int:
        return 3 if self.bodies.rotates else 2

    @property
    def has_planes(self) -> bool:
        return self.plane_points.shape[0] > 0

    @property
    def has_drums(self) -> bool:
        return self.drum_centers.shape[0] > 0

    @property
    def staggering(self) -> str:
        """SCISim's step map: the friction solver's staggering, else ``geometric``."""
        return self.friction.staggering if self.friction is not None else "geometric"

    @property
    def frictional(self) -> bool:
        """The scene declares friction with mu > 0."""
        return self.friction is not None and self.friction.frictional

    @property
    def balls_alone(self) -> bool:
        """No boundary and no kinematic body: impulses conserve linear momentum."""
        return not (self.has_planes or self.has_drums or bool(np.any(self.bodies.fixed)))
