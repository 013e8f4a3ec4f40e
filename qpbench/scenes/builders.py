"""Scenes built in code, and a writer of scene XML that the parser reads back exactly.

``box_scene(n)`` is the scale test: ``n`` unit balls (radius 1/2, mass 1) on a
jittered square lattice of spacing 1.25 (area fraction about 0.5), random
velocities of speed up to 1, four walls around them, no gravity, elastic ``lcp``
impacts. The work per ball per step is the same at every size.
"""

from __future__ import annotations

import math
import os
from fractions import Fraction
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from qpbench.atomic import atomic_path
from qpbench.scenes.model import Bodies, FrictionSolver, ImpactOperator, Scene, SolverChoice
from qpbench.scenes.solver_names import SCISIM_TO_QPBENCH

BOX_SPACING = 1.25
BOX_RADIUS = 0.5
BOX_DT = Fraction(1, 100)


def box_scene(n_balls: int, seed: int = 0, restitution: float = 1.0) -> Scene:
    """``n_balls`` balls packed at random in a square box with four walls (see module doc).

    Parameters
    ----------
    n_balls : int
        The number of balls, at least 1.
    seed : int, optional
        The seed of the jitter and the velocities; 0 by default.
    restitution : float, optional
        The coefficient of restitution of the ``lcp`` impacts; 1 (elastic) by default.

    Returns
    -------
    Scene
        A ball2d scene with Verlet steps of 1/100 s until t = 1, solved by policy iteration.

    Raises
    ------
    ValueError
        When ``n_balls`` is below 1.
    """
    if n_balls < 1:
        raise ValueError("a box needs at least one ball")
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(n_balls))
    rows, columns = np.divmod(np.arange(n_balls), side)
    cells = np.stack([columns, rows], axis=1).astype(float)  # (x, y) lattice indices
    jitter = rng.uniform(-1.0, 1.0, size=(n_balls, 2)) * 0.5 * (BOX_SPACING - 2 * BOX_RADIUS)
    positions = (cells + 0.5) * BOX_SPACING + jitter
    angle = rng.uniform(0.0, 2.0 * math.pi, n_balls)
    speed = rng.uniform(0.0, 1.0, n_balls)
    velocities = np.stack([speed * np.cos(angle), speed * np.sin(angle)], axis=1)
    width = side * BOX_SPACING
    height = math.ceil(n_balls / side) * BOX_SPACING
    bodies = Bodies(positions=positions, velocities=velocities, masses=np.ones(n_balls),
                    radii=np.full(n_balls, BOX_RADIUS), fixed=np.zeros(n_balls, dtype=bool))
    solver = SolverChoice("policy_iteration", SCISIM_TO_QPBENCH["policy_iteration"])
    return Scene(
        path=f"box_{n_balls}.xml", dialect="ball2d", bodies=bodies, integrator="verlet",
        dt=BOX_DT,
        plane_points=np.array([[0.0, 0.0], [width, 0.0], [0.0, 0.0], [0.0, height]]),
        plane_normals=np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]),
        impact=ImpactOperator(type="lcp", restitution=restitution, v_tol=1e-9, solver=solver),
        end_time=Fraction(1),
    )


def _number(value: float) -> str:
    """The shortest text that reads back as the same float."""
    return repr(float(value))


def _pair(values: np.ndarray) -> str:
    return f"{_number(values[0])} {_number(values[1])}"


def _operator_xml(operator: ImpactOperator, tag: str, indent: str) -> list[str]:
    attributes = f'type="{operator.type}" CoR="{_number(operator.restitution)}"'
    attributes += f' v_tol="{_number(operator.v_tol)}"'
    if tag == "impact_operator":
        attributes += f' cache_impulses="{int(operator.cache_impulses)}"'
    lines = [f"{indent}<{tag} {attributes}>"]
    if operator.solver is not None:
        options = "".join(f" {key}={quoteattr(value)}" for key, value
                          in operator.solver.options.items())
        lines.append(f'{indent}  <solver name="{operator.solver.scisim_name}"{options}/>')
    for sub, sub_tag in ((operator.elastic, "elastic_operator"),
                         (operator.inelastic, "inelastic_operator")):
        if sub is not None:
            lines.extend(_operator_xml(sub, sub_tag, indent + "  "))
    lines.append(f"{indent}</{tag}>")
    return lines


