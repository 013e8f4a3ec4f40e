"""Box contacts as SCISim generates them (``rigidbody2d/RigidBody2DSim.cpp``).

Detection is at the predicted state (x1, theta1); each contact point p becomes one
constraint built at the start state x0 (arms ``r = p - x0`` and, for a plane, the box's
vertex rotated by theta0), as SCISim does "to conserve angular momentum":

* box-plane (``computeBodyPlaneActiveSetAllPairs``): every vertex ``x1 + R(theta1) (i hx,
  j hy)`` (i, j in -1, +1, that order) with ``n . (vertex - p) <= 0`` is a contact with the
  plane normal and arm ``R(theta0) (i hx, j hy)`` (``StaticPlaneBodyConstraint``);
* circle-box (``CircleBoxTools::isActive``): the circle's centre in the box frame, folded
  into the first quadrant, against the face or the corner; normal from the box to the
  circle, contact point at the middle of the overlap; body a is the lower index and the
  normal points from b to a (``BodyBodyConstraint``); a kinematic box is listed second and
  its velocity at the contact point enters through ``G^T v`` (SCISim's
  ``KinematicObjectCircleConstraint``, up to its arm on the circle, parallel to n);
* box-box (``BoxBoxTools::isActive``): separating axes of both boxes, the axis of least
  penetration is the reference face, the incident face is clipped against it, and each
  clipped end deeper than the reference face is a contact point (moved by half its depth).

Kinematic boxes against boxes and kinematic circles against boxes stop SCISim; they are an
UnsupportedError here.
"""

from __future__ import annotations

import math

import numpy as np

from qpbench.errors import UnsupportedError
from qpbench.simulation.contacts import BODY_BODY, BOX_PLANE, Contacts


