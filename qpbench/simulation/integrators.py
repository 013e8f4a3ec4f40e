"""Unconstrained flow over one step, with the forces a scene declares (gravity or none).

With acceleration ``a`` (constant gravity on free bodies, zero on kinematic ones)
and step ``h``:

* ``symplectic_euler``: ``v1 = v0 + h a``, ``x1 = x0 + h v1``;
* ``verlet`` (velocity Verlet): ``x1 = x0 + h v0 + h^2 a / 2``,
  ``v1 = v0 + h (a(x0) + a(x1)) / 2 = v0 + h a`` (a does not depend on x).

Rotation (rigidbody2d) carries no torque: ``theta1 = theta0 + h omega``.
"""

from __future__ import annotations

import numpy as np


def flow(integrator: str, x0: np.ndarray, v0: np.ndarray, dt: float,
         acceleration: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(x1, v1) after one step of the unconstrained flow (module docstring).

    Parameters
    ----------
    integrator : str
        ``symplectic_euler`` or ``verlet``.
    x0, v0 : np.ndarray
        (bodies, 2) positions and velocities at the start of the step.
    dt : float
        The step, in seconds.
    acceleration : np.ndarray or None
        (bodies, 2) constant acceleration; None when there is no force (then
        ``x1 = x0 + dt v0`` whatever the integrator).

    Returns
    -------
    tuple of (np.ndarray, np.ndarray)
        The positions and velocities at the end of the step.

    Raises
    ------
    ValueError
        For an unknown integrator when there is a force.
    """
    if acceleration is None:
        return x0 + dt * v0, v0.copy()
    v1 = v0 + dt * acceleration
    if integrator == "symplectic_euler":
        return x0 + dt * v1, v1
    if integrator == "verlet":
        return x0 + dt * v0 + (0.5 * dt * dt) * acceleration, v1
    raise ValueError(f"unknown integrator {integrator!r}")
