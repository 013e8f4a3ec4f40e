"""Backends reached through qpsolvers (https://github.com/qpsolvers/qpsolvers), in three forms.

* ``dual``: ``min 1/2 l^T Q l + b^T l  s.t.  l >= 0`` as ``P = Q, q = b, lb = 0``.
* ``primal``: ``min 1/2 v^T M v - (M v-)^T v  s.t.  G^T v >= lower`` as ``G = -G^T``,
  ``h = -lower``. qpsolvers' Lagrangian is ``1/2 v^T P v + q^T v + z^T (G v - h)``, so
  stationarity reads ``M (v - v-) = G z``: the impulses are ``l = z`` (``z >= 0``).
* ``dual-factored``: ``min 1/2 y^T y + b^T l  s.t.  L l = y, l >= 0`` (Q never formed).

quadprog and ECOS factor P and refuse a singular one. Their ``dual`` still runs (Q is
regular on some problems) and a refusal reads ``unsupported: not positive definite``;
their ``dual-factored`` (P = diag(0, I), singular by construction) is unusable. The
variants ``quadprog-reg`` and ``ecos-reg`` solve ``Q + delta I`` instead, with delta
from the accuracy table: a different problem, named as such.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

try:
    import qpsolvers
except ImportError as _error:  # every solver of this family drops out and says why
    qpsolvers = None
    IMPORT_ERROR = f"import failed: {_error}"

from qpbench.problem import metrics
from qpbench.problem.formulations import factored_dual_qp, primal_qp, regularized
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverOutput, SolverSpec, reported_times
from qpbench.solvers.quiet import c_stdout_silenced, highs_banner_silenced
from qpbench.solvers.registry import register, register_unusable

BACKEND = "qpsolvers"
SOLVERS = ("osqp", "clarabel", "proxqp", "piqp", "daqp", "highs", "scs", "ecos", "cvxopt",
           "quadprog", "qpalm")
FORMULATIONS = ("dual", "primal", "dual-factored")
# backends whose qpsolvers wrapper passes initvals on to the solver
WARM_START = frozenset({"osqp", "proxqp", "qpalm", "scs", "cvxopt", "daqp"})
# backends that factor P and need it positive definite
POSITIVE_DEFINITE_ONLY = frozenset({"quadprog", "ecos"})
# regularized variants: name -> the backend that solves Q + delta I
REGULARIZED = {"quadprog-reg": "quadprog", "ecos-reg": "ecos"}
NOT_POSITIVE_DEFINITE = "unsupported: not positive definite"


def _claim(solver: str, solution: qpsolvers.Solution) -> tuple[str, int | None]:
    """The backend's own status string and iteration count, read from ``solution.extras``."""
    extras: dict[str, Any] = getattr(solution, "extras", None) or {}
    info = extras.get("info")
    if solver in ("osqp", "proxqp", "piqp", "qpalm") and info is not None:
        return str(info.status), _integer(getattr(info, "iter", None))
    if solver == "clarabel" and "status" in extras:
        return str(extras["status"]), None
    if solver == "scs" and "status" in extras:
        return str(extras["status"]), _integer(extras.get("iter"))
    if solver == "ecos" and "infostring" in extras:
        return str(extras["infostring"]), _integer(extras.get("iter"))
    if solver == "cvxopt" and "status" in extras:
        return str(extras["status"]), _integer(extras.get("iterations"))
    if solver == "quadprog" and "iterations" in extras:
        iterations = np.ravel(extras["iterations"])
        return "solved", _integer(iterations[0] if iterations.size else None)
    # daqp (exitflag > 0) and highs (model status kOptimal) only report found / not found
    return ("found" if solution.found else "not found"), None


def _reported_times(solver: str, solution: qpsolvers.Solution) -> dict[str, float]:
    """The backend's own split of its time: OSQP's ``setup_time`` / ``solve_time`` from its
    info, else qpsolvers' ``build_time`` / ``solve_time`` where it records them."""
    extras: dict[str, Any] = getattr(solution, "extras", None) or {}
    info = extras.get("info")
    source, setup, solve = solution, "build_time", "solve_time"
    if solver == "osqp" and info is not None:
        source, setup = info, "setup_time"
    return reported_times(backend_setup_time_s=getattr(source, setup, None),
                          backend_solve_time_s=getattr(source, solve, None))


def _integer(value: Any) -> int | None:
    try:
        return None if value is None else int(value)
    except (TypeError, ValueError):
        return None


def _build(formulation: str, problem: ImpactProblem, solver: str, delta: float | None
           ) -> tuple[qpsolvers.Problem, Callable[[qpsolvers.Solution], np.ndarray | None]]:
    """The qpsolvers problem of ``formulation`` and how to read l from its solution."""
    dense = solver in ("quadprog", "daqp")

    def matrix(a: Any) -> Any:
        return a.toarray() if dense and hasattr(a, "toarray") else a

    if formulation == "dual":
        Q = problem.Q if delta is None else regularized(problem.Q, delta)
        qp = qpsolvers.Problem(P=matrix(Q), q=problem.b, lb=np.zeros(problem.n_contacts))
        return qp, lambda solution: solution.x
    if formulation == "primal":
        primal = primal_qp(problem)
        qp = qpsolvers.Problem(P=matrix(primal.P), q=primal.q, G=matrix(-primal.A),
                               h=-primal.lower)
        return qp, lambda solution: solution.z
    if formulation == "dual-factored":
        factored = factored_dual_qp(problem)
        qp = qpsolvers.Problem(P=matrix(factored.P), q=factored.q, G=matrix(factored.G),
                               h=factored.h, A=matrix(factored.A), b=factored.b_eq)
        return qp, lambda solution: (None if solution.x is None
                                     else factored.impulses(solution.x))
    raise ValueError(f"unknown formulation {formulation!r}")


