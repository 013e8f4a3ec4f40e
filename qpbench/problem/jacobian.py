"""The contact Jacobian G, assembled in one place for the simulator and the generated families.

Contact k between body a and body b (b = -1 for a plane or a drum) with unit normal
``n_k`` (the direction of the impulse on a) is column k of G:

    G[d a + 0, k] = n_k,x    G[d a + 1, k] = n_k,y
    G[d b + 0, k] = -n_k,x   G[d b + 1, k] = -n_k,y    (two bodies only)

with d degrees of freedom per body (2 for balls; 3 for rigid circles, whose rotation row
a frictionless contact never touches), so that ``G^T v`` is the normal approach velocity.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def contact_jacobian(body_a: np.ndarray, body_b: np.ndarray, normals: np.ndarray,
                     bodies: int, dofs_per_body: int) -> sp.csc_matrix:
    """G (bodies * dofs_per_body x n) of n contacts ``(body_a, body_b, normals)``, as above."""
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
