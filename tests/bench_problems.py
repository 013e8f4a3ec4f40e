"""Tiny impact problems with exact references, for the harness tests, and the committed dumps
the solver tests share."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from qpbench.problem import files
from qpbench.problem.impact import ImpactProblem, Reference

# a dump of the research fork's 5x5 grid on which block pivoting cycles (problems/head_to_head)
CYCLING_DUMP = (Path(__file__).resolve().parents[1]
                / "problems/head_to_head/fork_5x5_grid/itr_15.xml.out")


def exact_impulses(problem: ImpactProblem) -> np.ndarray:
    """The least-norm l >= 0 with w = Q l + b >= 0 and l_i w_i = 0, found by trying supports
    (smallest first; only for a handful of contacts)."""
    Q = problem.Q.toarray()
    b = problem.b
    n = problem.n_contacts
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    for size in range(n + 1):
        for support in itertools.combinations(range(n), size):
            index = list(support)
            impulses = np.zeros(n)
            if index:
                impulses[index] = np.linalg.lstsq(Q[np.ix_(index, index)], -b[index],
                                                  rcond=None)[0]
            w = Q @ impulses + b
            if impulses.min() >= -1e-12 * scale and w.min() >= -1e-12 * scale:
                return np.maximum(impulses, 0.0)
    raise ValueError("no support solves the LCP")


def collinear_balls(name: str, count: int, restitution: float = 1.0) -> ImpactProblem:
    """``count`` unit balls on the x axis at spacing 1 (radius 1, so each overlaps the balls
    up to two places away): a contact for every pair closer than 2. The first ball moves
    right at 1, the last left at 1. The reference is the exact LCP solution. With 3 balls
    this is K3: Q = [[2, 1, -1], [1, 2, 1], [-1, 1, 2]], singular."""
    positions = np.arange(count, dtype=float)
    pairs = [(a, b) for a, b in itertools.combinations(range(count), 2)
             if positions[b] - positions[a] < 2.0 + 1e-12]
    G = np.zeros((2 * count, len(pairs)))
    for k, (a, b) in enumerate(pairs):
        normal = np.array([positions[a] - positions[b], 0.0])
        normal /= np.linalg.norm(normal)
        G[2 * a: 2 * a + 2, k] = normal
        G[2 * b: 2 * b + 2, k] = -normal
    v_minus = np.zeros(2 * count)
    v_minus[0], v_minus[-2] = 1.0, -1.0
    problem = ImpactProblem.build(name, G, np.ones(2 * count), v_minus, restitution,
                                  family="k3" if count == 3 else "row", source="tests")
    impulses = exact_impulses(problem)
    v_plus = problem.v_plus(impulses)
    problem.reference = Reference(v_plus=v_plus, impulses=impulses, method="enumeration",
                                  v_plus_check=v_plus.copy(), check_method="enumeration",
                                  agreement=0.0, tolerance=1e-9)
    return problem


def write_tiny_problems(folder: Path, count: int = 2) -> list[Path]:
    """Saves ``count`` tiny problems (K3, then rows of 4, 5, ... balls) into ``folder``."""
    problems = [collinear_balls(f"row{size}", size, restitution=0.5 if size % 2 else 1.0)
                for size in range(3, 3 + count)]
    return [files.save(problem, folder / problem.name) for problem in problems]
