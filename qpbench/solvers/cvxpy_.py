"""Backends reached through cvxpy (https://www.cvxpy.org), in three forms.

* ``dual``: ``min 1/2 quad_form(l, Q) + b^T l  s.t.  l >= 0``. Q is certified positive
  semi-definite here (:func:`qpbench.problem.formulations.certify_psd`) before it is
  wrapped in ``psd_wrap``; without a certificate cvxpy runs its own check.
* ``dual-factored``: ``min 1/2 sum_squares(L l) + b^T l  s.t.  l >= 0``, ``L = M^-1/2 G``
  (Q never formed; the natural conic form).
* ``primal``: ``min 1/2 sum_squares(M^1/2 (v - v-))  s.t.  G^T v >= lower``; cvxpy's
  ``dual_value`` of a ``>=`` constraint is ``>= 0`` and equals the impulses l.

cvxpy's compile step is inside ``time_s`` like everything else a cvxpy user waits for, and
also stored alone as ``compile_time_s``; the solver's own reported time is
``backend_solve_time_s``. IPOPT runs through cvxpy's NLP path
(``nlp=True``) as ``cvxpy-ipopt``, started at the warm start when one is given.

cvxpy takes seconds to import, so it is imported at the first solve; a solver is listed
as usable when cvxpy and the solver's package are installed.
"""

from __future__ import annotations

import contextlib
import importlib.util
import warnings
from collections.abc import Callable
from importlib import metadata
from typing import TYPE_CHECKING, Any

import numpy as np

from qpbench.problem import metrics
from qpbench.problem.formulations import certify_psd, factored_rows, primal_qp
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec, reported_times
from qpbench.solvers.quiet import c_stdout_silenced, highs_banner_silenced
from qpbench.solvers.registry import register, register_unusable

if TYPE_CHECKING:
    import cvxpy as cp

BACKEND = "cvxpy"
# cvxpy solver name -> the package that provides it
SOLVERS = {"CLARABEL": "clarabel", "OSQP": "osqp", "SCS": "scs", "ECOS": "ecos",
           "PIQP": "piqp", "PROXQP": "proxsuite", "CVXOPT": "cvxopt", "DAQP": "daqp",
           "HIGHS": "highspy", "IPOPT": "cyipopt"}
FORMULATIONS = ("dual", "primal", "dual-factored")
NLP_SOLVERS = frozenset({"IPOPT"})  # solved through cvxpy's NLP path, which takes a start


def qpbench_name(solver: str) -> str:
    """``cvxpy-<solver lower>``.

    Parameters
    ----------
    solver : str
        cvxpy's solver name, a key of SOLVERS (``CLARABEL``).

    Returns
    -------
    str
        The name qpbench lists it under (``cvxpy-clarabel``).
    """
    return f"cvxpy-{solver.lower()}"


class Model:
    """One formulation posed in cvxpy, with how to read the impulses and set a start."""

    def __init__(self, problem: ImpactProblem, formulation: str) -> None:
        import cvxpy as cp

        self.formulation = formulation
        self.info: dict[str, Any] = {}
        n = problem.n_contacts
        if formulation == "primal":
            primal = primal_qp(problem)
            mass = primal.P.diagonal()
            self.free = primal.free
            self.variable = cp.Variable(int(self.free.sum()), name="v")
            v_minus = problem.v_minus[self.free]
            self.constraint = primal.A @ self.variable >= primal.lower
            objective = 0.5 * cp.sum_squares(cp.multiply(np.sqrt(mass), self.variable - v_minus))
        else:
            self.variable = cp.Variable(n, name="l")
            self.constraint = self.variable >= 0
            if formulation == "dual":
                certificate = certify_psd(problem)
                self.info["psd_certificate"] = (
                    f"{certificate.method}: {certificate.value:.3e} "
                    f"(tolerance {certificate.tolerance:.1e})")
                Q = problem.Q
                quadratic = cp.quad_form(self.variable, cp.psd_wrap(Q) if certificate.psd else Q)
                self.info["psd_wrap"] = bool(certificate.psd)
            elif formulation == "dual-factored":
                quadratic = cp.sum_squares(factored_rows(problem) @ self.variable)
            else:
                raise ValueError(f"unknown formulation {formulation!r}")
            objective = 0.5 * quadratic + problem.b @ self.variable
        self.problem = cp.Problem(cp.Minimize(objective), [self.constraint])

    def impulses(self) -> np.ndarray | None:
        """The impulses of the last solve: the constraint's dual value (primal) or l.

        Returns
        -------
        np.ndarray or None
            l, flat; None when cvxpy holds no value (no solve, or a failed one).
        """
        value = self.constraint.dual_value if self.formulation == "primal" else self.variable.value
        return None if value is None else np.asarray(value, dtype=float).ravel()

    def start_at(self, problem: ImpactProblem, warm_start: np.ndarray) -> None:
        """Sets the variable's value from warm-start impulses (l, or v+(l) for primal).

        Parameters
        ----------
        problem : ImpactProblem
            The problem the model was posed from, for v+(l) on its free degrees of freedom.
        warm_start : np.ndarray
            A guess of l, shape (n,).
        """
        impulses = np.asarray(warm_start, dtype=float)
        if self.formulation == "primal":
            self.variable.value = problem.v_plus(impulses)[self.free]
        else:
            self.variable.value = impulses


