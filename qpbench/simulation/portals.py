"""Planar and Lees-Edwards portals (periodic boundaries), as SCISim's ``PlanarPortal`` has them.

A portal pairs two planes A and B (taken out of the scene's walls). Plane k has a point p_k,
a normal n_k and the tangent ``t_k = (-n_y, n_x)``. A point x behind plane A
(``n_A . (x - p_A) < 0``) maps to B: with ``a = n_A . (p_A - x)`` and
``s = t_A . (dx t_A + p_A - x)``, wrapped into [-bounds, bounds) for a Lees-Edwards portal,
``x' = p_B + a n_B + s t_B`` (and the same from B to A). A plain portal has dx = 0 and no
wrap; a Lees-Edwards portal slides: at the start of step k (time ``t = (k + 1) h``, as
SCISim's ``updateMovingPortals``) ``dx = v t - 2 bounds floor((v t + bounds) / (2 bounds))``.

* End of step: a centre behind a plane moves through it; through a Lees-Edwards portal its
  velocity also gains ``-v t_k`` (k the plane it was behind).
* Contacts: a body touching a plane at the predicted positions (ball2d: ``n . (x1 - p) <= r``;
  rigidbody2d: a corner of its box ``x1 +- r`` on or behind the plane) gets a copy on the other
  side; a copy meeting a body (or another copy) at x1 gives one teleported contact per pair
  of bodies, with the normal and arms of the copies at x0 (``TeleportedBallBallConstraint``,
  ``TeleportedCircleCircleConstraint``). Across a Lees-Edwards portal the contact has the
  kinematic kick ``k = -v t_k`` of the copied body (negated when that is the first body), and
  the relative velocity ``v_a - v_b - k`` puts ``n_rel = -n . k`` and ``d_rel = -t . k`` in the
  problem (``KinematicKick*Constraint``).
"""

from __future__ import annotations

import math

import numpy as np

from qpbench.scenes.model import Portal
from qpbench.simulation.contacts import BODY_BODY, Contacts


def offsets(portals: list[Portal], t: float) -> list[float]:
    """dx of each portal at time t.

    Parameters
    ----------
    portals : list of Portal
        The scene's portals.
    t : float
        The time, in seconds.

    Returns
    -------
    list of float
        Each portal's offset: 0 for a plain portal, the wrapped slide of a Lees-Edwards one.
    """
    out = []
    for portal in portals:
        if portal.v == 0.0:
            out.append(0.0)
            continue
        shift = portal.v * t
        out.append(shift - 2.0 * math.floor((shift + portal.bounds) / (2.0 * portal.bounds))
                   * portal.bounds)
    return out


def _tangent(n: np.ndarray) -> np.ndarray:
    return np.array([-n[1], n[0]])


def through(portal: Portal, dx: float, plane: int, x: np.ndarray) -> np.ndarray:
    """Points x (m, 2) moved through plane 0 (A) or 1 (B) of the portal.

    Parameters
    ----------
    portal : Portal
        The portal.
    dx : float
        Its offset (:func:`offsets`).
    plane : int
        0 to move from plane A to B, 1 from B to A.
    x : np.ndarray
        (m, 2) points behind that plane.

    Returns
    -------
    np.ndarray
        (m, 2) the points on the other side.
    """
    src_p, src_n = (portal.point_a, portal.normal_a) if plane == 0 else (portal.point_b,
                                                                         portal.normal_b)
    dst_p, dst_n = (portal.point_b, portal.normal_b) if plane == 0 else (portal.point_a,
                                                                         portal.normal_a)
    src_t, dst_t = _tangent(src_n), _tangent(dst_n)
    depth = (src_p - x) @ src_n
    along = (dx * src_t + src_p - x) @ src_t
    if portal.v != 0.0:
        along = along - 2.0 * np.floor((along + portal.bounds) / (2.0 * portal.bounds)) \
            * portal.bounds
    return dst_p + depth[:, None] * dst_n + along[:, None] * dst_t


def kick(portal: Portal, plane: int) -> np.ndarray:
    """The velocity a body gains through the plane: ``-v t``.

    Parameters
    ----------
    portal : Portal
        The portal.
    plane : int
        0 for plane A, 1 for plane B.

    Returns
    -------
    np.ndarray
        (2,) the velocity gained; zero for a plain portal.
    """
    n = portal.normal_a if plane == 0 else portal.normal_b
    return -portal.v * _tangent(n)


def enforce(portals: list[Portal], dxs: list[float], x: np.ndarray, v: np.ndarray) -> None:
    """Move centres behind a portal plane through it (in place), as SCISim's end of step.

    Parameters
    ----------
    portals : list of Portal
        The scene's portals.
    dxs : list of float
        Their offsets (:func:`offsets`).
    x, v : np.ndarray
        (bodies, 2) centres and velocities, updated in place (velocities gain the kick of a
        Lees-Edwards portal).
    """
    for portal, dx in zip(portals, dxs, strict=True):
        behind_a = (x - portal.point_a) @ portal.normal_a < 0.0
        behind_b = ~behind_a & ((x - portal.point_b) @ portal.normal_b < 0.0)
        for plane, behind in ((0, behind_a), (1, behind_b)):
            if np.any(behind):
                x[behind] = through(portal, dx, plane, x[behind])
                if portal.v != 0.0:
                    v[behind] += kick(portal, plane)


