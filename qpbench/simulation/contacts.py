"""Contacts of one step and the matrix G they define.

* ball-ball (a, b): active when the balls overlap at the start of the step or
  come within ``r_a + r_b`` of each other while moving linearly from their start
  to their predicted positions (continuous detection); normal
  ``n_ab = (x_a - x_b) / |x_a - x_b|`` at the start of the step; G gets ``+n_ab``
  in a's rows and ``-n_ab`` in b's.
* ball-plane: active when ``n . (x1 - p) <= r`` at the predicted position x1;
  G gets the plane normal n in the ball's rows.
* ball-drum: active when ``|x1 - c| >= R - r`` at the predicted position; G gets
  ``(c - x0) / |c - x0|`` (towards the drum centre) in the ball's rows.

A contact between two kinematic (fixed) bodies, or a kinematic body and a
boundary, cannot take an impulse and is left out.

For friction each contact also has a tangent ``t = (-n_y, n_x)`` and a contact point p at
the start positions, where SCISim puts it: ``p = (r_b x_a + r_a x_b) / (r_a + r_b)``
between two free circles (``RigidBody2DSim.cpp``), on the free body's surface,
``x - r n_out``, against a kinematic body, a plane or a drum; T (:meth:`Contacts.tangent_jacobian`)
carries the arms ``(p - x) x t`` on rigid bodies' rotation rows. ``gaps`` are SCISim's
``evaluateGapFunction`` values (negative when overlapping).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from qpbench.errors import UnsupportedError
from qpbench.problem.jacobian import contact_jacobian, tangent_jacobian, tangents
from qpbench.simulation.broad_phase import candidate_pairs, swept_boxes

BALL, PLANE, DRUM = 0, 1, 2
BOX_PLANE, BODY_BODY = 3, 4  # box contacts (qpbench.simulation.boxes): arms stored per contact


@dataclass
class Contacts:
    """n contacts: body a, body b (-1 for a boundary), kind, boundary index, unit normal."""

    body_a: np.ndarray  # (n,) int
    body_b: np.ndarray  # (n,) int, -1 for planes and drums
    kind: np.ndarray  # (n,) BALL, PLANE or DRUM
    boundary: np.ndarray  # (n,) index of the plane or drum, -1 for ball-ball
    normals: np.ndarray  # (n, 2)
    # (n, 4): the arms r_a, r_b (contact point minus each centre, at x0) of box contacts
    # (BOX_PLANE, BODY_BODY; r_b unused for a plane); NaN rows for the circle rules
    arms: np.ndarray | None = None
    point: np.ndarray | None = None  # (n,) int: which point of a pair or vertex of a box

    def __post_init__(self) -> None:
        n = self.body_a.shape[0]
        if self.arms is None:
            self.arms = np.full((n, 4), np.nan)
        if self.point is None:
            self.point = np.zeros(n, dtype=np.int64)

    @classmethod
    def empty(cls) -> Contacts:
        """No contacts.

        Returns
        -------
        Contacts
            Zero contacts, with arrays of the right dtypes and shapes.
        """
        none = np.zeros(0, dtype=np.int64)
        return cls(none, none.copy(), none.copy(), none.copy(), np.zeros((0, 2)))

    @property
    def boxed(self) -> np.ndarray:
        """(n,) bool: contacts whose arms are stored (box contacts)."""
        assert self.arms is not None
        return ~np.isnan(self.arms[:, 0])

    @property
    def count(self) -> int:
        return int(self.body_a.shape[0])

    def keys(self) -> np.ndarray:
        """An integer identity per contact (kind, a, b or boundary), stable across steps.

        Box contacts also carry their point number, so each vertex or clipped point is its own.

        Returns
        -------
        np.ndarray
            (n,) int64 keys: kind in bits 60 and up, body a in bits 30 to 59, then b or the
            boundary (shifted by two bits for box contacts, with the point number below).
        """
        other = np.where((self.kind == BALL) | (self.kind == BODY_BODY), self.body_b,
                         self.boundary)
        boxed = (self.kind == BOX_PLANE) | (self.kind == BODY_BODY)
        assert self.point is not None
        other = np.where(boxed, (other << 2) | self.point, other)
        return (self.kind.astype(np.int64) << 60) | (self.body_a.astype(np.int64) << 30) | other

    def jacobian(self, bodies: int, dofs_per_body: int) -> sp.csc_matrix:
        """G, the gradients of the contacts' gaps, as SCISim builds them.

        Column k is the gradient of the gap of contact k; box contacts add ``r_a x n`` (and
        ``-(r_b x n)``) on the rotation rows, as SCISim's
        ``BodyBodyConstraint``/``StaticPlaneBodyConstraint::evalH``.

        Parameters
        ----------
        bodies : int
            Number of bodies.
        dofs_per_body : int
            2 for balls (x, y), 3 for rigid bodies (x, y, theta).

        Returns
        -------
        sp.csc_matrix
            G, (bodies * dofs_per_body, n).
        """
        G = contact_jacobian(self.body_a, self.body_b, self.normals, bodies, dofs_per_body)
        boxed = self.boxed
        if dofs_per_body != 3 or not np.any(boxed):
            return G
        return sp.csc_matrix(G + self._arm_matrix(self.normals, boxed, G.shape))

    def _arm_matrix(self, directions: np.ndarray, boxed: np.ndarray, shape: tuple[int, int]
                    ) -> sp.csc_matrix:
        """The rotation-row terms ``r_a x d`` and ``-(r_b x d)`` of the box contacts."""
        assert self.arms is not None
        k = np.flatnonzero(boxed)
        a, b = self.body_a[k], self.body_b[k]
        two = b >= 0
        value_a = _cross(self.arms[k, 0:2], directions[k])
        value_b = -_cross(self.arms[k[two], 2:4], directions[k[two]])
        return sp.csc_matrix((np.concatenate([value_a, value_b]),
                              (np.concatenate([3 * a + 2, 3 * b[two] + 2]),
                               np.concatenate([k, k[two]]))), shape=shape)

    def contact_points(self, x0: np.ndarray, radii: np.ndarray, fixed: np.ndarray
                       ) -> np.ndarray:
        """p per contact at the start positions x0 (module docstring).

        Parameters
        ----------
        x0 : np.ndarray
            (bodies, 2) centres at the start of the step.
        radii : np.ndarray
            (bodies,) radii.
        fixed : np.ndarray
            (bodies,) bool: kinematic bodies.

        Returns
        -------
        np.ndarray
            (n, 2) contact points.
        """
        a, b = self.body_a, self.body_b
        points = x0[a] - radii[a][:, None] * self.normals
        pair = self.kind == BALL
        if np.any(pair):
            pa, pb = a[pair], b[pair]
            free = ~fixed[pa] & ~fixed[pb]
            both = np.flatnonzero(pair)[free]
            ra, rb = radii[a[both]], radii[b[both]]
            points[both] = (rb[:, None] * x0[a[both]] + ra[:, None] * x0[b[both]]) / (
                ra + rb)[:, None]
            against_a = np.flatnonzero(pair)[fixed[pa] & ~fixed[pb]]  # b is the free body
            points[against_a] = (x0[b[against_a]]
                                 + radii[b[against_a]][:, None] * self.normals[against_a])
        return points

    def tangent_jacobian(self, x0: np.ndarray, radii: np.ndarray, fixed: np.ndarray,
                         bodies: int, dofs_per_body: int) -> sp.csc_matrix:
        """T (bodies * dofs_per_body x n): tangents, with the arms on rotation rows.

        Circle contacts take the arm ``(p - x) x t`` from :meth:`contact_points`; box contacts
        their stored arms.

        Parameters
        ----------
        x0 : np.ndarray
            (bodies, 2) centres at the start of the step.
        radii : np.ndarray
            (bodies,) radii.
        fixed : np.ndarray
            (bodies,) bool: kinematic bodies.
        bodies : int
            Number of bodies.
        dofs_per_body : int
            2 for balls, 3 for rigid bodies (arms on the rotation rows).

        Returns
        -------
        sp.csc_matrix
            T, (bodies * dofs_per_body, n).
        """
        if dofs_per_body != 3:
            return tangent_jacobian(self.body_a, self.body_b, self.normals, bodies,
                                    dofs_per_body)
        t = tangents(self.normals)
        points = self.contact_points(x0, radii, fixed)
        arm_a = _cross(points - x0[self.body_a], t)
        arm_b = np.zeros(self.count)
        pair = self.body_b >= 0
        arm_b[pair] = _cross(points[pair] - x0[self.body_b[pair]], t[pair])
        boxed = self.boxed
        if np.any(boxed):  # the stored arms (arm_a/arm_b of the circle rules unused there)
            assert self.arms is not None
            arm_a[boxed] = _cross(self.arms[boxed, 0:2], t[boxed])
            two = boxed & pair
            arm_b[two] = _cross(self.arms[two, 2:4], t[two])
        return tangent_jacobian(self.body_a, self.body_b, self.normals, bodies,
                                dofs_per_body, arm_a, arm_b)

    def gaps(self, x0: np.ndarray, radii: np.ndarray, plane_points: np.ndarray,
             plane_normals: np.ndarray, drum_centers: np.ndarray, drum_radii: np.ndarray
             ) -> np.ndarray:
        """The gap of each contact at x0 (negative when overlapping).

        ``|x_a - x_b| - r_a - r_b`` between balls, ``n . (x - p) - r`` for a plane,
        ``R - r - |x - c|`` for a drum; zero for box contacts.

        Parameters
        ----------
        x0 : np.ndarray
            (bodies, 2) centres at the start of the step.
        radii : np.ndarray
            (bodies,) radii.
        plane_points, plane_normals : np.ndarray
            (planes, 2) a point and the unit normal of each static plane.
        drum_centers : np.ndarray
            (drums, 2) the drums' centres.
        drum_radii : np.ndarray
            (drums,) the drums' radii.

        Returns
        -------
        np.ndarray
            (n,) gaps.
        """
        a, b, k = self.body_a, self.body_b, self.boundary
        gaps = np.zeros(self.count)
        pair = self.kind == BALL
        gaps[pair] = (np.hypot(*(x0[a[pair]] - x0[b[pair]]).T)
                      - radii[a[pair]] - radii[b[pair]])
        plane = self.kind == PLANE
        gaps[plane] = (np.einsum("ij,ij->i", x0[a[plane]] - plane_points[k[plane]],
                                 plane_normals[k[plane]]) - radii[a[plane]])
        drum = self.kind == DRUM
        gaps[drum] = (drum_radii[k[drum]] - radii[a[drum]]
                      - np.hypot(*(x0[a[drum]] - drum_centers[k[drum]]).T))
        return gaps

    @staticmethod
    def concatenate(parts: list[Contacts]) -> Contacts:
        """The contacts of ``parts``, one after another.

        Parameters
        ----------
        parts : list of Contacts
            The contact sets, at least one.

        Returns
        -------
        Contacts
            Every contact of every part, in order.
        """
        return Contacts(*(np.concatenate([getattr(part, name) for part in parts])
                          for name in ("body_a", "body_b", "kind", "boundary", "normals",
                                       "arms", "point")))


def _cross(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """u x w = u_x w_y - u_y w_x, row by row."""
    return u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]


def ball_ball(x0: np.ndarray, x1: np.ndarray, radii: np.ndarray, fixed: np.ndarray,
              coincident: list[tuple[int, int]] | None = None) -> Contacts:
    """Ball-ball contacts by continuous detection over the step (see the module docstring).

    The distance of the relative position ``d(t) = d0 + t (d1 - d0)``, t in [0, 1], is
    smallest at ``t* = clip(-d0.(d1 - d0) / |d1 - d0|^2, 0, 1)``; the pair is active when
    ``|d(t*)| <= r_a + r_b``. A pair with the same centre has no normal: SCISim's is zero,
    an inert constraint; it is left out and appended to ``coincident`` when given.

    Parameters
    ----------
    x0, x1 : np.ndarray
        (balls, 2) centres at the start and predicted at the end of the step.
    radii : np.ndarray
        (balls,) radii.
    fixed : np.ndarray
        (balls,) bool: kinematic balls (a pair of two is left out).
    coincident : list of (int, int) or None, optional
        Receives the pairs left out for sharing a centre; None (default) drops them silently.

    Returns
    -------
    Contacts
        The active pairs (a < b), normals from b to a at x0.
    """
    lower, upper = swept_boxes(x0, x1, radii)
    pairs = candidate_pairs(lower, upper)
    if pairs.shape[0] == 0:
        return Contacts.empty()
    a, b = pairs[:, 0], pairs[:, 1]
    movable = ~(fixed[a] & fixed[b])
    a, b = a[movable], b[movable]
    d0 = x0[a] - x0[b]
    motion = (x1[a] - x1[b]) - d0
    reach = radii[a] + radii[b]
    motion_sq = np.einsum("ij,ij->i", motion, motion)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(motion_sq > 0, -np.einsum("ij,ij->i", d0, motion) / motion_sq, 0.0)
    t = np.clip(t, 0.0, 1.0)
    closest = d0 + t[:, None] * motion
    active = np.einsum("ij,ij->i", closest, closest) <= reach**2
    a, b, d0 = a[active], b[active], d0[active]
    length = np.hypot(d0[:, 0], d0[:, 1])
    same = length <= 0.0
    if np.any(same):
        # SCISim normalises a zero vector to zero: a zero normal, a constraint that does
        # nothing; qpbench leaves such a pair out of the problem and tells the caller
        if coincident is not None:
            coincident.extend(zip(a[same].tolist(), b[same].tolist(), strict=True))
        a, b, d0, length = a[~same], b[~same], d0[~same], length[~same]
    none = np.full(a.shape[0], -1, dtype=np.int64)
    return Contacts(a.astype(np.int64), b.astype(np.int64), np.full_like(none, BALL), none,
                    d0 / length[:, None])


def ball_plane(x1: np.ndarray, radii: np.ndarray, fixed: np.ndarray, points: np.ndarray,
               normals: np.ndarray) -> Contacts:
    """Ball-plane contacts at the predicted positions: ``n . (x1 - p) <= r``.

    Parameters
    ----------
    x1 : np.ndarray
        (balls, 2) predicted centres.
    radii : np.ndarray
        (balls,) radii.
    fixed : np.ndarray
        (balls,) bool: kinematic balls, left out.
    points, normals : np.ndarray
        (planes, 2) a point and the unit normal of each plane.

    Returns
    -------
    Contacts
        Plane by plane, the balls touching it, with the plane's normal.
    """
    parts = []
    for index, (point, normal) in enumerate(zip(points, normals, strict=True)):
        balls = np.flatnonzero(((x1 - point) @ normal <= radii) & ~fixed)
        parts.append(Contacts(balls, np.full_like(balls, -1), np.full_like(balls, PLANE),
                              np.full_like(balls, index), np.tile(normal, (balls.shape[0], 1))))
    return Contacts.concatenate(parts) if parts else Contacts.empty()


def ball_drum(x0: np.ndarray, x1: np.ndarray, radii: np.ndarray, fixed: np.ndarray,
              centers: np.ndarray, drum_radii: np.ndarray, where: str = "") -> Contacts:
    """Ball-drum contacts at the predicted positions: ``|x1 - c| >= R - r``.

    The normal is ``(c - x0) / |c - x0|`` (from x1 when x0 is at the centre).

    Parameters
    ----------
    x0, x1 : np.ndarray
        (balls, 2) centres at the start and predicted at the end of the step.
    radii : np.ndarray
        (balls,) radii.
    fixed : np.ndarray
        (balls,) bool: kinematic balls, left out.
    centers : np.ndarray
        (drums, 2) the drums' centres.
    drum_radii : np.ndarray
        (drums,) the drums' radii.
    where : str, optional
        A prefix naming the scene (``PATH: ``) in an error; empty by default.

    Returns
    -------
    Contacts
        Drum by drum, the balls touching it, with the inward normal.

    Raises
    ------
    UnsupportedError
        When a ball sits at a drum's centre at both x0 and x1 (no normal).
    """
    parts = []
    for index, (center, drum_radius) in enumerate(zip(centers, drum_radii, strict=True)):
        balls = np.flatnonzero((np.hypot(*(x1 - center).T) >= drum_radius - radii) & ~fixed)
        inward = center - x0[balls]
        length = np.hypot(inward[:, 0], inward[:, 1])
        at_centre = length <= 0.0
        inward[at_centre] = center - x1[balls[at_centre]]
        length[at_centre] = np.hypot(inward[at_centre, 0], inward[at_centre, 1])
        if np.any(length <= 0.0):
            raise UnsupportedError(f"{where}body #{balls[np.argmax(length <= 0)]} sits at the "
                                   f"centre of drum #{index}, so the contact normal is undefined")
        parts.append(Contacts(balls, np.full_like(balls, -1), np.full_like(balls, DRUM),
                              np.full_like(balls, index), inward / length[:, None]))
    return Contacts.concatenate(parts) if parts else Contacts.empty()
