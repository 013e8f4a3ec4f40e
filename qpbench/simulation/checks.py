"""Energy and momentum of the bodies, for the checks a simulation reports.

Over free (non-kinematic) bodies with masses m, moments of inertia I and gravity g:

* ``energy = sum 1/2 m |v|^2 + sum 1/2 I omega^2 - sum m g . x`` (kinetic plus potential);
* ``momentum = sum m v``; with gravity it should equal ``P0 + (sum m) g t``;
* ``momentum_drift = |P(t) - P0 - (sum m) g t| / max(sum m |v0|, sum m |v(t)|, tiny)``,
  zero up to rounding when only balls meet (impulses between balls conserve momentum).

Every sum runs in an order that does not depend on the CPU (NumPy's pairwise summation of
elementwise products, :func:`qpbench.problem.metrics.dot`, never a BLAS product), so that a
simulation reports the same figures on every machine.
"""

from __future__ import annotations

import numpy as np

from qpbench.problem.metrics import TINY, dot


def energy(masses: np.ndarray, inertia: np.ndarray, free: np.ndarray, positions: np.ndarray,
           velocities: np.ndarray, omega: np.ndarray | None, gravity: np.ndarray | None) -> float:
    """Kinetic plus gravitational potential energy of the free bodies (formula above).

    Parameters
    ----------
    masses, inertia : np.ndarray
        (bodies,) masses and moments of inertia.
    free : np.ndarray
        (bodies,) bool: the free (non-kinematic) bodies.
    positions, velocities : np.ndarray
        (bodies, 2) centres and linear velocities.
    omega : np.ndarray or None
        (bodies,) angular velocities; None for balls, which carry no rotation.
    gravity : np.ndarray or None
        (2,) gravitational acceleration; None when the scene has no gravity.

    Returns
    -------
    float
        The energy.
    """
    m = masses[free]
    total = 0.5 * float(np.sum(m * np.einsum("ij,ij->i", velocities[free], velocities[free])))
    if omega is not None:
        total += 0.5 * float(np.sum(inertia[free] * omega[free] ** 2))
    if gravity is not None:
        height = positions[free, 0] * gravity[0] + positions[free, 1] * gravity[1]
        total -= dot(m, height)
    return total


def momentum(masses: np.ndarray, free: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """Linear momentum sum m v of the free bodies.

    Parameters
    ----------
    masses : np.ndarray
        (bodies,) masses.
    free : np.ndarray
        (bodies,) bool: the free (non-kinematic) bodies.
    velocities : np.ndarray
        (bodies, 2) linear velocities.

    Returns
    -------
    np.ndarray
        (2,) momentum.
    """
    weights, moving = masses[free], velocities[free]
    return np.array([dot(weights, moving[:, 0]), dot(weights, moving[:, 1])])


def momentum_drift(masses: np.ndarray, free: np.ndarray, v_start: np.ndarray, v_end: np.ndarray,
                   gravity: np.ndarray | None, elapsed: float) -> float:
    """Relative momentum drift over ``elapsed`` seconds (formula above).

    Parameters
    ----------
    masses : np.ndarray
        (bodies,) masses.
    free : np.ndarray
        (bodies,) bool: the free (non-kinematic) bodies.
    v_start, v_end : np.ndarray
        (bodies, 2) linear velocities at the start and at the end.
    gravity : np.ndarray or None
        (2,) gravitational acceleration; None when the scene has no gravity.
    elapsed : float
        Simulated seconds between the two velocities.

    Returns
    -------
    float
        The drift, relative to the larger momentum magnitude sum m |v|.
    """
    expected = momentum(masses, free, v_start)
    if gravity is not None:
        expected = expected + float(np.sum(masses[free])) * gravity * elapsed
    difference = momentum(masses, free, v_end) - expected
    scale = max(dot(masses[free], np.hypot(*v_start[free].T)),
                dot(masses[free], np.hypot(*v_end[free].T)), TINY)
    return float(np.hypot(*difference)) / scale