def touching(portal: Portal, x1: np.ndarray, radii: np.ndarray, aabb: bool
             ) -> tuple[np.ndarray, np.ndarray]:
    """(bodies, plane) touching plane A (checked first) or B at x1.

    Parameters
    ----------
    portal : Portal
        The portal.
    x1 : np.ndarray
        (bodies, 2) predicted centres.
    radii : np.ndarray
        (bodies,) radii.
    aabb : bool
        Whether a body reaches a plane with its axis-aligned box ``x1 +- r`` (rigidbody2d)
        rather than its circle (ball2d).

    Returns
    -------
    tuple of (np.ndarray, np.ndarray)
        The touching bodies' indices and, for each, 0 (plane A) or 1 (plane B).
    """
    def near(point: np.ndarray, normal: np.ndarray) -> np.ndarray:
        reach = radii * (abs(normal[0]) + abs(normal[1])) if aabb else radii
        return (x1 - point) @ normal <= reach
    on_a = near(portal.point_a, portal.normal_a)
    on_b = ~on_a & near(portal.point_b, portal.normal_b)
    bodies = np.flatnonzero(on_a | on_b)
    return bodies, np.where(on_a[bodies], 0, 1)


def teleported_contacts(portals: list[Portal], dxs: list[float], x0: np.ndarray,
                        x1: np.ndarray, radii: np.ndarray, fixed: np.ndarray, aabb: bool
                        ) -> tuple[Contacts, np.ndarray]:
    """The contacts across portals and their kinematic kicks (n, 2).

    Parameters
    ----------
    portals : list of Portal
        The scene's portals.
    dxs : list of float
        Their offsets (:func:`offsets`).
    x0, x1 : np.ndarray
        (bodies, 2) centres at the start and predicted at the end of the step.
    radii : np.ndarray
        (bodies,) radii.
    fixed : np.ndarray
        (bodies,) bool: kinematic bodies (a pair of two is left out).
    aabb : bool
        Whether bodies reach a plane with their axis-aligned box (see :func:`touching`).

    Returns
    -------
    tuple of (Contacts, np.ndarray)
        One BODY_BODY contact per pair of bodies meeting across a portal (normal and arms of the
        copies at x0), and the (n, 2) kick of each. A pair whose centres coincide through the
        portal has no normal and is left out (an inert constraint, as ``contacts.ball_ball``
        leaves out two balls with one centre).
    """
    n_bodies = x1.shape[0]
    # copies: (body, portal, plane), in SCISim's order (portal by portal, body by body)
    copies: list[tuple[int, int, int]] = []
    for index, portal in enumerate(portals):
        bodies, planes = touching(portal, x1, radii, aabb)
        copies.extend((int(b), index, int(p)) for b, p in zip(bodies, planes, strict=True))
    if not copies:
        return Contacts.empty(), np.zeros((0, 2))

    def centre(x: np.ndarray, slot: int) -> np.ndarray:
        if slot < n_bodies:
            return x[slot]
        body, index, plane = copies[slot - n_bodies]
        return through(portals[index], dxs[index], plane, x[body][None, :])[0]

    def body_of(slot: int) -> int:
        return slot if slot < n_bodies else copies[slot - n_bodies][0]

    def overlap(xa: np.ndarray, xb: np.ndarray, ra: float, rb: float) -> bool:
        d = xa - xb
        return float(d @ d) <= (ra + rb) ** 2

    candidates = []
    for k in range(len(copies)):
        slot = n_bodies + k
        for other in range(slot):
            if body_of(other) != body_of(slot):
                candidates.append((other, slot))
    candidates.sort()
    chosen: dict[tuple[int, int], tuple[int, int]] = {}
    for first, second in candidates:
        a, b = body_of(first), body_of(second)
        key = (min(a, b), max(a, b))
        if key in chosen or (fixed[a] and fixed[b]):
            continue
        if first >= n_bodies and overlap(x1[a], x1[b], radii[a], radii[b]):
            continue  # found without the portal
        if overlap(centre(x1, first), centre(x1, second), radii[a], radii[b]):
            chosen[key] = (first, second) if a < b else (second, first)
    rows_a, rows_b, normals, arms, kicks = [], [], [], [], []
    for (a, b), (slot_a, slot_b) in sorted(chosen.items()):
        xa, xb = centre(x0, slot_a), centre(x0, slot_b)
        d = xa - xb
        length = math.hypot(d[0], d[1])
        if not length > 0.0:
            continue  # one centre through the portal: no normal, an inert pair (ball_ball's rule)
        normal = d / length
        share = radii[a] / (radii[a] + radii[b])
        arms.append(np.concatenate([share * (xb - xa), (share - 1.0) * (xb - xa)]))
        k = np.zeros(2)
        for slot, sign in ((slot_b, 1.0), (slot_a, -1.0)):
            if slot >= n_bodies:
                _, index, plane = copies[slot - n_bodies]
                if portals[index].v != 0.0:
                    k = sign * kick(portals[index], plane)
                    break
        rows_a.append(a)
        rows_b.append(b)
        normals.append(normal)
        kicks.append(k)
    if not rows_a:
        return Contacts.empty(), np.zeros((0, 2))
    count = len(rows_a)
    return (Contacts(np.array(rows_a, dtype=np.int64), np.array(rows_b, dtype=np.int64),
                     np.full(count, BODY_BODY, dtype=np.int64), np.full(count, -1, dtype=np.int64),
                     np.array(normals), np.array(arms), np.full(count, 3, dtype=np.int64)),
            np.array(kicks))
