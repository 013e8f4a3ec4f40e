"""Seeded, deterministic families of hard impact problems (2 degrees of freedom per ball).

Every family lays out balls, finds the contacts and assembles G with the simulator's
:func:`~qpbench.problem.jacobian.contact_jacobian`: ball-ball contact a,b puts ``+n_ab`` in
a's rows and ``-n_ab`` in b's, ``n_ab = (x_a - x_b) / |x_a - x_b|``; a ball-plane contact
puts the plane normal in the ball's rows. A contact is active when the balls overlap (or touch
within ``touch_tolerance``) and approach each other or rest against each other
(``G^T v- <= 0``), as in SCISim's impact detection.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from qpbench.errors import QpbenchError
from qpbench.memory import require
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.jacobian import contact_jacobian
from qpbench.problem.metrics import dot


@dataclass
class Layout:
    """Balls (and static planes) at the start of an impact step."""

    positions: np.ndarray  # (balls, 2)
    velocities: np.ndarray  # (balls, 2)
    radii: np.ndarray  # (balls,)
    masses: np.ndarray  # (balls,)
    plane_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    plane_normals: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    restitution: float = 1.0
    touch_tolerance: float = 1e-9
    approaching_only: bool = True


def ball_pairs(layout: Layout) -> np.ndarray:
    """Pairs (a, b), a < b, with |x_a - x_b| <= r_a + r_b + touch_tolerance.

    Parameters
    ----------
    layout : Layout
        The balls.

    Returns
    -------
    np.ndarray
        The pairs, integers of shape (pairs, 2), sorted by a then b.
    """
    reach = 2.0 * float(np.max(layout.radii)) + layout.touch_tolerance
    pairs = cKDTree(layout.positions).query_pairs(reach, output_type="ndarray")
    if pairs.size == 0:
        return np.zeros((0, 2), dtype=int)
    pairs = np.sort(pairs, axis=1)
    gaps = np.linalg.norm(layout.positions[pairs[:, 0]] - layout.positions[pairs[:, 1]], axis=1)
    reach_pairs = layout.radii[pairs[:, 0]] + layout.radii[pairs[:, 1]]
    touching = gaps <= reach_pairs + layout.touch_tolerance
    pairs = pairs[touching]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def assemble(name: str, family: str, layout: Layout, metadata: dict | None = None,
             extra_normals: list[tuple[int, int, np.ndarray]] | None = None) -> ImpactProblem:
    """The ImpactProblem of ``layout``: G, M^-1 = diag(1/m, 1/m), v-, one restitution.

    ``extra_normals`` adds contacts (a, b, n): +n in a's rows and -n in b's (b = -1 for none).

    Parameters
    ----------
    name, family : str
        The problem's name and family.
    layout : Layout
        The balls and planes; with ``approaching_only`` only contacts with ``G^T v- <= 0``
        are kept.
    metadata : dict or None, optional
        The problem's metadata; None (the default) for none.
    extra_normals : list of (int, int, np.ndarray) or None, optional
        Contacts added after the ball pairs and planes; None (the default) for none.

    Returns
    -------
    ImpactProblem
        The validated problem, with source ``generated``.
    """
    balls = layout.positions.shape[0]
    # contacts in column order: ball pairs, then planes, then the extra normals
    body_a: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    body_b: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    normals: list[np.ndarray] = [np.zeros((0, 2))]

    def add(a: np.ndarray, b: np.ndarray | None, contact_normals: np.ndarray) -> None:
        body_a.append(np.asarray(a, dtype=np.int64))
        body_b.append(np.full(len(a), -1, dtype=np.int64) if b is None
                      else np.asarray(b, dtype=np.int64))
        normals.append(np.asarray(contact_normals, dtype=float).reshape(-1, 2))

    pairs = ball_pairs(layout)
    if len(pairs):
        delta = layout.positions[pairs[:, 0]] - layout.positions[pairs[:, 1]]
        add(pairs[:, 0], pairs[:, 1], delta / np.linalg.norm(delta, axis=1)[:, None])
    for point, normal in zip(layout.plane_points, layout.plane_normals, strict=True):
        distance = (layout.positions - point) @ normal
        touching = np.flatnonzero(distance <= layout.radii + layout.touch_tolerance)
        add(touching, None, np.tile(normal, (len(touching), 1)))
    for a, b, normal in extra_normals or []:
        add(np.array([a]), None if b < 0 else np.array([b]), np.asarray(normal)[None, :])
    G = contact_jacobian(np.concatenate(body_a), np.concatenate(body_b),
                         np.concatenate(normals), balls, 2)
    v_minus = layout.velocities.reshape(-1)
    if layout.approaching_only:
        G = G[:, np.flatnonzero(G.T @ v_minus <= 0)]
    m_inv = np.repeat(1.0 / layout.masses, 2)
    return ImpactProblem.build(name, G, m_inv, v_minus, layout.restitution, family=family,
                               source="generated", metadata=metadata or {})


def libm(function: Callable[[float], float], values: np.ndarray | float) -> np.ndarray:
    """``function`` (from ``math``: the C library's) of each value.

    NumPy's vectorised sin, cos, tan, arctan and power run CPU-specific code (AVX-512 SVML
    where there is AVX-512) whose last bits differ from the C library's, which would make a
    generated problem's numbers, and so the committed results' fingerprints, depend on the
    machine.

    Parameters
    ----------
    function : callable
        A function of one float, e.g. ``math.sin``.
    values : np.ndarray or float
        The arguments.

    Returns
    -------
    np.ndarray
        ``function`` of each value, of the shape of ``values``.
    """
    return np.array([function(float(value)) for value in np.ravel(values)]).reshape(
        np.shape(values))


def _rotate(points: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return points @ np.array([[c, s], [-s, c]])


def _symmetric(positions: np.ndarray, rng: np.random.Generator | None) -> Layout:
    """Unit balls of radius 1 at ``positions`` moving to their centroid; rotated when seeded."""
    if rng is not None:
        angle = rng.uniform(0, 2 * np.pi)
        positions = _rotate(positions, angle)
    centre = positions.mean(axis=0)
    velocities = -(positions - centre) / np.linalg.norm(positions - centre, axis=1)[:, None]
    if rng is not None:
        velocities *= rng.uniform(0.5, 2.0, size=(len(positions), 1))
    return Layout(positions, velocities, np.ones(len(positions)), np.ones(len(positions)))


def k3(size: int, rng: np.random.Generator | None) -> Layout:
    """Three collinear overlapping unit balls at x = -1/2, 0, 1/2 (radius 1).

    v- = (1, 0, -1) along the line; contacts (0,1), (0,2), (1,2) give
    Q = [[2,1,-1],[1,2,1],[-1,1,2]] and every solution l = (t, 2 - t, t), 0 <= t <= 2, gives
    v+_x = (-1, 0, 1) for c = 1.

    Parameters
    ----------
    size : int
        Unused (always three balls).
    rng : np.random.Generator or None
        Rotates the layout and scales the velocities when given; None for the canonical case.

    Returns
    -------
    Layout
        The balls.
    """
    positions = np.array([[-0.5, 0.0], [0.0, 0.0], [0.5, 0.0]])
    velocities = np.array([[1.0, 0.0], [0.0, 0.0], [-1.0, 0.0]])
    if rng is not None:
        angle = rng.uniform(0, 2 * np.pi)
        positions, velocities = _rotate(positions, angle), _rotate(velocities, angle)
        velocities *= rng.uniform(0.5, 2.0)
    return Layout(positions, velocities, np.ones(3), np.ones(3))


def k4(size: int, rng: np.random.Generator | None) -> Layout:
    """Four unit balls (radius 1) on the corners of a unit square, moving to its centre.

    Six contacts, Q of rank 5.

    Parameters
    ----------
    size : int
        Unused (always four balls).
    rng : np.random.Generator or None
        Rotates the layout and scales each speed when given; None for the canonical case.

    Returns
    -------
    Layout
        The balls.
    """
    return _symmetric(np.array([[-0.5, 0.5], [0.5, 0.5], [0.5, -0.5], [-0.5, -0.5]]), rng)


def k4_middle(size: int, rng: np.random.Generator | None) -> Layout:
    """K4 plus a fifth ball at rest in the centre: ten contacts.

    Parameters
    ----------
    size : int
        Unused (always five balls).
    rng : np.random.Generator or None
        As :func:`k4` takes it.

    Returns
    -------
    Layout
        The balls.
    """
    layout = k4(size, rng)
    centre = layout.positions.mean(axis=0)
    return Layout(np.vstack([layout.positions, centre]), np.vstack([layout.velocities, [0, 0]]),
                  np.ones(5), np.ones(5))


def cradle(size: int, rng: np.random.Generator | None) -> Layout:
    """Newton's cradle: ``size`` touching balls (radius 1/2) in a row.

    The first moves at v = (1, 0); for size 3 the LCP gives v+ = (-1/3, 2/3, 2/3) in x.

    Parameters
    ----------
    size : int
        The number of balls.
    rng : np.random.Generator or None
        Draws the first ball's speed in [0.5, 2] when given; None for speed 1.

    Returns
    -------
    Layout
        The balls.
    """
    positions = np.column_stack([np.arange(size, dtype=float), np.zeros(size)])
    velocities = np.zeros((size, 2))
    velocities[0, 0] = 1.0
    if rng is not None:
        velocities[0, 0] = rng.uniform(0.5, 2.0)
    return Layout(positions, velocities, np.full(size, 0.5), np.ones(size))


def grid(size: int, rng: np.random.Generator | None) -> Layout:
    """``size`` x ``size`` balls of radius 1 at spacing 1, perturbed, with random velocities.

    The positions are perturbed by up to 0.01 and the velocities uniform in [-1, 1]^2: the
    overlapping grids on which policy iteration was found to fail.

    Parameters
    ----------
    size : int
        Balls per side.
    rng : np.random.Generator or None
        The draws; None for seed 0.

    Returns
    -------
    Layout
        The balls.
    """
    rng = rng or np.random.default_rng(0)
    ii, jj = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    positions = np.column_stack([ii.ravel(), jj.ravel()]).astype(float)
    positions += rng.uniform(0.0, 0.01, size=positions.shape)
    velocities = rng.uniform(-1.0, 1.0, size=positions.shape)
    return Layout(positions, velocities, np.ones(len(positions)), np.ones(len(positions)))


def box(size: int, rng: np.random.Generator | None) -> Layout:
    """``size`` balls (radius 1/2) densely packed in a square box with four walls.

    A jittered square lattice at spacing 0.98 (so neighbours overlap slightly), random
    velocities.

    Parameters
    ----------
    size : int
        The number of balls.
    rng : np.random.Generator or None
        The draws; None for seed 0.

    Returns
    -------
    Layout
        The balls and the four walls.
    """
    rng = rng or np.random.default_rng(0)
    side = int(np.ceil(np.sqrt(size)))
    spacing = 0.98
    ii, jj = np.divmod(np.arange(size), side)
    positions = np.column_stack([jj, ii]).astype(float) * spacing + 0.5
    positions += rng.uniform(-0.01, 0.01, size=positions.shape)
    velocities = rng.uniform(-1.0, 1.0, size=positions.shape)
    width = (side - 1) * spacing + 1.0 - 0.02
    plane_points = np.array([[0.0, 0.0], [width, 0.0], [0.0, 0.0], [0.0, width]])
    plane_normals = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    return Layout(positions, velocities, np.full(size, 0.5), np.ones(size), plane_points,
                  plane_normals)


def mass_ratio(size: int, rng: np.random.Generator | None) -> Layout:
    """A perturbed grid whose masses are log-uniform over 1e-6 .. 1e6.

    Parameters
    ----------
    size : int
        Balls per side.
    rng : np.random.Generator or None
        The draws; None for seed 0.

    Returns
    -------
    Layout
        The balls.
    """
    rng = rng or np.random.default_rng(0)
    layout = grid(size, rng)
    layout.masses = libm(lambda exponent: 10.0 ** exponent,
                         rng.uniform(-6.0, 6.0, size=len(layout.masses)))
    return layout


def near_duplicate(size: int, rng: np.random.Generator | None) -> tuple[Layout, list]:
    """A perturbed grid where every ball-ball contact appears twice.

    The copy's normal is turned by about 1e-9 rad: Q is numerically rank deficient.

    Parameters
    ----------
    size : int
        Balls per side.
    rng : np.random.Generator or None
        The draws; None for seed 0.

    Returns
    -------
    layout : Layout
        The balls.
    extra : list of (int, int, np.ndarray)
        The duplicate contacts (a, b, turned normal), for :func:`assemble`.
    """
    rng = rng or np.random.default_rng(0)
    layout = grid(size, rng)
    extra = []
    for a, b in ball_pairs(layout):
        delta = layout.positions[a] - layout.positions[b]
        # |delta| by the fixed-order inner product (np.linalg.norm of a vector is a BLAS dot
        # product, whose kernels, with or without fused multiply-adds, depend on the CPU)
        length = np.sqrt(dot(delta, delta))
        normal = _rotate((delta / length)[None, :], rng.uniform(0.5e-9, 2e-9))[0]
        extra.append((int(a), int(b), normal))
    return layout, extra


Builder = Callable[[int, np.random.Generator | None], "Layout | tuple[Layout, list]"]

# family -> (builder, default size)
FAMILIES: dict[str, tuple[Builder, int]] = {
    "k3": (k3, 3),
    "k4": (k4, 4),
    "k4-middle": (k4_middle, 5),
    "cradle": (cradle, 3),
    "grid": (grid, 5),
    "box": (box, 100),
    "mass-ratio": (mass_ratio, 5),
    "near-duplicate": (near_duplicate, 4),
}


def family_entry(families: dict[str, tuple[Any, int]], family: str, size: int | None,
                 label: str = "family") -> tuple[Any, int]:
    """(builder, size) of ``family`` in a family table.

    The size is the family's default when ``size`` is None; QpbenchError for an unknown family
    or a size below 1.

    Parameters
    ----------
    families : dict of str to (builder, int)
        The table: family -> (builder, default size).
    family : str
        The family asked for.
    size : int or None
        The size asked for; None for the default.
    label : str, optional
        What a family is called in the message; ``family`` by default.

    Returns
    -------
    builder : Any
        The family's builder.
    size : int
        The size to build.

    Raises
    ------
    QpbenchError
        When the family is unknown or the size is below 1.
    """
    if family not in families:
        raise QpbenchError(f"unknown {label} '{family}' (known: {', '.join(families)})")
    builder, default_size = families[family]
    size = default_size if size is None else int(size)
    if size < 1:
        raise QpbenchError(f"family '{family}': size must be >= 1, got {size}")
    return builder, size


# families whose size counts balls per side of a square grid, and rows of a triangle
# (qpbench.problem.friction_generate's pyramid); every other family's counts balls
PER_SIDE_FAMILIES = ("grid", "mass-ratio", "near-duplicate")
ROW_FAMILIES = ("pyramid",)
# a lower bound of the bytes one ball of a generated problem takes while it is built (its
# layout's positions, velocities, radii and masses, the grid indices, its contacts' G)
BALL_BYTES = 1024


def family_balls(family: str, size: int) -> int:
    """The balls of a problem of ``family`` (frictionless or frictional) at ``size``.

    Parameters
    ----------
    family : str
        The family.
    size : int
        Its size: balls per side, rows of a triangle or balls (see :data:`PER_SIDE_FAMILIES`
        and :data:`ROW_FAMILIES`).

    Returns
    -------
    int
        The number of balls.
    """
    if family in PER_SIDE_FAMILIES:
        return size * size
    if family in ROW_FAMILIES:
        return size * (size + 1) // 2
    return size


def check_family_size(family: str, size: int) -> None:
    """Refuses a family size that needs more memory than is available.

    OutOfMemory (one line, naming the family, the size and its balls, and the memory
    available) before anything is allocated, when one problem of ``family`` at ``size`` needs
    more than the memory available (:data:`BALL_BYTES` per ball).

    Parameters
    ----------
    family : str
        The family.
    size : int
        Its size.

    Raises
    ------
    OutOfMemory
        When the problem would not fit.
    """
    balls = family_balls(family, size)
    require(balls * BALL_BYTES, f"family '{family}' at size {size} ({balls} balls)")


def generate(family: str, size: int | None = None, seed: int = 0, count: int = 1,
             restitution: float | None = None) -> list[ImpactProblem]:
    """``count`` problems of ``family``; problem i uses seed ``seed + i``.

    For k3, k4, k4-middle and cradle, seed 0 is the canonical, unrotated case.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    size : int or None, optional
        The family's size; None (the default) for its default size.
    seed : int, optional
        The first problem's seed; 0 by default.
    count : int, optional
        The number of problems; 1 by default.
    restitution : float or None, optional
        The coefficient of restitution of every contact; None (the default) for 1.

    Returns
    -------
    list of ImpactProblem
        The problems, named ``FAMILY-SIZE-sSEED``.

    Raises
    ------
    QpbenchError
        When the family is unknown or the size below 1.
    OutOfMemory
        When one problem would not fit in memory.
    """
    builder, size = family_entry(FAMILIES, family, size)
    check_family_size(family, size)
    problems = []
    for index in range(count):
        problem_seed = seed + index
        rng = np.random.default_rng(problem_seed) if (problem_seed or family in
                                                       ("grid", "box", "mass-ratio",
                                                        "near-duplicate")) else None
        built = builder(size, rng)
        layout, extra = built if isinstance(built, tuple) else (built, None)
        if restitution is not None:
            layout.restitution = restitution
        name = f"{family}-{size}-s{problem_seed}"
        metadata = {"family": family, "size": size, "seed": problem_seed,
                    "restitution": layout.restitution}
        problems.append(assemble(name, family, layout, metadata, extra))
    return problems
