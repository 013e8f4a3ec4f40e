"""Box contacts as SCISim generates them (``rigidbody2d/RigidBody2DSim.cpp``).

Detection is at the predicted state (x1, theta1); each contact point p becomes one
constraint built at the start state x0 (arms ``r = p - x0`` and, for a plane, the box's
vertex rotated by theta0), as SCISim does "to conserve angular momentum":

* box-plane (``computeBodyPlaneActiveSetAllPairs``): every vertex ``x1 + R(theta1) (i hx,
  j hy)`` (i, j in -1, +1, that order) with ``n . (vertex - p) <= 0`` is a contact with the
  plane normal and arm ``R(theta0) (i hx, j hy)`` (``StaticPlaneBodyConstraint``); planes
  in scene order, then the free boxes by index, then their vertices;
* circle-box (``CircleBoxTools::isActive``): the circle's centre in the box frame, folded
  into the first quadrant, against the face or the corner; normal from the box to the
  circle, contact point at the middle of the overlap; body a is the lower index and the
  normal points from b to a (``BodyBodyConstraint``); a kinematic box is listed second and
  its velocity at the contact point enters through ``G^T v`` (SCISim's
  ``KinematicObjectCircleConstraint``, up to its arm on the circle, parallel to n);
* box-box (``BoxBoxTools::isActive``): separating axes of both boxes, the axis of least
  penetration is the reference face, the incident face is clipped against it, and each
  clipped end deeper than the reference face is a contact point (moved by half its depth).

Body-body contacts come in the order of the broad phase's candidate pairs (sorted (i, j),
i < j), a box-box pair's points in clipping order. Kinematic boxes against boxes and
kinematic circles against boxes stop SCISim; they are an UnsupportedError here, for the
first such candidate pair.

The narrow phase runs compiled (numba, ``njit(cache=True)``): one loop over all candidate
pairs and one over the box vertices, writing the contact table directly. Numba rather than
vectorised numpy because each pair takes a different branch (which of four axes is the
reference, face or corner, how many clipped points survive): numpy would evaluate every
branch for every pair under masks and then compact the rows, whereas the compiled loop reads
as SCISim's code line by line, keeps the contacts' order by construction and costs
O(pairs). The arithmetic is SCISim's, in the order the former per-pair numpy code used
(``R = [[c, -s], [s, c]]``, products summed left to right, no fused multiply-adds), so the
contacts agree with it to the last bit or within rounding of a dot product.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from qpbench.errors import UnsupportedError
from qpbench.simulation.broad_phase import candidate_pairs, swept_boxes
from qpbench.simulation.contacts import BODY_BODY, BOX_PLANE, Contacts

VERTEX_SIGNS = ((-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0))  # SCISim's i, j loops
_SIGNS = np.array(VERTEX_SIGNS)

# what _body_body_table reports about the first refused candidate pair
NO_REFUSAL, KINEMATIC_BOX_BOX, KINEMATIC_CIRCLE_BOX = 0, 1, 2
_REFUSALS = {KINEMATIC_BOX_BOX: "kinematic box-box", KINEMATIC_CIRCLE_BOX: "kinematic circle-box"}


@njit(cache=True, error_model="numpy")
def circle_box(xc: float, yc: float, radius: float, xb: float, yb: float, theta: float,
               hx: float, hy: float) -> tuple[bool, float, float, float, float]:
    """Contact of a circle against a box: whether they touch, the normal and the contact point.

    n is unit, from the box towards the circle; p is at the middle of the overlap, in world
    coordinates (module docstring).

    Parameters
    ----------
    xc, yc : float
        The circle's centre.
    radius : float
        The circle's radius.
    xb, yb : float
        The box's centre.
    theta : float
        The box's angle in radians.
    hx, hy : float
        The box's half-widths along its own axes.

    Returns
    -------
    tuple of (bool, float, float, float, float)
        (hit, n_x, n_y, p_x, p_y); ``hit`` False and zeros when apart.
    """
    c, s = math.cos(theta), math.sin(theta)
    dx, dy = xc - xb, yc - yb
    lx, ly = c * dx + s * dy, -s * dx + c * dy  # R^T (x_circle - x_box)
    invert_x, invert_y = lx < 0.0, ly < 0.0
    lx, ly = abs(lx), abs(ly)
    corner = False
    if hx * ly < hy * lx:  # right or corner region
        if ly <= hy:
            depth = lx - radius - hx
            if depth > 0.0:
                return False, 0.0, 0.0, 0.0, 0.0
            nx, ny = 1.0, 0.0
        else:
            corner = True
    else:  # top or corner region
        if lx <= hx:
            depth = ly - radius - hy
            if depth > 0.0:
                return False, 0.0, 0.0, 0.0, 0.0
            nx, ny = 0.0, 1.0
        else:
            corner = True
    if corner:  # towards the nearest vertex (hx, hy) of the folded box
        nx, ny = lx - hx, ly - hy
        squared = nx * nx + ny * ny
        if squared > radius * radius:
            return False, 0.0, 0.0, 0.0, 0.0
        length = math.sqrt(squared)
        nx, ny = nx / length, ny / length
        depth = length - radius
    reach = radius + 0.5 * depth
    px, py = lx - reach * nx, ly - reach * ny
    if invert_x:
        nx, px = -nx, -px
    if invert_y:
        ny, py = -ny, -py
    return (True, c * nx - s * ny, s * nx + c * ny,
            c * px - s * py + xb, s * px + c * py + yb)


@njit(cache=True, error_model="numpy")
def box_box(x0: float, y0: float, theta0: float, hx0: float, hy0: float, x1: float,
            y1: float, theta1: float, hx1: float, hy1: float, points: np.ndarray
            ) -> tuple[int, float, float]:
    """Contact points of box 0 against box 1 by separating axes and clipping.

    n is unit, from box 1 towards box 0; the first ``count`` rows of ``points`` are set to the
    contact points (module docstring).

    Parameters
    ----------
    x0, y0, theta0, hx0, hy0 : float
        Box 0's centre, angle in radians and half-widths.
    x1, y1, theta1, hx1, hy1 : float
        Box 1's, likewise.
    points : np.ndarray
        (2, 2) float array, written in place: one contact point per row.

    Returns
    -------
    tuple of (int, float, float)
        (count, n_x, n_y); count 0 (and a zero normal) when apart.
    """
    c0, s0 = math.cos(theta0), math.sin(theta0)
    c1, s1 = math.cos(theta1), math.sin(theta1)
    # Q = |R0^T R1|
    q00, q01 = abs(c0 * c1 + s0 * s1), abs(c0 * -s1 + s0 * c1)
    q10, q11 = abs(-s0 * c1 + c0 * s1), abs(-s0 * -s1 + c0 * c1)
    px, py = x1 - x0, y1 - y0
    distances = (c0 * px + s0 * py, -s0 * px + c0 * py,  # p in box 0's frame
                 c1 * px + s1 * py, -s1 * px + c1 * py)  # p in box 1's frame
    widths = (q00 * hx1 + q01 * hy1 + hx0, q10 * hx1 + q11 * hy1 + hy0,
              q00 * hx0 + q10 * hy0 + hx1, q01 * hx0 + q11 * hy0 + hy1)
    best, feature, invert = -math.inf, -1, False
    for k in range(4):  # separating axes: box 0's x, y, then box 1's x, y
        depth = abs(distances[k]) - widths[k]
        if depth > 0:
            return 0, 0.0, 0.0
        if depth > best:
            best, invert, feature = depth, distances[k] < 0.0, k
    first_is_reference = feature <= 1
    # the reference box a and the incident box b, each as centre, cos, sin, half-widths
    if first_is_reference:
        xa, ya, ca, sa, ha_x, ha_y = x0, y0, c0, s0, hx0, hy0
        xb, yb, cb, sb, hb_x, hb_y = x1, y1, c1, s1, hx1, hy1
        a_n = feature
    else:
        xa, ya, ca, sa, ha_x, ha_y = x1, y1, c1, s1, hx1, hy1
        xb, yb, cb, sb, hb_x, hb_y = x0, y0, c0, s0, hx0, hy0
        a_n = feature - 2
    # n: column a_n of the reference box's rotation, turned by invert
    if a_n == 0:
        nx, ny = ca, sa
    else:
        nx, ny = -sa, ca
    if invert:
        nx, ny = -nx, -ny
    m_x, m_y = (nx, ny) if first_is_reference else (-nx, -ny)  # out of a's reference face
    in_b_x, in_b_y = cb * m_x + sb * m_y, -sb * m_x + cb * m_y  # Rb^T m
    b_n = 1 if abs(in_b_y) > abs(in_b_x) else 0
    b_axis = (cb, sb, -sb, cb)  # Rb's columns
    bn_x, bn_y = b_axis[2 * b_n], b_axis[2 * b_n + 1]
    bt_x, bt_y = b_axis[2 - 2 * b_n], b_axis[3 - 2 * b_n]
    hb_n, hb_t = (hb_y, hb_x) if b_n == 1 else (hb_x, hb_y)
    side = (1.0 if (in_b_y if b_n == 1 else in_b_x) < 0.0 else -1.0) * hb_n
    face_x, face_y = xb - xa + side * bn_x, yb - ya + side * bn_y  # incident face, from a
    if a_n == 0:
        at_x, at_y, ha_n, ha_t = -sa, ca, ha_x, ha_y
    else:
        at_x, at_y, ha_n, ha_t = ca, sa, ha_y, ha_x
    c_on_a = face_x * at_x + face_y * at_y
    costheta = at_x * bt_x + at_y * bt_y
    lo, hi = c_on_a - costheta * hb_t, c_on_a + costheta * hb_t
    if lo > hi:
        lo, hi = hi, lo
    if ha_t < lo:  # Python's min(lo, ha_t), max(hi, -ha_t): the first on ties
        lo = ha_t
    if -ha_t > hi:
        hi = -ha_t
    ends = (lo if lo > -ha_t else -ha_t, hi if hi < ha_t else ha_t)  # clipped to a's face
    clipped = 2 if ends[0] != ends[1] else 1
    count = 0
    for k in range(clipped):
        along = (ends[k] - c_on_a) / costheta
        point_x, point_y = face_x + along * bt_x, face_y + along * bt_y
        depth = ha_n - (m_x * point_x + m_y * point_y)
        if depth >= 0.0:
            half_depth = 0.5 * depth
            points[count, 0] = xa + point_x + half_depth * m_x
            points[count, 1] = ya + point_y + half_depth * m_y
            count += 1
    return count, -nx, -ny


@njit(cache=True, error_model="numpy")
def _body_body_table(pairs: np.ndarray, is_box: np.ndarray, fixed: np.ndarray,
                     x0: np.ndarray, x1: np.ndarray, theta1: np.ndarray, radii: np.ndarray,
                     half_widths: np.ndarray
                     ) -> tuple[int, int, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                np.ndarray]:
    """The box-box and circle-box contacts of the candidate pairs, in their order:
    (refusal, refused pair, count, a, b, normals, arms, point), the arrays' first ``count``
    rows filled. A refusal (module docstring) stops at that pair with count 0."""
    capacity = 2 * pairs.shape[0]
    body_a = np.empty(capacity, dtype=np.int64)
    body_b = np.empty(capacity, dtype=np.int64)
    normals = np.empty((capacity, 2))
    arms = np.empty((capacity, 4))
    point = np.empty(capacity, dtype=np.int64)
    found = np.empty((2, 2))
    count = 0
    for row in range(pairs.shape[0]):
        i, j = pairs[row, 0], pairs[row, 1]
        if not (is_box[i] or is_box[j]) or (fixed[i] and fixed[j]):
            continue
        if is_box[i] and is_box[j]:
            if fixed[i] or fixed[j]:
                return KINEMATIC_BOX_BOX, row, 0, body_a, body_b, normals, arms, point
            hits, nx, ny = box_box(x1[i, 0], x1[i, 1], theta1[i], half_widths[i, 0],
                                   half_widths[i, 1], x1[j, 0], x1[j, 1], theta1[j],
                                   half_widths[j, 0], half_widths[j, 1], found)
            for k in range(hits):
                body_a[count], body_b[count], point[count] = i, j, k
                normals[count, 0], normals[count, 1] = nx, ny
                arms[count, 0], arms[count, 1] = found[k, 0] - x0[i, 0], found[k, 1] - x0[i, 1]
                arms[count, 2], arms[count, 3] = found[k, 0] - x0[j, 0], found[k, 1] - x0[j, 1]
                count += 1
            continue
        circle, box = (i, j) if is_box[j] else (j, i)
        if fixed[circle]:
            return KINEMATIC_CIRCLE_BOX, row, 0, body_a, body_b, normals, arms, point
        hit, nx, ny, px, py = circle_box(x1[circle, 0], x1[circle, 1], radii[circle],
                                         x1[box, 0], x1[box, 1], theta1[box],
                                         half_widths[box, 0], half_widths[box, 1])
        if not hit:
            continue
        if circle < box or fixed[box]:  # a kinematic body second, as SCISim lists it
            first, second = circle, box
        else:
            first, second, nx, ny = box, circle, -nx, -ny
        body_a[count], body_b[count], point[count] = first, second, 0
        normals[count, 0], normals[count, 1] = nx, ny
        arms[count, 0], arms[count, 1] = px - x0[first, 0], py - x0[first, 1]
        arms[count, 2], arms[count, 3] = px - x0[second, 0], py - x0[second, 1]
        count += 1
    return NO_REFUSAL, -1, count, body_a, body_b, normals, arms, point


@njit(cache=True, error_model="numpy")
def _box_plane_table(boxes: np.ndarray, x1: np.ndarray, theta0: np.ndarray,
                     theta1: np.ndarray, half_widths: np.ndarray, plane_points: np.ndarray,
                     plane_normals: np.ndarray, signs: np.ndarray
                     ) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every vertex of the ``boxes`` at or below each plane at x1: (count, body, plane,
    arm ``R(theta0) (i hx, j hy)``, vertex number), the first ``count`` rows filled."""
    capacity = plane_points.shape[0] * boxes.shape[0] * signs.shape[0]
    body = np.empty(capacity, dtype=np.int64)
    plane = np.empty(capacity, dtype=np.int64)
    arms = np.empty((capacity, 2))
    vertex_number = np.empty(capacity, dtype=np.int64)
    count = 0
    for index in range(plane_points.shape[0]):
        qx, qy = plane_points[index, 0], plane_points[index, 1]
        nx, ny = plane_normals[index, 0], plane_normals[index, 1]
        for k in boxes:
            c1, s1 = math.cos(theta1[k]), math.sin(theta1[k])
            for vertex in range(signs.shape[0]):
                ax, ay = signs[vertex, 0] * half_widths[k, 0], signs[vertex, 1] * half_widths[k, 1]
                vx, vy = x1[k, 0] + (c1 * ax - s1 * ay), x1[k, 1] + (s1 * ax + c1 * ay)
                if nx * (vx - qx) + ny * (vy - qy) <= 0.0:
                    c0, s0 = math.cos(theta0[k]), math.sin(theta0[k])
                    body[count], plane[count], vertex_number[count] = k, index, vertex
                    arms[count, 0], arms[count, 1] = c0 * ax - s0 * ay, s0 * ax + c0 * ay
                    count += 1
    return count, body, plane, arms, vertex_number


