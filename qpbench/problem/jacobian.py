"""The contact Jacobian G, assembled in one place for the simulator and the generated families.

Contact k between body a and body b (b = -1 for a plane or a drum) with unit normal
``n_k`` (the direction of the impulse on a) is column k of G:

    G[d a + 0, k] = n_k,x    G[d a + 1, k] = n_k,y
    G[d b + 0, k] = -n_k,x   G[d b + 1, k] = -n_k,y    (two bodies only)

with d degrees of freedom per body (2 for balls; 3 for rigid circles, whose rotation row
a frictionless contact never touches), so that ``G^T v`` is the normal approach velocity.

The tangent Jacobian T (:func:`tangent_jacobian`) has the same layout with the tangent
``t_k = (-n_y, n_x)`` in place of n_k and, for rigid circles (d = 3), the arm term on the
rotation rows, as SCISim's ``evalH`` (``rigidbody2d/CircleCircleConstraint.cpp``,
``StaticPlaneCircleConstraint.cpp``, ``KinematicObjectCircleConstraint.cpp``) defines it:
with ``p_k`` the contact point and ``x`` a body's centre,

    T[d a + 2, k] = (p_k - x_a) x t_k      T[d b + 2, k] = -((p_k - x_b) x t_k)

(``u x w = u_x w_y - u_y w_x``), so that ``T^T v`` is the tangential velocity of a's
contact point relative to b's. ball2d balls have translation rows only.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def contact_jacobian(body_a: np.ndarray, body_b: np.ndarray, normals: np.ndarray,
                     bodies: int, dofs_per_body: int) -> sp.csc_matrix:
    """G (bodies * dofs_per_body x n) of n contacts ``(body_a, body_b, normals)``, as above.

    Parameters
    ----------
    body_a, body_b : np.ndarray
        Body indices of each contact, integers of shape (n,); ``body_b`` is -1 for a plane or
        a drum.
    normals : np.ndarray
        Unit normals n_k (the direction of the impulse on a), shape (n, 2).
    bodies : int
        The number of bodies.
    dofs_per_body : int
        2 for balls, 3 for rigid circles (the rotation row is left empty).

    Returns
    -------
    sp.csc_matrix
        G, (bodies * dofs_per_body) x n.
    """
    body_a = np.asarray(body_a, dtype=np.int64)
    body_b = np.asarray(body_b, dtype=np.int64)
    normals = np.asarray(normals, dtype=float).reshape(-1, 2)
    column = np.arange(body_a.shape[0])
    two_body = body_b >= 0
    rows = [dofs_per_body * body_a, dofs_per_body * body_a + 1,
            dofs_per_body * body_b[two_body], dofs_per_body * body_b[two_body] + 1]
    cols = [column, column, column[two_body], column[two_body]]
    values = [normals[:, 0], normals[:, 1], -normals[two_body, 0], -normals[two_body, 1]]
    return sp.csc_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))),
        shape=(bodies * dofs_per_body, body_a.shape[0]),
    )


def tangents(normals: np.ndarray) -> np.ndarray:
    """t = (-n_y, n_x) per contact: [n t] is right-handed, as SCISim's contact bases.

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
    return np.stack([-normals[:, 1], normals[:, 0]], axis=1)


def tangent_jacobian(body_a: np.ndarray, body_b: np.ndarray, normals: np.ndarray,
                     bodies: int, dofs_per_body: int, arm_a: np.ndarray | None = None,
                     arm_b: np.ndarray | None = None) -> sp.csc_matrix:
    """T (bodies * dofs_per_body x n), as in the module docstring.

    ``arm_a``/``arm_b`` are the scalars ``(p_k - x) x t_k`` of body a and body b (used only
    when ``dofs_per_body == 3``).

    Parameters
    ----------
    body_a, body_b : np.ndarray
        Body indices of each contact, integers of shape (n,); ``body_b`` is -1 for a plane or
        a drum.
    normals : np.ndarray
        Unit normals n_k, shape (n, 2); the tangents are :func:`tangents` of them.
    bodies : int
        The number of bodies.
    dofs_per_body : int
        2 for balls, 3 for rigid circles.
    arm_a, arm_b : np.ndarray or None, optional
        The arms of body a and body b, shape (n,) each (``arm_b``'s entries of one-body
        contacts are ignored); required when ``dofs_per_body == 3``, None by default.

    Returns
    -------
    sp.csc_matrix
        T, (bodies * dofs_per_body) x n.

    Raises
    ------
    ValueError
        When ``dofs_per_body == 3`` and an arm is missing.
    """
    body_a = np.asarray(body_a, dtype=np.int64)
    body_b = np.asarray(body_b, dtype=np.int64)
    T = contact_jacobian(body_a, body_b, tangents(normals), bodies, dofs_per_body)
    if dofs_per_body != 3:
        return T
    if arm_a is None or arm_b is None:
        raise ValueError("rigid bodies need the arms of both bodies")
    column = np.arange(body_a.shape[0])
    two_body = body_b >= 0
    arms = sp.csc_matrix(
        (np.concatenate([np.asarray(arm_a, dtype=float),
                         -np.asarray(arm_b, dtype=float)[two_body]]),
         (np.concatenate([3 * body_a + 2, 3 * body_b[two_body] + 2]),
          np.concatenate([column, column[two_body]]))),
        shape=T.shape)
    return sp.csc_matrix(T + arms)
