"""pi-robust's start sweeps: more of them where one factorization costs many sweeps."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from qpbench.problem.formulations import pose
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.accuracy import OPTIONS
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge


def weakly_coupled_contacts(contacts: int = 200, shared: int = 50,
                            coupling: float = 0.12) -> ImpactProblem:
    """Contacts that each push one degree of freedom of their own and, weakly (``coupling``),
    two of ``shared`` others drawn at random: Q = I plus small couplings over a random graph,
    whose envelope stays wide in any bandwidth order (one factorization costs over a hundred
    sweeps), while projected Gauss-Seidel contracts fast."""
    rng = np.random.default_rng(0)
    rows, columns, values = [], [], []
    for contact in range(contacts):
        rows.append(contact)
        columns.append(contact)
        values.append(1.0)
        for other in rng.choice(shared, size=2, replace=False):
            rows.append(contacts + other)
            columns.append(contact)
            values.append(coupling)
    G = sp.csc_matrix((values, (rows, columns)), shape=(contacts + shared, contacts))
    velocities = np.zeros(contacts + shared)
    velocities[:contacts] = -1.0
    return ImpactProblem.build("weakly-coupled", G, np.ones(contacts + shared), velocities, 0.0)


def residual_after_sweeps(problem: ImpactProblem, sweeps: int) -> float:
    """qpbench's residual of ``sweeps`` projected Gauss-Seidel sweeps from l = 0 (dense)."""
    copy = problem.blind_copy()
    pose(copy, "lcp")
    Q, b = copy.Q.toarray(), copy.b
    impulses = np.zeros(b.size)
    for _ in range(sweeps):
        for i in range(b.size):
            impulses[i] = max(0.0, impulses[i] - (Q[i] @ impulses + b[i]) / Q[i, i])
    natural = np.minimum(np.diag(Q) * impulses, Q @ impulses + b)
    return float(np.max(np.abs(natural)) / np.max(np.abs(b)))


def test_a_wide_envelope_gets_the_start_sweeps_that_solve_it() -> None:
    """The accuracy table's first sweeps leave this problem three orders of magnitude short of
    1e-8; one factorization of its envelope costs as much as about a hundred sweeps, so the
    kernel sweeps on (``SWEEP_SHARE``) and the sweeps alone solve it: no factorization, and the
    answer is judged solved."""
    problem = weakly_coupled_contacts()
    assert residual_after_sweeps(problem, OPTIONS["pi-robust"]["start_sweeps"]) > 1e-6
    row, output = solve_and_judge(get("pi-robust"), problem, 1e-8)
    assert row["success"] and output.claimed_success and row["residual"] <= 1e-8
    assert output.info["path"] == "start sweeps" and output.info["factorizations"] == 0