def _collision_boxes(x0: np.ndarray, x1: np.ndarray, radii: np.ndarray, theta1: np.ndarray,
                     half_widths: np.ndarray, is_box: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners of each body's collision box: a circle's swept over the step
    (``broad_phase.swept_boxes``); a box's at x1 alone, ``x1 -+ |R(theta1)| h`` (as SCISim)."""
    lower, upper = swept_boxes(x0, x1, radii)
    boxes = np.flatnonzero(is_box)
    cos, sin = np.abs(np.cos(theta1[boxes])), np.abs(np.sin(theta1[boxes]))
    hx, hy = half_widths[boxes, 0], half_widths[boxes, 1]
    extents = np.column_stack([cos * hx + sin * hy, sin * hx + cos * hy])
    lower[boxes], upper[boxes] = x1[boxes] - extents, x1[boxes] + extents
    return lower, upper


def refuse_kinematic(where: str, what: str, a: int, b: int) -> UnsupportedError:
    """The error for a kinematic pair SCISim cannot handle either.

    Parameters
    ----------
    where : str
        A prefix naming the scene (``PATH: ``), or empty.
    what : str
        The pair's kind: ``kinematic box-box`` or ``kinematic circle-box``.
    a, b : int
        The two bodies' indices.

    Returns
    -------
    UnsupportedError
        The error to raise, naming both bodies.
    """
    return UnsupportedError(f"{where}bodies #{a} and #{b}: {what} contacts are not supported "
                            "(SCISim stops there too)")


def box_contacts(x0: np.ndarray, x1: np.ndarray, theta0: np.ndarray, theta1: np.ndarray,
                 radii: np.ndarray, half_widths: np.ndarray, fixed: np.ndarray,
                 plane_points: np.ndarray, plane_normals: np.ndarray, where: str = ""
                 ) -> tuple[Contacts, Contacts]:
    """(body-body, box-plane) contacts of every box (module docstring).

    Circle-circle and circle-plane contacts are found elsewhere
    (:mod:`qpbench.simulation.contacts`).

    Parameters
    ----------
    x0, x1 : np.ndarray
        (bodies, 2) centres at the start of the step and predicted at its end.
    theta0, theta1 : np.ndarray
        (bodies,) angles in radians, likewise.
    radii : np.ndarray
        (bodies,) radii of the circles (read for circles only).
    half_widths : np.ndarray
        (bodies, 2) half-widths of the boxes; NaN rows for circles.
    fixed : np.ndarray
        (bodies,) bool: kinematic bodies.
    plane_points, plane_normals : np.ndarray
        (planes, 2) a point and the unit normal of each static plane.
    where : str, optional
        A prefix naming the scene (``PATH: ``) in an error; empty by default.

    Returns
    -------
    tuple of (Contacts, Contacts)
        The box-box and circle-box contacts, in the order of the candidate pairs, and the
        box-plane contacts, planes in scene order, then boxes by index, then vertices.

    Raises
    ------
    UnsupportedError
        For the first candidate pair of a kinematic box against a box, or a kinematic circle
        against a box.
    """
    x0, x1 = (np.ascontiguousarray(x, dtype=float) for x in (x0, x1))
    theta0, theta1, radii = (np.ascontiguousarray(v, dtype=float)
                             for v in (theta0, theta1, radii))
    half_widths = np.ascontiguousarray(half_widths, dtype=float)
    fixed = np.ascontiguousarray(fixed, dtype=np.bool_)
    is_box = ~np.isnan(half_widths[:, 0])
    lower, upper = _collision_boxes(x0, x1, radii, theta1, half_widths, is_box)
    pairs = np.ascontiguousarray(candidate_pairs(lower, upper), dtype=np.int64)
    refusal, refused, count, a, b, normals, arms, point = _body_body_table(
        pairs, is_box, fixed, x0, x1, theta1, radii, half_widths)
    if refusal != NO_REFUSAL:
        i, j = (int(body) for body in pairs[refused])
        if refusal == KINEMATIC_CIRCLE_BOX and is_box[i]:
            i, j = j, i  # the circle first
        raise refuse_kinematic(where, _REFUSALS[refusal], i, j)
    body_body = Contacts(a[:count], b[:count], np.full(count, BODY_BODY, dtype=np.int64),
                         np.full(count, -1, dtype=np.int64), normals[:count], arms[:count],
                         point[:count])
    plane_points = np.ascontiguousarray(plane_points, dtype=float).reshape(-1, 2)
    plane_normals = np.ascontiguousarray(plane_normals, dtype=float).reshape(-1, 2)
    movable = np.flatnonzero(is_box & ~fixed).astype(np.int64)
    count, body, plane, plane_arms, vertex = _box_plane_table(
        movable, x1, theta0, theta1, half_widths, plane_points, plane_normals, _SIGNS)
    box_planes = Contacts(body[:count], np.full(count, -1, dtype=np.int64),
                          np.full(count, BOX_PLANE, dtype=np.int64), plane[:count],
                          plane_normals[plane[:count]],
                          np.hstack([plane_arms[:count], np.full((count, 2), np.nan)]),
                          vertex[:count])
    return body_body, box_planes