def _refused_positive_definite(messages: list[str]) -> bool:
    return any("positive definite" in message for message in messages)


def make_solve(name: str, solver: str, formulation: str) -> Callable[..., SolverOutput]:
    """The solve function of ``name`` (a qpsolvers backend, or its ``-reg`` variant).

    Parameters
    ----------
    name : str
        The solver's name in qpbench, whose accuracy-table row gives the options
        (``quadprog-reg``'s includes the regularization).
    solver : str
        The qpsolvers backend that runs it (``quadprog``).
    formulation : str
        ``dual``, ``primal`` or ``dual-factored``.

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` on an ImpactProblem: the options for ``eps``
        at the problem's scale, the warm start in the formulation's variables as qpsolvers'
        ``initvals``; its claim is qpsolvers' ``found``, a refused singular P reads
        ``unsupported: not positive definite``, and ``info`` holds the scale (and delta).
    """

    def solve(problem: ImpactProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        scale = metrics.scale(problem)
        options = accuracy.options_for(name, eps, scale)
        delta = None
        if "regularization" in options:
            delta = float(options.pop("regularization")) * max(
                float(np.max(problem.diag_Q, initial=0.0)), metrics.TINY)
        qp, impulses_of = _build(formulation, problem, solver, delta)
        initvals = _initial_values(formulation, problem, warm_start)
        messages: list[str] = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            quiet = c_stdout_silenced() if solver == "osqp" else contextlib.nullcontext()
            with quiet:
                try:
                    solution = qpsolvers.solve_problem(qp, solver=solver, initvals=initvals,
                                                       **options)
                except (qpsolvers.ProblemError, qpsolvers.SolverError, ValueError) as error:
                    solution = None
                    messages.append(str(error))
            messages.extend(str(warning.message) for warning in caught)
        info: dict[str, Any] = {"scale": scale}
        if delta is not None:
            info["regularization_delta"] = delta
        if solution is None:
            refused = _refused_positive_definite(messages)
            status = NOT_POSITIVE_DEFINITE if refused else f"error: {messages[0]}"
            return SolverOutput(impulses=None, status=status, claimed_success=False,
                                info=info)
        status, iterations = _claim(solver, solution)
        if not solution.found and _refused_positive_definite(messages):
            status = NOT_POSITIVE_DEFINITE
        impulses = impulses_of(solution) if solution.found or solution.x is not None else None
        return SolverOutput(
            impulses=None if impulses is None or np.size(impulses) == 0 else impulses,
            status=status,
            claimed_success=bool(solution.found),
            iterations=iterations,
            backend_times=_reported_times(solver, solution),
            info=info,
        )

    return solve


def _initial_values(formulation: str, problem: ImpactProblem, warm_start: np.ndarray | None
                    ) -> np.ndarray | None:
    """The warm start in the formulation's variables: l, v+(l) on free dofs, or (l, L l)."""
    if warm_start is None:
        return None
    impulses = np.asarray(warm_start, dtype=float)
    if formulation == "dual":
        return impulses
    if formulation == "primal":
        return problem.v_plus(impulses)[problem.m_inv > 0]
    factored = factored_dual_qp(problem)
    return np.concatenate([impulses, factored.A[:, : problem.n_contacts] @ impulses])


def _version(solver: str) -> str:
    """qpsolvers' version and the backend's package version."""
    from importlib import metadata

    package = {"proxqp": "proxsuite", "highs": "highspy"}.get(solver, solver)
    try:
        return f"{metadata.version(package)} (qpsolvers {qpsolvers.__version__})"
    except metadata.PackageNotFoundError:
        return f"qpsolvers {qpsolvers.__version__}"


def _register_all() -> None:
    if qpsolvers is None:
        for name in (*SOLVERS, *REGULARIZED):
            register_unusable(name, ("dual",) if name in REGULARIZED else FORMULATIONS,
                              BACKEND, IMPORT_ERROR)
        return
    for solver in SOLVERS:
        if solver not in qpsolvers.available_solvers:
            register_unusable(solver, FORMULATIONS, BACKEND,
                              f"qpsolvers has no '{solver}' installed")
            continue
        for formulation in FORMULATIONS:
            if solver in POSITIVE_DEFINITE_ONLY and formulation == "dual-factored":
                register(SolverSpec(name=solver, formulation=formulation, backend=BACKEND,
                                    solve=None, version=_version(solver),
                                    reason=f"{NOT_POSITIVE_DEFINITE} (P = diag(0, I) is "
                                    "singular)"))
                continue
            register(SolverSpec(name=solver, formulation=formulation, backend=BACKEND,
                                solve=make_solve(solver, solver, formulation),
                                version=_version(solver), warm_start=solver in WARM_START,
                                description=f"{solver} through qpsolvers",
                                prepare=highs_banner_silenced if solver == "highs" else None))
    for name, solver in REGULARIZED.items():
        if solver not in qpsolvers.available_solvers:
            register_unusable(name, ("dual",), BACKEND, f"qpsolvers has no '{solver}' installed")
            continue
        register(SolverSpec(name=name, formulation="dual", backend=BACKEND,
                            solve=make_solve(name, solver, "dual"), version=_version(solver),
                            warm_start=False,
                            description=f"{solver} on Q + delta I (delta in the accuracy table)"))


_register_all()
