"""How deep bodies overlap in a configuration: the Signorini violation of a state, for boxes.

Circles' gaps are :meth:`qpbench.simulation.contacts.Contacts.gaps`. Here, for boxes
(rigidbody2d ``<geometry type="box">``, half widths ``h``, angle ``theta``):

* box and plane: a vertex ``v = x + R(theta) (+-h_x, +-h_y)`` below the plane through ``p`` with
  unit normal ``n`` overlaps it by ``-n . (v - p)``;
* circle and box: the circle's centre in the box's frame, ``c' = R(theta)^T (c - x)``; outside
  the box it overlaps by ``r - |c' - clamp(c', -h, h)|``, inside by ``r + min(h - |c'|)``;
* box and box: by the separating axis theorem (Gottschalk, Lin and Manocha, "OBBTree", 1996),
  on each of the four face normals the two boxes' extents overlap by
  ``e_a + e_b - |n . (x_b - x_a)|`` (``e`` a box's half extent along ``n``); they overlap by the
  least of the four, when all four are positive.
"""

from __future__ import annotations

import numpy as np

_SIGNS = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


def _rotation(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def box_plane_depth(x: np.ndarray, theta: float, half_widths: np.ndarray,
                    plane_point: np.ndarray, plane_normal: np.ndarray) -> float:
    """How deep the box (centre ``x``, angle ``theta``) reaches below the plane (0 if not).

    Parameters
    ----------
    x : np.ndarray
        (2,) the box's centre.
    theta : float
        The box's angle in radians.
    half_widths : np.ndarray
        (2,) the box's half-widths.
    plane_point, plane_normal : np.ndarray
        (2,) a point of the plane and its unit normal.

    Returns
    -------
    float
        The depth of the deepest vertex below the plane, 0 when none is.
    """
    vertices = x + (_SIGNS * half_widths) @ _rotation(theta).T
    return max(0.0, -float(np.min((vertices - plane_point) @ plane_normal)))


def circle_box_depth(centre: np.ndarray, radius: float, x: np.ndarray, theta: float,
                     half_widths: np.ndarray) -> float:
    """How deep the circle and the box overlap (0 if not).

    Parameters
    ----------
    centre : np.ndarray
        (2,) the circle's centre.
    radius : float
        The circle's radius.
    x : np.ndarray
        (2,) the box's centre.
    theta : float
        The box's angle in radians.
    half_widths : np.ndarray
        (2,) the box's half-widths.

    Returns
    -------
    float
        The radius less the distance to the box (plus the depth inside when the centre is in
        the box); 0 when apart.
    """
    local = _rotation(theta).T @ (centre - x)
    if np.all(np.abs(local) <= half_widths):
        return radius + float(np.min(half_widths - np.abs(local)))
    nearest = np.clip(local, -half_widths, half_widths)
    return max(0.0, radius - float(np.hypot(*(local - nearest))))


def box_box_depth(x_a: np.ndarray, theta_a: float, h_a: np.ndarray, x_b: np.ndarray,
                  theta_b: float, h_b: np.ndarray) -> float:
    """How deep two boxes overlap, by separating axes.

    The least overlap of their extents over the four face normals, 0 when one of them separates
    the boxes.

    Parameters
    ----------
    x_a, x_b : np.ndarray
        (2,) the boxes' centres.
    theta_a, theta_b : float
        The boxes' angles in radians.
    h_a, h_b : np.ndarray
        (2,) the boxes' half-widths.

    Returns
    -------
    float
        The depth.
    """
    rotation_a, rotation_b = _rotation(theta_a), _rotation(theta_b)
    offset = x_b - x_a
    deepest = np.inf
    for axis in (*rotation_a.T, *rotation_b.T):
        extent_a = float(np.sum(np.abs(axis @ rotation_a) * h_a))
        extent_b = float(np.sum(np.abs(axis @ rotation_b) * h_b))
        overlap = extent_a + extent_b - abs(float(axis @ offset))
        if overlap <= 0.0:
            return 0.0
        deepest = min(deepest, overlap)
    return deepest