def rotation(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


VERTEX_SIGNS = ((-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0))  # SCISim's i, j loops


def box_plane(x1: np.ndarray, theta1: float, half: np.ndarray, point: np.ndarray,
              normal: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """(vertex number, body-space arm) of every vertex at or below the plane at x1."""
    R = rotation(theta1)
    found = []
    for k, (i, j) in enumerate(VERTEX_SIGNS):
        arm = np.array([i * half[0], j * half[1]])
        vertex = x1 + R @ arm
        if float(normal @ (vertex - point)) <= 0.0:
            found.append((k, arm))
    return found


def circle_box(x_circle: np.ndarray, radius: float, x_box: np.ndarray, theta_box: float,
               half: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(n, p) of a circle against a box, n from the box towards the circle; None if apart."""
    R = rotation(theta_box)
    local = R.T @ (x_circle - x_box)
    invert_x, invert_y = local[0] < 0.0, local[1] < 0.0
    local = np.abs(local)
    if half[0] * local[1] < half[1] * local[0]:  # right or corner region
        if local[1] <= half[1]:
            depth = local[0] - radius - half[0]
            if depth > 0.0:
                return None
            n = np.array([1.0, 0.0])
        else:
            n, depth = _corner(local, half, radius)
            if n is None:
                return None
    else:  # top or corner region
        if local[0] <= half[0]:
            depth = local[1] - radius - half[1]
            if depth > 0.0:
                return None
            n = np.array([0.0, 1.0])
        else:
            n, depth = _corner(local, half, radius)
            if n is None:
                return None
    p = local - (radius + 0.5 * depth) * n
    sign = np.array([-1.0 if invert_x else 1.0, -1.0 if invert_y else 1.0])
    n, p = n * sign, p * sign
    return R @ n, R @ p + x_box


def _corner(local: np.ndarray, half: np.ndarray, radius: float
            ) -> tuple[np.ndarray | None, float]:
    n = local - half
    squared = float(n @ n)
    if squared > radius * radius:
        return None, 0.0
    length = math.sqrt(squared)
    return n / length, length - radius


def box_box(x0: np.ndarray, theta0: float, r0: np.ndarray, x1: np.ndarray, theta1: float,
            r1: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """(n, points) of two boxes (n from box 1 towards box 0); no points when apart."""
    R0, R1 = rotation(theta0), rotation(theta1)
    Q = np.abs(R0.T @ R1)
    p = x1 - x0
    best = -math.inf
    feature = -1
    invert = False
    tests = []
    p_in_0, widths_0 = R0.T @ p, Q @ r1 + r0
    p_in_1, widths_1 = R1.T @ p, Q.T @ r0 + r1
    tests = [(p_in_0[0], widths_0[0]), (p_in_0[1], widths_0[1]),
             (p_in_1[0], widths_1[0]), (p_in_1[1], widths_1[1])]
    for k, (distance, width) in enumerate(tests):
        depth = abs(distance) - width
        if depth > 0:
            return np.zeros(2), []
        if depth > best:
            best, invert, feature = depth, distance < 0.0, k
    first_is_reference = feature <= 1
    n = R0[:, feature] if first_is_reference else R1[:, feature - 2]
    if invert:
        n = -n
    Ra, Rb = (R0, R1) if first_is_reference else (R1, R0)
    xa, xb = (x0, x1) if first_is_reference else (x1, x0)
    ra, rb = (r0, r1) if first_is_reference else (r1, r0)
    normal2 = n if first_is_reference else -n
    n_in_b = Rb.T @ normal2
    b_n = 1 if abs(n_in_b[1]) > abs(n_in_b[0]) else 0
    b_t = 1 - b_n
    b_face_center = xb - xa + (1.0 if n_in_b[b_n] < 0.0 else -1.0) * rb[b_n] * Rb[:, b_n]
    a_n = feature if first_is_reference else feature - 2
    a_t = 1 - a_n
    c_on_a = float(b_face_center @ Ra[:, a_t])
    costheta = float(Ra[:, a_t] @ Rb[:, b_t])
    lo, hi = c_on_a - costheta * rb[b_t], c_on_a + costheta * rb[b_t]
    if lo > hi:
        lo, hi = hi, lo
    lo, hi = min(lo, ra[a_t]), max(hi, -ra[a_t])
    intersection = (max(-ra[a_t], lo), min(ra[a_t], hi))
    count = 2 if intersection[0] != intersection[1] else 1
    points = []
    for k in range(count):
        point = b_face_center + ((intersection[k] - c_on_a) / costheta) * Rb[:, b_t]
        depth = ra[a_n] - float(normal2 @ point)
        if depth >= 0.0:
            points.append(xa + point + 0.5 * depth * normal2)
    return -n, points


def refuse_kinematic(where: str, what: str, a: int, b: int) -> UnsupportedError:
    return UnsupportedError(f"{where}bodies #{a} and #{b}: {what} contacts are not supported "
                            "(SCISim stops there too)")


def box_contacts(x0: np.ndarray, x1: np.ndarray, theta0: np.ndarray, theta1: np.ndarray,
                 radii: np.ndarray, half_widths: np.ndarray, fixed: np.ndarray,
                 plane_points: np.ndarray, plane_normals: np.ndarray, where: str = ""
                 ) -> tuple[Contacts, Contacts]:
    """(body-body, box-plane) contacts of every box (module docstring); circle-circle and
    circle-plane contacts are found elsewhere."""
    from qpbench.simulation.broad_phase import candidate_pairs, swept_boxes

    is_box = ~np.isnan(half_widths[:, 0])
    lower, upper = swept_boxes(x0, x1, radii)
    for k in np.flatnonzero(is_box):  # SCISim: a box's collision box is at x1 alone
        extents = np.abs(rotation(float(theta1[k]))) @ half_widths[k]
        lower[k], upper[k] = x1[k] - extents, x1[k] + extents
    rows: list[tuple[int, int, int, int, np.ndarray, np.ndarray, np.ndarray, int]] = []
    for i, j in candidate_pairs(lower, upper).tolist():
        if not (is_box[i] or is_box[j]) or (fixed[i] and fixed[j]):
            continue
        if is_box[i] and is_box[j]:
            if fixed[i] or fixed[j]:
                raise refuse_kinematic(where, "kinematic box-box", i, j)
            n, points = box_box(x1[i], float(theta1[i]), half_widths[i], x1[j],
                                float(theta1[j]), half_widths[j])
            for k, p in enumerate(points):
                rows.append((BODY_BODY, i, j, -1, n, p - x0[i], p - x0[j], k))
            continue
        circle, box = (i, j) if is_box[j] else (j, i)
        if fixed[circle]:
            raise refuse_kinematic(where, "kinematic circle-box", circle, box)
        hit = circle_box(x1[circle], float(radii[circle]), x1[box], float(theta1[box]),
                         half_widths[box])
        if hit is None:
            continue
        n, p = hit
        if circle < box or fixed[box]:  # a kinematic body second, as SCISim lists it
            rows.append((BODY_BODY, circle, box, -1, n, p - x0[circle], p - x0[box], 0))
        else:
            rows.append((BODY_BODY, box, circle, -1, -n, p - x0[box], p - x0[circle], 0))
    plane_rows = []
    for index, (point, normal) in enumerate(zip(plane_points, plane_normals, strict=True)):
        for k in np.flatnonzero(is_box & ~fixed):
            for vertex, arm in box_plane(x1[k], float(theta1[k]), half_widths[k], point,
                                         normal):
                plane_rows.append((BOX_PLANE, int(k), -1, index, normal,
                                   rotation(float(theta0[k])) @ arm, np.full(2, np.nan),
                                   vertex))
    return _table(rows), _table(plane_rows)


def _table(rows: list) -> Contacts:
    if not rows:
        return Contacts.empty()
    kind, a, b, boundary, normals, arm_a, arm_b, point = zip(*rows, strict=True)
    arms = np.hstack([np.array(arm_a, dtype=float), np.array(arm_b, dtype=float)])
    return Contacts(np.array(a, dtype=np.int64), np.array(b, dtype=np.int64),
                    np.array(kind, dtype=np.int64), np.array(boundary, dtype=np.int64),
                    np.array(normals, dtype=float).reshape(-1, 2), arms,
                    np.array(point, dtype=np.int64))
