"""Tiny impact problems whose post-impact velocities are known in closed form (no tests here).

Each case has ``v_plus`` (the unique post-impact velocity) and ``impulses`` when l is
unique (None when Q is singular and l is not).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from qpbench.problem.dumps import import_dump
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference


@dataclass(frozen=True)
class Case:
    problem: ImpactProblem
    v_plus: np.ndarray
    impulses: np.ndarray | None


def balls(name: str, centres: list[tuple[float, float]], pairs: list[tuple[int, int]],
          velocities: list[tuple[float, float]], masses: list[float] | None = None,
          restitution: float = 1.0) -> ImpactProblem:
    """Ball-ball contacts: column k has +n_ab in a's rows, -n_ab in b's, n_ab = (x_a - x_b)/|.|;
    a mass of inf makes a ball kinematic (m_inv = 0)."""
    masses = masses or [1.0] * len(centres)
    G = np.zeros((2 * len(centres), len(pairs)))
    for k, (a, b) in enumerate(pairs):
        normal = np.subtract(centres[a], centres[b])
        normal = normal / np.linalg.norm(normal)
        G[2 * a: 2 * a + 2, k] += normal
        G[2 * b: 2 * b + 2, k] -= normal
    m_inv = np.repeat([0.0 if np.isinf(m) else 1.0 / m for m in masses], 2)
    return ImpactProblem.build(name, G, m_inv, np.ravel(velocities), restitution)


def head_on() -> Case:
    """Two equal balls head-on with c = 1 swap velocities; l = 2, w = 0."""
    problem = balls("head-on", [(0, 0), (1, 0)], [(0, 1)], [(1, 0), (-1, 0)])
    return Case(problem, np.array([-1.0, 0, 1, 0]), np.array([2.0]))


def mass_ratio() -> Case:
    """m = 1 and 3, c = 1/2, 1D: v1+ = (m1 v1 + m2 v2 + m2 c (v2 - v1)) / (m1 + m2)."""
    m1, m2, v1, v2, c = 1.0, 3.0, 2.0, -1.0, 0.5
    problem = balls("mass-ratio", [(0, 0), (1, 0)], [(0, 1)], [(v1, 0), (v2, 0)],
                    masses=[m1, m2], restitution=c)
    v1_plus = (m1 * v1 + m2 * v2 + m2 * c * (v2 - v1)) / (m1 + m2)
    v2_plus = (m1 * v1 + m2 * v2 + m1 * c * (v1 - v2)) / (m1 + m2)
    return Case(problem, np.array([v1_plus, 0, v2_plus, 0]), np.array([m1 * (v1 - v1_plus)]))


def separating() -> Case:
    """Balls already moving apart: no impulse, v+ = v-."""
    problem = balls("separating", [(0, 0), (1, 0)], [(0, 1)], [(-1, 0.5), (1, 0)])
    return Case(problem, problem.v_minus.copy(), np.array([0.0]))


def against_fixed_ball() -> Case:
    """A unit ball hits a kinematic (fixed) ball with c = 1 and bounces straight back."""
    problem = balls("fixed", [(0, 0), (1, 0)], [(0, 1)], [(1, 0), (0, 0)],
                    masses=[1.0, float("inf")])
    return Case(problem, np.array([-1.0, 0, 0, 0]), np.array([2.0]))


def k3() -> Case:
    """Three collinear overlapping unit balls, all three pairs in contact (singular Q,
    rank 2): v- = (1, 0, -1) gives v+ = (-1, 0, 1) whatever l is."""
    problem = balls("k3", [(0, 0), (1, 0), (2, 0)], [(0, 1), (1, 2), (0, 2)],
                    [(1, 0), (0, 0), (-1, 0)])
    return Case(problem, np.array([-1.0, 0, 0, 0, 1, 0]), None)


ALL_CASES = {case.problem.name: case for case in
             (head_on(), mass_ratio(), separating(), against_fixed_ball(), k3())}


# the SCISim dumps the repository holds (two of them singular)
DUMP_FILES = sorted((Path(__file__).resolve().parents[1] / "problems" / "dumps").glob("*"))


@cache
def dump_problem(path: Path) -> ImpactProblem:
    """The SCISim dump at ``path`` as a problem with its verified reference (read once)."""
    problem = attach_reference(import_dump(path))
    assert problem.reference is not None and problem.reference.verified
    return problem
