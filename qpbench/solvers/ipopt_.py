"""IPOPT through cyipopt, configured as SCISim's LCP0OperatorIpopt.

* ``dual``: ``min 1/2 l^T Q l + b^T l`` with the bounds ``l >= 0`` and no constraints;
  gradient ``Q l + b``, Hessian ``Q`` (lower triangle, constant).
* ``primal``: ``min 1/2 (v - v-)^T M (v - v-)`` with ``g(v) = A v >= lower`` (``A = G^T``
  on the free degrees of freedom); Jacobian ``A`` and Hessian ``M`` are constant.
  IPOPT's Lagrangian is ``f + mult_g^T g``, so a constraint active at its lower bound has
  ``mult_g <= 0`` and stationarity reads ``M (v - v-) = -A^T mult_g``: ``l = -mult_g``.

Options come from the accuracy table (``hessian_constant``, ``jac_c_constant``,
``jac_d_constant``, ``linear_solver mumps``, ``tol``), plus ``bound_relax_factor``: IPOPT's
default relaxes bounds by 1e-8, which alone caps the residual near 1e-8, so the table
tightens it with the level. The start is l = 0 (v = v- in the primal) or the warm start.
``claimed_success`` is IPOPT's status 0, "Solve_Succeeded"; acceptable-level termination
is switched off in the table.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import metadata
from typing import Any

import numpy as np
import scipy.sparse as sp

try:
    import cyipopt
except ImportError as _error:  # ipopt drops out and says why
    cyipopt = None
    IMPORT_ERROR = f"import failed: {_error}"

from qpbench.problem import metrics
from qpbench.problem.formulations import primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.quiet import c_stdout_silenced
from qpbench.solvers.registry import register, register_unusable

BACKEND = "cyipopt"
NAME = "ipopt"
FORMULATIONS = ("dual", "primal")
INFINITY = 2e19  # IPOPT's default nlp_upper_bound_inf is 1e19


class QuadraticProgram:
    """``min 1/2 x^T H x + c^T x  s.t.  J x >= lower`` for cyipopt, with constant H and J.

    The callbacks are the ones cyipopt asks for; ``iterations`` counts IPOPT's iterations.
    """

    def __init__(self, hessian: sp.spmatrix, linear: np.ndarray, jacobian: sp.spmatrix
                 ) -> None:
        lower = sp.tril(sp.coo_matrix(hessian)).tocoo()
        self.hessian_matrix = sp.csr_matrix(hessian)
        self.hessian_rows, self.hessian_cols = lower.row, lower.col
        self.hessian_values = lower.data
        self.linear = linear
        jacobian = sp.coo_matrix(jacobian)
        self.jacobian_matrix = sp.csr_matrix(jacobian)
        self.jacobian_rows, self.jacobian_cols = jacobian.row, jacobian.col
        self.jacobian_values = jacobian.data
        self.iterations = 0

    def objective(self, x: np.ndarray) -> float:
        """The objective ``1/2 x^T H x + c^T x``.

        Parameters
        ----------
        x : np.ndarray
            The point, shape (k,).

        Returns
        -------
        float
            Its value.
        """
        return float(0.5 * x @ (self.hessian_matrix @ x) + self.linear @ x)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """The objective's gradient ``H x + c``.

        Parameters
        ----------
        x : np.ndarray
            The point, shape (k,).

        Returns
        -------
        np.ndarray
            The gradient, shape (k,).
        """
        return self.hessian_matrix @ x + self.linear

    def constraints(self, x: np.ndarray) -> np.ndarray:
        """The constraint values ``J x``.

        Parameters
        ----------
        x : np.ndarray
            The point, shape (k,).

        Returns
        -------
        np.ndarray
            One value per constraint row.
        """
        return self.jacobian_matrix @ x

    def jacobianstructure(self) -> tuple[np.ndarray, np.ndarray]:
        """The places of J's stored entries.

        Returns
        -------
        rows, cols : np.ndarray
            Their row and column indices, in the order of :meth:`jacobian`'s values.
        """
        return self.jacobian_rows, self.jacobian_cols

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """J's stored entries, the same at every point (J is constant).

        Parameters
        ----------
        x : np.ndarray
            The point, shape (k,).

        Returns
        -------
        np.ndarray
            The values at :meth:`jacobianstructure`'s places.
        """
        return self.jacobian_values

    def hessianstructure(self) -> tuple[np.ndarray, np.ndarray]:
        """The places of the lower triangle of H's stored entries.

        Returns
        -------
        rows, cols : np.ndarray
            Their row and column indices, in the order of :meth:`hessian`'s values.
        """
        return self.hessian_rows, self.hessian_cols

    def hessian(self, x: np.ndarray, multipliers: np.ndarray, objective_factor: float
                ) -> np.ndarray:
        """The Lagrangian's Hessian: ``objective_factor * H`` (the constraints are linear).

        Parameters
        ----------
        x : np.ndarray
            The point, shape (k,).
        multipliers : np.ndarray
            The constraints' multipliers; unused, as linear constraints add no curvature.
        objective_factor : float
            IPOPT's factor of the objective.

        Returns
        -------
        np.ndarray
            The lower triangle's values at :meth:`hessianstructure`'s places.
        """
        return objective_factor * self.hessian_values

    def intermediate(self, algorithm_mode: int, iteration: int, *values: Any) -> bool:
        """IPOPT's per-iteration callback: records the iteration count.

        Parameters
        ----------
        algorithm_mode : int
            0 in the regular mode, 1 in restoration; unused.
        iteration : int
            The iteration IPOPT has reached, stored as ``iterations``.
        *values : Any
            The iteration's objective, infeasibilities, step sizes and so on; unused.

        Returns
        -------
        bool
            Always True: IPOPT goes on.
        """
        self.iterations = int(iteration)
        return True


def _posed(formulation: str, problem: ImpactProblem, warm_start: np.ndarray | None
           ) -> tuple[QuadraticProgram, dict[str, np.ndarray], np.ndarray,
                      Callable[[np.ndarray, dict[str, Any]], np.ndarray]]:
    """The program, its bounds, its start and how to read l from (x, info)."""
    n = problem.n_contacts
    start = np.zeros(n) if warm_start is None else np.asarray(warm_start, dtype=float)
    if formulation == "dual":
        program = QuadraticProgram(problem.Q, problem.b, sp.csr_matrix((0, n)))
        bounds = {"lb": np.zeros(n), "ub": np.full(n, INFINITY),
                  "cl": np.zeros(0), "cu": np.zeros(0)}
        return program, bounds, start, lambda x, info: x
    primal = primal_qp(problem)
    k = int(primal.free.sum())
    program = QuadraticProgram(primal.P, primal.q, primal.A)
    bounds = {"lb": np.full(k, -INFINITY), "ub": np.full(k, INFINITY),
              "cl": primal.lower, "cu": np.full(n, INFINITY)}
    v_start = problem.v_plus(start)[primal.free]
    return program, bounds, v_start, lambda x, info: -np.asarray(info["mult_g"], dtype=float)


def make_solve(formulation: str) -> Callable[..., SolverOutput]:
    """The solve function of ``ipopt`` on ``formulation``.

    Parameters
    ----------
    formulation : str
        ``dual`` (bounds l >= 0) or ``primal`` (velocities with ``A v >= lower``).

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem: the accuracy table's
        ``ipopt`` row for ``eps`` at the problem's scale, the warm start (l, or v+ of it in
        the primal) or l = 0 as the start; its claim is IPOPT's status 0, its ``info`` the
        scale.
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        options = accuracy.options_for(NAME, eps, scale)
        program, bounds, start, impulses_of = _posed(formulation, problem, warm_start)
        nlp = cyipopt.Problem(n=start.size, m=bounds["cl"].size, problem_obj=program, **bounds)
        for key, value in options.items():
            nlp.add_option(key, value)
        with c_stdout_silenced():
            x, info = nlp.solve(start)
        message = info.get("status_msg", b"")
        message = message.decode(errors="replace") if isinstance(message, bytes) else message
        status_code = int(info.get("status", -199))
        return SolverOutput(
            impulses=impulses_of(np.asarray(x, dtype=float), info),
            status=f"{status_code}: {message.strip()}",
            claimed_success=status_code == 0,
            iterations=program.iterations,
            info={"scale": scale},
        )

    return solve


def _version() -> str:
    ipopt = ".".join(str(part) for part in cyipopt.IPOPT_VERSION)
    return f"Ipopt {ipopt} (cyipopt {metadata.version('cyipopt')})"


if cyipopt is None:
    register_unusable(NAME, FORMULATIONS, BACKEND, IMPORT_ERROR)
else:
    for _formulation in FORMULATIONS:
        register(SolverSpec(name=NAME, formulation=_formulation, backend=BACKEND,
                            solve=make_solve(_formulation), version=_version(), warm_start=True,
                            description="IPOPT through cyipopt, configured as SCISim"))