def _friction_xml(solver: FrictionSolver) -> list[str]:
    """A friction solver element with every attribute SCISim requires."""
    common = (f'mu="{_number(solver.mu)}" CoR="{_number(solver.restitution)}" '
              f'max_iters="{solver.max_iters}" tol="{_number(solver.tol)}" '
              f'staggering="{solver.staggering}"')
    if solver.kind == "sobogus":
        extra = ""
        if solver.staggering == "symplectic_euler":
            extra = (f' stabilization="{int(solver.stabilization)}" '
                     f'penetration_threshold="{_number(solver.penetration_threshold)}"')
        return [f'  <{solver.declared_by} {common} eval_every="{solver.eval_every}" '
                f'cache_impulses="{solver.cache_impulses}"{extra}/>']
    assert solver.impact_solver is not None
    options = "".join(f' {key}="{value}"' for key, value in solver.impact_solver.options.items())
    return [f"  <{solver.declared_by} {common}>",
            f'    <lcp_impact_solver name="{solver.impact_solver.scisim_name}"{options}/>',
            f'    <mdp_friction_solver name="{solver.friction_solver_name}"/>',
            f"  </{solver.declared_by}>"]


def scene_xml(scene: Scene) -> str:
    """The scene as SCISim XML in its own dialect.

    Parameters
    ----------
    scene : Scene
        A ball2d or rigidbody2d scene.

    Returns
    -------
    str
        The XML text, ending with a newline, with floats written so that they read back
        exactly.
    """
    bodies = scene.bodies
    lines = [f"<{scene.dialect}_scene>", f'  <integrator type="{scene.integrator}" '
                                         f'dt="{scene.dt}"/>']
    if scene.friction is not None:
        lines.extend(_friction_xml(scene.friction))
    elif scene.impact is not None:
        lines.extend(_operator_xml(scene.impact, "impact_operator", "  "))
    if scene.end_time is not None:
        lines.append(f'  <end_time t="{scene.end_time}"/>')
    if scene.gravity is not None:
        if scene.dialect == "ball2d":
            lines.append(f'  <gravity fx="{_number(scene.gravity[0])}" '
                         f'fy="{_number(scene.gravity[1])}"/>')
        else:
            lines.append(f'  <near_earth_gravity f="{_pair(scene.gravity)}"/>')
    for point, normal in zip(scene.plane_points, scene.plane_normals, strict=True):
        lines.append(f'  <static_plane x="{_pair(point)}" n="{_pair(normal)}"/>')
    for center, radius in zip(scene.drum_centers, scene.drum_radii, strict=True):
        lines.append(f'  <static_drum x="{_number(center[0])}" y="{_number(center[1])}" '
                     f'r="{_number(radius)}"/>')
    if scene.dialect == "ball2d":
        for x, v, m, r, fixed in zip(bodies.positions, bodies.velocities, bodies.masses,
                                     bodies.radii, bodies.fixed, strict=True):
            lines.append(f'  <ball x="{_number(x[0])}" y="{_number(x[1])}" '
                         f'vx="{_number(v[0])}" vy="{_number(v[1])}" m="{_number(m)}" '
                         f'r="{_number(r)}" fixed="{int(fixed)}"/>')
    else:
        is_box = bodies.is_box
        halves = bodies.half_widths if bodies.half_widths is not None else np.full(
            (bodies.count, 2), np.nan)
        shapes = sorted({("box", *halves[i].tolist()) if is_box[i]
                         else ("circle", float(bodies.radii[i]), 0.0)
                         for i in range(bodies.count)})
        for kind, first, second in shapes:
            size = f"{_number(first)} {_number(second)}" if kind == "box" else _number(first)
            lines.append(f'  <geometry type="{kind}" r="{size}"/>')
        theta = bodies.theta if bodies.theta is not None else np.zeros(bodies.count)
        omega = bodies.omega if bodies.omega is not None else np.zeros(bodies.count)
        for i in range(bodies.count):
            if is_box[i]:
                shape = ("box", *halves[i].tolist())
                rho = bodies.masses[i] / (4.0 * halves[i, 0] * halves[i, 1])
            else:
                shape = ("circle", float(bodies.radii[i]), 0.0)
                rho = bodies.masses[i] / (math.pi * bodies.radii[i] ** 2)
            lines.append(f'  <rigid_body x="{_pair(bodies.positions[i])}" '
                         f'theta="{_number(theta[i])}" v="{_pair(bodies.velocities[i])}" '
                         f'omega="{_number(omega[i])}" rho="{_number(rho)}" '
                         f'geo_idx="{shapes.index(shape)}" '
                         f'fixed="{int(bodies.fixed[i])}"/>')
    lines.append(f"</{scene.dialect}_scene>")
    return "\n".join(lines) + "\n"


def write_scene(scene: Scene, path: str | os.PathLike[str]) -> Path:
    """Writes ``scene`` as XML to ``path`` atomically (a temporary file, then a rename).

    Parameters
    ----------
    scene : Scene
        The scene, as :func:`scene_xml` writes it.
    path : str or os.PathLike
        The file to write.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        When ``path`` cannot be written.
    """
    with atomic_path(path) as temporary:
        temporary.write_text(scene_xml(scene), encoding="utf-8")
    return Path(path)
