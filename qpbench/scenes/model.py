"""What a scene declares: bodies, effects, integrator, impact operator and end time.

A scene holds exactly what its file says; the simulator composes its step from
these parts only (no gravity term without gravity, no plane test without planes).
Bodies are circles. ``ball2d`` bodies have 2 degrees of freedom (x, y);
``rigidbody2d`` circles have a third, rotation, with moment of inertia
``I = m r^2 / 2``, which frictionless impacts never touch.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

INTEGRATORS = ("symplectic_euler", "verlet")
OPERATORS = ("lcp", "gr", "grr", "gauss_seidel")


@dataclass
class Bodies:
    """Circles in file order. Fixed bodies are kinematic: infinite mass, constant velocity."""

    positions: np.ndarray  # (bodies, 2)
    velocities: np.ndarray  # (bodies, 2)
    masses: np.ndarray  # (bodies,)
    radii: np.ndarray  # (bodies,)
    fixed: np.ndarray  # (bodies,) bool
    theta: np.ndarray | None = None  # (bodies,) rigidbody2d only
    omega: np.ndarray | None = None  # (bodies,) rigidbody2d only

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def rotates(self) -> bool:
        """True for rigidbody2d circles (a third degree of freedom per body)."""
        return self.theta is not None

    @property
    def inertia(self) -> np.ndarray:
        """I = m r^2 / 2 of a solid disc (zeros when bodies do not rotate)."""
        if not self.rotates:
            return np.zeros(self.count)
        return 0.5 * self.masses * self.radii**2


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
    impact: ImpactOperator | None = None
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
    def balls_alone(self) -> bool:
        """No boundary and no kinematic body: impulses conserve linear momentum."""
        return not (self.has_planes or self.has_drums or bool(np.any(self.bodies.fixed)))