def make_solve(solver: str, formulation: str) -> Callable[..., SolverOutput]:
    """The solve function of ``cvxpy-<solver>`` on ``formulation``.

    Parameters
    ----------
    solver : str
        cvxpy's solver name, a key of SOLVERS.
    formulation : str
        ``dual``, ``dual-factored`` or ``primal``.

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem: the model posed and
        solved with the accuracy table's row for ``eps`` at the problem's scale (the warm
        start used only on the NLP path); its claim is cvxpy's ``optimal``, its backend
        times cvxpy's compile time and the solver's own, a solver error an output with no
        impulses.
    """
    name = qpbench_name(solver)

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        import cvxpy as cp

        scale = metrics.scale(problem)
        options = accuracy.options_for(name, eps, scale)
        model = Model(problem, formulation)
        if warm_start is not None and solver in NLP_SOLVERS:
            model.start_at(problem, warm_start)
        extra = {"nlp": True} if solver in NLP_SOLVERS else {}
        quiet = c_stdout_silenced() if solver in ("OSQP", "IPOPT") else contextlib.nullcontext()
        error: Exception | None = None
        with warnings.catch_warnings(), quiet:
            warnings.simplefilter("ignore")
            try:
                model.problem.solve(solver=solver, **extra, **options)
            except (cp.error.SolverError, ValueError, ArithmeticError) as raised:
                error = raised
        info = {"scale": scale, **model.info}
        times = _reported_times(model.problem)
        if error is not None:
            return SolverOutput(impulses=None, status=f"error: {type(error).__name__}: {error}",
                                claimed_success=False, backend_times=times, info=info)
        status = str(model.problem.status)
        stats = model.problem.solver_stats
        iterations = getattr(stats, "num_iters", None) if stats is not None else None
        return SolverOutput(
            impulses=model.impulses(),
            status=status,
            claimed_success=status == cp.OPTIMAL,
            iterations=int(iterations) if isinstance(iterations, int | np.integer) else None,
            backend_times=times,
            info=info,
        )

    return solve


def _reported_times(problem: cp.Problem) -> dict[str, float]:
    """cvxpy's compilation time of the last solve and the solver's own set-up and solve times,
    where they were recorded."""
    stats = problem.solver_stats
    return reported_times(compile_time_s=getattr(problem, "compilation_time", None),
                          backend_setup_time_s=getattr(stats, "setup_time", None),
                          backend_solve_time_s=getattr(stats, "solve_time", None))


def _version(solver: str) -> str:
    return f"{metadata.version(SOLVERS[solver])} (cvxpy {metadata.version('cvxpy')})"


def _installed(package: str) -> bool:
    return importlib.util.find_spec(package) is not None


def _register_all() -> None:
    for solver, package in SOLVERS.items():
        name = qpbench_name(solver)
        if not _installed("cvxpy"):
            register_unusable(name, FORMULATIONS, BACKEND, "import failed: no module 'cvxpy'")
            continue
        if not _installed(package):
            register_unusable(name, FORMULATIONS, BACKEND,
                              f"cvxpy's {solver} needs the package '{package}'")
            continue
        for formulation in FORMULATIONS:
            if solver in NLP_SOLVERS and formulation == "primal":
                register(SolverSpec(name=name, formulation=formulation, backend=BACKEND,
                                    solve=None, version=_version(solver),
                                    reason="cvxpy's NLP path gives no constraint multipliers "
                                    "(no l)"))
                continue
            register(SolverSpec(name=name, formulation=formulation, backend=BACKEND,
                                solve=make_solve(solver, formulation), version=_version(solver),
                                warm_start=solver in NLP_SOLVERS,
                                description=f"{solver} through cvxpy",
                                prepare=highs_banner_silenced if solver == "HIGHS" else None))


_register_all()
