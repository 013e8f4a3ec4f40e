"""Seeded, deterministic families of frictional impact problems (docs/design.md section 8).

Each contact has a normal n (the direction of the impulse on its first body, as in
:mod:`qpbench.problem.generate`) and the tangent ``t = (-n_y, n_x)``; G and T are assembled by
the same :func:`~qpbench.problem.jacobian.contact_jacobian`, so a ball-ball contact puts
``+t`` in a's rows and ``-t`` in b's. A rigid disc (3 dofs x, y, theta, ``I = m R^2 / 2``)
also carries the arm term in T's rotation row: for a contact point at arm r from the centre
the entry is ``r x t``; a disc of radius R on a floor with normal n has ``r = -R n``, so
``r x t = -R (n x t) = -R``.

"Resting" contacts get the velocity one time step of gravity gives them
(``v- = g dt`` downward, GRAVITY and STEP), as a simulator's impact solve would see it.

Families (name: default size, what size counts):

* ``incline`` (2 balls): balls resting on a plane tilted at theta, each with its own mu on
  either side of ``tan theta``: ball i sticks iff ``theta <= atan(mu_i)`` (e = 0), which
  ``metadata["sticks"]`` records; for one ball the side alternates with the seed.
* ``rough-floor`` (2 discs): rigid discs bouncing with spin on a rough floor, apart from each
  other; ``W = diag(1/m, 3/m)`` per disc, so disc i sticks iff
  ``|u_T-| <= 3 mu (1 + e) |u_N-|`` (``metadata["sticks"]``).
* ``pyramid`` (2 rows): a triangle of touching unit balls on a rough floor, resting, with a
  small seeded sideways kick; W is singular (more unknowns than dofs).
* ``wedge`` (1 ball): a ball dropped with e > 0 into a V whose faces are steeper than the
  friction angle (normals within ``atan(mu)`` of horizontal): jammed, the relaxed problem is
  unbounded, and the exact one has no solution (the reference says so; size balls each get
  their own V).
* ``friction-mass-ratio`` (4 balls): a row of touching balls on a rough floor with masses
  log-uniform over 1e-3 .. 1e3 and random velocities.
* ``rough-box`` (30 balls): the frictionless ``box`` family's dense box, with tangents, e = 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.generate import Layout, ball_pairs, family_entry, libm
from qpbench.problem.generate import generate as generate_frictionless
from qpbench.problem.jacobian import contact_jacobian

GRAVITY = 9.81
STEP = 0.01


def tangent(normals: np.ndarray) -> np.ndarray:
    """t = (-n_y, n_x) per row.

    Parameters
    ----------
    normals : np.ndarray
        Unit normals, shape (n, 2) (or 2n entries).

    Returns
    -------
    np.ndarray
        The tangents, shape (n, 2).
    """
    normals = np.asarray(normals, dtype=float).reshape(-1, 2)
    return np.column_stack([-normals[:, 1], normals[:, 0]])


def tangents_of(G: sp.spmatrix) -> sp.csc_matrix:
    """T of a ball2d G (2 dofs per ball), its normals turned into tangents.

    Each ball's (n_x, n_y) rows become (-n_y, n_x), with the same sign pattern, so
    ``t = (-n_y, n_x)`` on the first body and ``-t`` on the other.

    Parameters
    ----------
    G : sp.spmatrix
        Contact normals of balls, (2 balls) x n.

    Returns
    -------
    sp.csc_matrix
        T, of G's shape.
    """
    balls = G.shape[0] // 2
    rotation = sp.kron(sp.identity(balls), sp.csr_matrix([[0.0, -1.0], [1.0, 0.0]]))
    return sp.csc_matrix(rotation @ G)


@dataclass
class Draft:
    """What a family builds: G and T (ball2d or 3-dof discs), masses, v-, mu, e, metadata."""

    G: sp.csc_matrix
    T: sp.csc_matrix
    m_inv: np.ndarray
    v_minus: np.ndarray
    mu: np.ndarray | float
    restitution: np.ndarray | float
    dofs_per_body: int = 2
    metadata: dict[str, Any] = field(default_factory=dict)


def balls_draft(layout: Layout, mu: np.ndarray | float,
                extra: list[tuple[int, int, np.ndarray]] | None = None) -> Draft:
    """The contacts of ``layout`` that approach or rest (``G^T v- <= 0``), with tangents.

    The contacts are the ball pairs, the planes, then ``extra`` (a, b, n) with b = -1 for a
    static body.

    Parameters
    ----------
    layout : Layout
        The balls and planes.
    mu : np.ndarray or float
        Friction coefficients, one for all contacts or one per contact before the
        approaching ones are kept.
    extra : list of (int, int, np.ndarray) or None, optional
        Contacts added after the ball pairs and planes; None (the default) for none.

    Returns
    -------
    Draft
        G, T, M^-1, v-, mu and the layout's restitution of the kept contacts.
    """
    body_a, body_b, normals = [np.zeros(0, int)], [np.zeros(0, int)], [np.zeros((0, 2))]
    pairs = ball_pairs(layout)
    if len(pairs):
        delta = layout.positions[pairs[:, 0]] - layout.positions[pairs[:, 1]]
        body_a.append(pairs[:, 0])
        body_b.append(pairs[:, 1])
        normals.append(delta / np.linalg.norm(delta, axis=1)[:, None])
    for point, normal in zip(layout.plane_points, layout.plane_normals, strict=True):
        touching = np.flatnonzero((layout.positions - point) @ normal
                                  <= layout.radii + layout.touch_tolerance)
        body_a.append(touching)
        body_b.append(np.full(len(touching), -1))
        normals.append(np.tile(normal, (len(touching), 1)))
    for a, b, normal in extra or []:
        body_a.append(np.array([a]))
        body_b.append(np.array([b]))
        normals.append(np.asarray(normal, dtype=float)[None, :])
    a, b, n = np.concatenate(body_a), np.concatenate(body_b), np.concatenate(normals)
    balls = layout.positions.shape[0]
    G = contact_jacobian(a, b, n, balls, 2)
    T = contact_jacobian(a, b, tangent(n), balls, 2)
    v_minus = layout.velocities.reshape(-1)
    keep = np.flatnonzero(G.T @ v_minus <= 1e-12)
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (G.shape[1],))[keep]
    return Draft(G[:, keep], T[:, keep], np.repeat(1.0 / layout.masses, 2), v_minus, mu,
                 layout.restitution)


def _resting(balls: int) -> np.ndarray:
    velocities = np.zeros((balls, 2))
    velocities[:, 1] = -GRAVITY * STEP
    return velocities


def incline(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """Balls resting on a plane tilted at theta, each with its own mu (module docstring).

    Parameters
    ----------
    size : int
        The number of balls.
    rng : np.random.Generator
        The draws of theta and the margins of mu.
    seed : int
        The problem's seed: 0 gives theta 0.3 and fixed margins; it also sets which balls
        stick.

    Returns
    -------
    Draft
        The problem, with ``theta``, ``friction_angles`` and ``sticks`` in its metadata.
    """
    theta = 0.3 if seed == 0 else float(rng.uniform(0.1, 0.6))
    normal = np.array([-math.sin(theta), math.cos(theta)])
    along = np.array([math.cos(theta), math.sin(theta)])
    positions = np.array([3.0 * i * along + normal for i in range(size)])
    sticks = [(seed + i) % 2 == 0 for i in range(size)]
    margin = rng.uniform(0.1, 0.4, size) if seed else np.full(size, 0.25)
    # ball i sticks iff theta <= atan(mu_i): mu on the far side of tan(theta) for each
    mu = np.where(sticks, math.tan(theta) / (1.0 - margin), math.tan(theta) * (1.0 - margin))
    layout = Layout(positions, _resting(size), np.ones(size), np.ones(size),
                    np.zeros((1, 2)), normal[None, :], restitution=0.0)
    draft = balls_draft(layout, 0.0)
    draft.mu = mu
    draft.metadata = {"theta": theta, "friction_angles": libm(math.atan, mu).tolist(),
                      "sticks": sticks}
    return draft


def rough_floor(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """Rigid discs bouncing with spin on a rough floor, apart from each other (module docstring).

    Parameters
    ----------
    size : int
        The number of discs.
    rng : np.random.Generator
        The draws of radii, masses, velocities, spins, mu and e.
    seed : int
        Unused (the draws come from ``rng``).

    Returns
    -------
    Draft
        The problem (3 dofs per disc), with ``radii`` and ``sticks`` in its metadata.
    """
    radius = rng.uniform(0.5, 1.5, size)
    mass = rng.uniform(0.5, 2.0, size)
    inertia = 0.5 * mass * radius ** 2
    velocity = np.column_stack([rng.uniform(-2.0, 2.0, size), -rng.uniform(0.5, 3.0, size)])
    spin = rng.uniform(-5.0, 5.0, size)
    mu = rng.uniform(0.1, 0.8, size)
    restitution = rng.uniform(0.0, 0.8, size)
    rows, columns, normal_values, tangent_values = [], [], [], []
    for i in range(size):  # floor normal (0, 1), tangent (-1, 0), arm term r x t = -R
        rows += [3 * i, 3 * i + 1, 3 * i + 2]
        columns += [i, i, i]
        normal_values += [0.0, 1.0, 0.0]
        tangent_values += [-1.0, 0.0, -radius[i]]
    shape = (3 * size, size)
    G = sp.csc_matrix((normal_values, (rows, columns)), shape=shape)
    T = sp.csc_matrix((tangent_values, (rows, columns)), shape=shape)
    m_inv = np.column_stack([1.0 / mass, 1.0 / mass, 1.0 / inertia]).reshape(-1)
    v_minus = np.column_stack([velocity, spin]).reshape(-1)
    u_normal, u_tangential = G.T @ v_minus, T.T @ v_minus
    sticks = np.abs(u_tangential) <= 3.0 * mu * (1.0 + restitution) * np.abs(u_normal)
    return Draft(G, T, m_inv, v_minus, mu, restitution, dofs_per_body=3,
                 metadata={"radii": radius.tolist(), "sticks": sticks.tolist()})


def pyramid(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """A triangle of touching unit balls on a rough floor, resting (module docstring).

    Parameters
    ----------
    size : int
        The number of rows.
    rng : np.random.Generator
        The draws of the sideways kick and mu.
    seed : int
        The problem's seed: 0 gives no kick and mu 0.5.

    Returns
    -------
    Draft
        The problem.
    """
    centres = [(2.0 * i + row, 1.0 + row * np.sqrt(3.0))
               for row in range(size) for i in range(size - row)]
    positions = np.array(centres, dtype=float)
    balls = len(positions)
    velocities = _resting(balls)
    if seed:
        velocities[:, 0] += rng.uniform(-0.5, 0.5, balls) * GRAVITY * STEP
    mu = 0.5 if seed == 0 else float(rng.uniform(0.1, 0.9))
    layout = Layout(positions, velocities, np.ones(balls), np.ones(balls), np.zeros((1, 2)),
                    np.array([[0.0, 1.0]]), restitution=0.0)
    return balls_draft(layout, mu)


def wedge(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """Balls dropped with e > 0 into a V steeper than the friction angle (module docstring).

    Parameters
    ----------
    size : int
        The number of balls, each in its own V.
    rng : np.random.Generator
        The draws of mu, face angles, e and velocities.
    seed : int
        The problem's seed: 0 gives the canonical case (mu 0.8, e 0.5, straight down).

    Returns
    -------
    Draft
        The problem, with ``face_angles`` and ``friction_angles`` in its metadata.
    """
    positions = np.column_stack([10.0 * np.arange(size), np.zeros(size)])
    mu = 0.8 if seed == 0 else rng.uniform(0.5, 1.0, size)
    mu = np.broadcast_to(mu, (size,))
    # face normals phi above horizontal, phi below the friction angle: jammed
    phi = libm(math.atan, mu) * (0.5 if seed == 0 else rng.uniform(0.3, 0.8, size))
    restitution = 0.5 if seed == 0 else float(rng.uniform(0.3, 0.9))
    down = np.ones(size) if seed == 0 else rng.uniform(0.5, 2.0, size)
    # sideways less than the faces' slope allows, so that both faces are approached
    sideways = np.zeros(size) if seed == 0 else rng.uniform(-0.5, 0.5, size) * libm(math.tan,
                                                                                    phi)
    velocities = np.column_stack([sideways * down, -down])
    extra = []
    for i in range(size):
        extra.append((i, -1, np.array([math.cos(phi[i]), math.sin(phi[i])])))
        extra.append((i, -1, np.array([-math.cos(phi[i]), math.sin(phi[i])])))
    layout = Layout(positions, velocities, np.ones(size), np.ones(size), restitution=restitution)
    draft = balls_draft(layout, np.repeat(mu, 2), extra)
    draft.metadata = {"face_angles": phi.tolist(), "friction_angles": libm(math.atan, mu).tolist()}
    return draft


def friction_mass_ratio(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """A row of touching balls on a rough floor with masses log-uniform over 1e-3 .. 1e3.

    Parameters
    ----------
    size : int
        The number of balls.
    rng : np.random.Generator
        The draws of velocities, masses and mu.
    seed : int
        Unused (the draws come from ``rng``).

    Returns
    -------
    Draft
        The problem.
    """
    positions = np.column_stack([2.0 * np.arange(size), np.ones(size)])
    velocities = np.column_stack([rng.uniform(-1.0, 1.0, size), -rng.uniform(0.5, 1.0, size)])
    masses = libm(lambda exponent: 10.0 ** exponent, rng.uniform(-3.0, 3.0, size))
    layout = Layout(positions, velocities, np.ones(size), masses, np.zeros((1, 2)),
                    np.array([[0.0, 1.0]]), restitution=0.0)
    return balls_draft(layout, rng.uniform(0.2, 0.8))


def rough_box(size: int, rng: np.random.Generator, seed: int) -> Draft:
    """The frictionless ``box`` family's dense box, with tangents, e = 0.

    Parameters
    ----------
    size : int
        The number of balls.
    rng : np.random.Generator
        The draws of mu, one per contact in [0.1, 0.6].
    seed : int
        The seed of the ``box`` problem.

    Returns
    -------
    Draft
        The problem.
    """
    box = generate_frictionless("box", size=size, seed=seed, restitution=0.0)[0]
    mu = rng.uniform(0.1, 0.6, box.n_contacts)
    return Draft(box.G, tangents_of(box.G), box.m_inv, box.v_minus, mu, 0.0)


Builder = Callable[[int, np.random.Generator, int], Draft]

# family -> (builder, default size)
FRICTION_FAMILIES: dict[str, tuple[Builder, int]] = {
    "incline": (incline, 2),
    "rough-floor": (rough_floor, 2),
    "pyramid": (pyramid, 2),
    "wedge": (wedge, 1),
    "friction-mass-ratio": (friction_mass_ratio, 4),
    "rough-box": (rough_box, 30),
}


def generate(family: str, size: int | None = None, seed: int = 0, count: int = 1,
             restitution: float | None = None, mu: float | None = None
             ) -> list[FrictionalProblem]:
    """``count`` problems of the frictional ``family``; problem i uses seed ``seed + i``.

    ``restitution`` and ``mu`` replace the family's own values on every contact.

    Parameters
    ----------
    family : str
        One of :data:`FRICTION_FAMILIES`.
    size : int or None, optional
        The family's size; None (the default) for its default size.
    seed : int, optional
        The first problem's seed; 0 by default.
    count : int, optional
        The number of problems; 1 by default.
    restitution, mu : float or None, optional
        Values for every contact; None (the default) keeps the family's own.

    Returns
    -------
    list of FrictionalProblem
        The problems, named ``FAMILY-SIZE-sSEED``.

    Raises
    ------
    QpbenchError
        When the family is unknown or the size below 1.
    """
    builder, size = family_entry(FRICTION_FAMILIES, family, size, "frictional family")
    problems = []
    for index in range(count):
        problem_seed = seed + index
        draft = builder(size, np.random.default_rng(problem_seed), problem_seed)
        if restitution is not None:
            draft.restitution = restitution
        if mu is not None:
            draft.mu = mu
        name = f"{family}-{size}-s{problem_seed}"
        metadata = {"family": family, "size": size, "seed": problem_seed,
                    "restitution": np.asarray(draft.restitution, dtype=float).tolist(),
                    "mu": np.asarray(draft.mu, dtype=float).tolist(), **draft.metadata}
        problems.append(FrictionalProblem.build(
            name, draft.G, draft.T, draft.m_inv, draft.v_minus, draft.mu, draft.restitution,
            family=family, source="generated", metadata=metadata,
            dofs_per_body=draft.dofs_per_body))
    return problems
