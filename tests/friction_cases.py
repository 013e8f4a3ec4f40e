"""Small frictional problems with hand-checkable answers, shared by the friction tests."""

from __future__ import annotations

import numpy as np

from qpbench.problem.friction import FrictionalProblem


def ball_on_floor(u_normal: float, u_tangential: float, mu: float, restitution: float = 0.0,
                  mass: float = 1.0, name: str = "ball", family: str = "") -> FrictionalProblem:
    """One ball2d ball (2 dofs) on the floor y = 0: n = (0, 1), t = (-1, 0), W = I / m."""
    return FrictionalProblem.build(name, G=[[0.0], [1.0]], T=[[-1.0], [0.0]],
                                   m_inv=[1.0 / mass, 1.0 / mass],
                                   v_minus=[-u_tangential, u_normal], mu=mu,
                                   restitution=restitution, family=family)


def pair_on_floor(mu: float, seed: int = 0, falling: bool = True,
                  d_rel: list[float] | None = None) -> FrictionalProblem:
    """Two balls on a floor, touching each other: three contacts (ball 0 on the floor, ball 1
    on the floor, ball 0 left of ball 1); ``falling`` makes both approach the floor."""
    rng = np.random.default_rng(seed)
    G = np.zeros((4, 3))
    T = np.zeros((4, 3))
    G[1, 0], T[0, 0] = 1.0, -1.0  # ball 0 on the floor
    G[3, 1], T[2, 1] = 1.0, -1.0  # ball 1 on the floor
    G[0, 2], G[2, 2] = -1.0, 1.0  # ball 0 left of ball 1: n = (-1, 0) on ball 0
    T[1, 2], T[3, 2] = -1.0, 1.0
    velocity = rng.standard_normal(4)
    if falling:
        velocity[[1, 3]] = -np.abs(velocity[[1, 3]]) - 0.5
    return FrictionalProblem.build("pair", G, T, m_inv=[1.0, 1.0, 0.5, 0.5], v_minus=velocity,
                                   mu=mu, restitution=0.3, d_rel=d_rel)
