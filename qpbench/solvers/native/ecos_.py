"""ECOS through its own API: ``ecos.solve(c, G, h, dims)``, a second-order cone program
``min c^T z`` subject to ``h - G z`` in a product of cones.

A quadratic ``1/2 ||R x - r||^2`` becomes the epigraph variable t with
``||(t - 1/2, R x - r)|| <= t + 1/2`` (which is ``||R x - r||^2 <= 2 t``), over
``z = (x, t)``, after the nonnegative rows (ECOS's ``l`` cone) of the constraints:

* ``dual``: ``R`` from the Cholesky factor of Q (``Q = R^T R``, ``r = 0``), rows ``l >= 0``;
  a singular Q has none, and is refused by name (status ``unsupported: not positive
  definite``, no claim), as through qpsolvers;
* ``primal``: ``R = M^1/2``, ``r = M^1/2 v-`` (diagonal, always regular), rows
  ``G^T v - lower >= 0``, whose multipliers (nonnegative) are the impulses;
* ``dual-factored``: ``R = L``, ``r = 0``, rows ``l >= 0``: ECOS's own form, with no Q and
  no factorization, so it takes singular problems.

ECOS takes no warm start; it reports its set-up and solve times.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

try:
    import ecos
except ImportError as _error:
    ecos = None
    IMPORT_ERROR = _error

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_rows, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolveFunction, SolverOutput, reported_times
from qpbench.solvers.native.common import native_name, register_missing, register_pairs
from qpbench.solvers.qpsolvers_ import NOT_POSITIVE_DEFINITE

NAME = native_name("ecos")
FORMULATIONS = ("dual", "primal", "dual-factored")
OPTIMAL = 0  # ECOS's exitFlag of "optimal solution found"


def _solved(cost: np.ndarray, rows: sp.spmatrix, bounds: np.ndarray, R: sp.spmatrix,
            r: np.ndarray, eps: float, scale: float
            ) -> tuple[SolverOutput, np.ndarray, np.ndarray]:
    """``min cost^T x + 1/2 ||R x - r||^2`` subject to ``rows x >= bounds``: the output
    (impulses not yet set), x, and the rows' multipliers."""
    m, dofs = rows.shape
    k = R.shape[0]
    epigraph = sp.csc_matrix(([-1.0, -1.0], ([0, 1], [0, 0])), shape=(2, 1))
    G = sp.vstack([sp.hstack([-rows, sp.csc_matrix((m, 1))]),
                   sp.hstack([sp.csc_matrix((2, dofs)), epigraph]),
                   sp.hstack([-R, sp.csc_matrix((k, 1))])], format="csc")
    h = np.concatenate([-bounds, [0.5, -0.5], -r])
    c = np.concatenate([cost, [1.0]])
    result = ecos.solve(c, G, h, {"l": m, "q": [k + 2]}, verbose=False,
                        **accuracy.options_for(NAME, eps, scale))
    info = result["info"]
    timing = info.get("timing", {})
    output = SolverOutput(
        impulses=None, status=str(info["infostring"]),
        claimed_success=info["exitFlag"] == OPTIMAL, iterations=int(info["iter"]),
        backend_times=reported_times(backend_setup_time_s=timing.get("tsetup"),
                                     backend_solve_time_s=timing.get("tsolve")),
        info={"scale": scale})
    return output, np.asarray(result["x"])[:dofs], np.asarray(result["z"])[:m]


def make_solve(formulation: str) -> SolveFunction:
    """The solve function of ``ecos-native`` in ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    SolveFunction
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem, with the accuracy
        table's options for ``eps`` at the problem's scale; the warm start is ignored. Its
        claim is ECOS's exit flag 0; a dual whose Q has no Cholesky factor reads
        ``unsupported: not positive definite``.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        n = problem.n_contacts
        identity = sp.identity(n, format="csc")
        if formulation == "primal":
            primal = primal_qp(problem)
            root = np.sqrt(primal.P.diagonal())
            output, _, multipliers = _solved(np.zeros(primal.q.size), primal.A,
                                             primal.lower, sp.diags(root, format="csc"),
                                             -primal.q / root, eps, scale)
            output.impulses = multipliers
            return output
        if formulation == "dual-factored":
            L = factored_rows(problem)
            output, impulses, _ = _solved(problem.b, identity, np.zeros(n), L,
                                          np.zeros(L.shape[0]), eps, scale)
            output.impulses = impulses
            return output
        try:
            R = np.linalg.cholesky(problem.Q.toarray()).T
        except np.linalg.LinAlgError:
            return SolverOutput(impulses=None, status=NOT_POSITIVE_DEFINITE,
                                claimed_success=False, info={"scale": scale})
        output, impulses, _ = _solved(problem.b, identity, np.zeros(n), sp.csc_matrix(R),
                                      np.zeros(n), eps, scale)
        output.impulses = impulses
        return output

    return solve


if ecos is None:
    register_missing({NAME: FORMULATIONS}, IMPORT_ERROR)
else:
    register_pairs(NAME, {formulation: make_solve(formulation) for formulation in FORMULATIONS},
                   "ecos")
