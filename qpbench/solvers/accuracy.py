"""THE table that maps qpbench's accuracy levels to each solver's own options.

qpbench's accuracy level eps is a bound on its own residual,
``||min(D l, Q l + b)||_inf / scale`` with ``scale = max(||b||_inf, tiny)``.
Backends use absolute tolerances on their own residuals, so each row maps
``(eps, scale)`` to that backend's options. A value is either a constant or a
function ``f(eps, scale)`` whose docstring's first line says how it follows from eps
(the report prints it). This module is the only place solver options are set.

Rules the rows follow: feasibility and stationarity tolerances are ``eps * scale``
(velocities); a duality gap is ``eps * scale^2`` for first-order methods, but
``eps^2 * scale^2`` for interior points, because on a degenerate contact
(``l_i = w_i = 0``) they stop with ``min(l_i, w_i) ~ sqrt(l_i w_i)``; IPOPT's
acceptable-level exit is off so that its "success" means its tolerance; every
regularization is a named ``*-reg`` variant with its delta here.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Any

LEVELS: tuple[float, ...] = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
DEFAULT_TIME_LIMIT_S = 60.0

OptionValue = Any | Callable[[float, float], Any]


def _absolute(eps: float, scale: float) -> float:
    """eps * scale: our relative level as an absolute velocity tolerance."""
    return eps * scale


def _relative(eps: float, scale: float) -> float:
    return eps


def _inner_tolerance(eps: float, scale: float) -> float:
    """0.01 * eps: relative tolerance of an inner linear solve (CG)"""
    return 0.01 * eps


def _gap(eps: float, scale: float) -> float:
    """eps * scale^2

    An absolute duality gap l^T w (velocity^2 when diag(Q) ~ 1).
    """
    return eps * scale * scale


def _tenth(eps: float, scale: float) -> float:
    """0.1 * eps: the accuracy level of an inner solve (staggered projections' two QPs)"""
    return 0.1 * eps


def _ipm_gap(eps: float, scale: float) -> float:
    """max(eps^2, 1e-15) * scale^2

    An interior point leaves min(l_i, w_i) ~ sqrt(l_i w_i) on a degenerate contact
    (l_i = w_i = 0), so its gap must be eps^2 for a residual eps.
    """
    return max(eps * eps, 1e-15) * scale * scale


def _ipopt_tol(eps: float, scale: float) -> float:
    """max(eps^2, 1e-16) * scale^2

    As ``_ipm_gap`` (IPOPT's tol bounds its complementarity l_i z_i), with the floor
    IPOPT still reaches in double precision.
    """
    return max(eps * eps, 1e-16) * scale * scale


def _bound_relax(eps: float, scale: float) -> float:
    """min(1e-8, 0.01 * eps)

    IPOPT relaxes every bound by this relative amount (default 1e-8), which alone
    leaves a residual near 1e-8.
    """
    return min(1e-8, 0.01 * eps)


def _ipm_gap_relative(eps: float, scale: float) -> float:
    """max(eps^2, 1e-15)"""
    return max(eps * eps, 1e-15)


def _conic_gap(eps: float, scale: float) -> float:
    """max(eps^2, 1e-12)

    ECOS poses the quadratic as a second-order cone, where l errs by ~sqrt(gap); below
    1e-12 it stops at "close to optimal".
    """
    return max(eps * eps, 1e-12)


def _cvxopt_cone_gap(eps: float, scale: float) -> float:
    """max(eps^2, 1e-10) * scale^2

    cvxpy poses CVXOPT a cone program (the quadratic as a cone, so l errs by ~sqrt(gap))
    that fails outright below a gap of about 1e-10.
    """
    return max(eps * eps, 1e-10) * scale * scale


def _cvxopt_cone_gap_relative(eps: float, scale: float) -> float:
    """max(eps^2, 1e-10)"""
    return max(eps * eps, 1e-10)


def _ktratio(eps: float, scale: float) -> float:
    """min(1e-6, eps)"""
    return min(1e-6, eps)


def _regularization(eps: float, scale: float) -> float:
    """0.1 * eps * max(diag Q)

    The delta of a ``*-reg`` variant, which solves Q + delta I (the backend multiplies
    this value by max(diag Q)).
    """
    return 0.1 * eps


def _highs_reg(eps: float, scale: float) -> float:
    """0.1 * eps

    HiGHS's own Hessian regularization of its QP solver (default 1e-7, which alone
    stops it near a residual of 1e-7).
    """
    return 0.1 * eps


ITERATIVE_MAX_ITER = 200_000  # first-order methods (ADMM, proximal, SCS)
INTERIOR_MAX_ITER = 500  # interior-point methods


OPTIONS: dict[str, dict[str, OptionValue]] = {
    # --- through qpsolvers -----------------------------------------------------
    "osqp": {"eps_abs": _absolute, "eps_rel": _relative, "polishing": True,
             "max_iter": ITERATIVE_MAX_ITER, "time_limit": DEFAULT_TIME_LIMIT_S},
    "clarabel": {"tol_gap_abs": _ipm_gap, "tol_gap_rel": _ipm_gap_relative, "tol_feas": _relative,
                 "tol_ktratio": _ktratio, "max_iter": INTERIOR_MAX_ITER,
                 "time_limit": DEFAULT_TIME_LIMIT_S},
    "proxqp": {"eps_abs": _absolute, "eps_rel": 0.0, "check_duality_gap": True,
               "eps_duality_gap_abs": _gap, "eps_duality_gap_rel": 0.0,
               "max_iter": ITERATIVE_MAX_ITER},
    "piqp": {"eps_abs": _absolute, "eps_rel": _relative, "check_duality_gap": True,
             "eps_duality_gap_abs": _ipm_gap, "eps_duality_gap_rel": _ipm_gap_relative,
             "max_iter": INTERIOR_MAX_ITER},
    "daqp": {"primal_tol": _absolute, "dual_tol": _absolute, "iter_limit": 100_000,
             "time_limit": DEFAULT_TIME_LIMIT_S},
    "highs": {"primal_feasibility_tolerance": _absolute,
              "dual_feasibility_tolerance": _absolute, "qp_regularization_value": _highs_reg,
              "time_limit": DEFAULT_TIME_LIMIT_S},
    "scs": {"eps_abs": _absolute, "eps_rel": _relative, "max_iters": ITERATIVE_MAX_ITER,
            "time_limit_secs": DEFAULT_TIME_LIMIT_S},
    "ecos": {"abstol": _conic_gap, "reltol": _conic_gap, "feastol": _relative,
             "max_iters": INTERIOR_MAX_ITER},
    "ecos-reg": {"abstol": _conic_gap, "reltol": _conic_gap, "feastol": _relative,
                 "max_iters": INTERIOR_MAX_ITER, "regularization": _regularization},
    "cvxopt": {"abstol": _ipm_gap, "reltol": _ipm_gap_relative, "feastol": _relative,
               "maxiters": INTERIOR_MAX_ITER},
    "quadprog": {},  # an exact active-set method: no tolerance, no limit
    "quadprog-reg": {"regularization": _regularization},
    "qpalm": {"eps_abs": _absolute, "eps_rel": _relative, "max_iter": ITERATIVE_MAX_ITER,
              "time_limit": DEFAULT_TIME_LIMIT_S},
    # --- IPOPT through cyipopt, configured as SCISim's LCP0OperatorIpopt ----------
    "ipopt": {"tol": _ipopt_tol, "bound_relax_factor": _bound_relax, "acceptable_iter": 0,
              "max_iter": 3000, "max_cpu_time": DEFAULT_TIME_LIMIT_S, "linear_solver": "mumps",
              "hessian_constant": "yes", "jac_c_constant": "yes", "jac_d_constant": "yes",
              "print_level": 0, "sb": "yes"},
    # --- through cvxpy (its own option names per solver) ----------------------------
    "cvxpy-osqp": {"eps_abs": _absolute, "eps_rel": _relative, "polishing": True,
                   "max_iter": ITERATIVE_MAX_ITER, "time_limit": DEFAULT_TIME_LIMIT_S},
    "cvxpy-clarabel": {"tol_gap_abs": _ipm_gap, "tol_gap_rel": _ipm_gap_relative,
                       "tol_feas": _relative, "tol_ktratio": _ktratio,
                       "max_iter": INTERIOR_MAX_ITER, "time_limit": DEFAULT_TIME_LIMIT_S},
    "cvxpy-proxqp": {"eps_abs": _absolute, "eps_rel": 0.0, "max_iter": ITERATIVE_MAX_ITER},
    "cvxpy-piqp": {"eps_abs": _absolute, "eps_rel": _relative, "check_duality_gap": True,
                   "eps_duality_gap_abs": _ipm_gap, "eps_duality_gap_rel": _ipm_gap_relative,
                   "max_iter": INTERIOR_MAX_ITER},
    "cvxpy-daqp": {"primal_tol": _absolute, "dual_tol": _absolute, "iter_limit": 100_000,
                   "time_limit": DEFAULT_TIME_LIMIT_S},
    "cvxpy-highs": {"primal_feasibility_tolerance": _absolute,
                    "dual_feasibility_tolerance": _absolute,
                    "qp_regularization_value": _highs_reg,
                    "time_limit": DEFAULT_TIME_LIMIT_S},
    "cvxpy-scs": {"eps_abs": _absolute, "eps_rel": _relative, "max_iters": ITERATIVE_MAX_ITER,
                  "time_limit_secs": DEFAULT_TIME_LIMIT_S},
    "cvxpy-ecos": {"abstol": _conic_gap, "reltol": _conic_gap, "feastol": _relative,
                   "max_iters": INTERIOR_MAX_ITER},
    "cvxpy-cvxopt": {"abstol": _cvxopt_cone_gap, "reltol": _cvxopt_cone_gap_relative,
                     "feastol": _relative, "max_iters": INTERIOR_MAX_ITER},
    "cvxpy-ipopt": {"tol": _ipopt_tol, "acceptable_iter": 0, "max_iter": 3000,
                    "max_cpu_time": DEFAULT_TIME_LIMIT_S, "linear_solver": "mumps",
                    "hessian_constant": "yes", "jac_c_constant": "yes",
                    "jac_d_constant": "yes", "print_level": 0, "sb": "yes"},
    # --- solvers written here: tolerance on qpbench's own relative residual ---
    "pi": {"tol": _relative, "max_iters": 100, "cg_rtol": _inner_tolerance,
           "cg_max_iters": 2_000},
    "pi-v2": {"tol": _relative, "max_iters": 200, "cg_rtol": _inner_tolerance,
              "cg_max_iters": 2_000, "seed": 0},
    "pi-robust": {"tol": _relative, "rho": 1e-5, "rho_min": 1e-14, "rho_decrease": 0.01,
                  "stall_ratio": 0.5, "stall_steps": 3, "backup_steps": 0,
                  "active_set": True, "drift_steps": 3, "pi_budget": 100, "finish_budget": 3,
                  "finish_below": 1e-3, "ipm_iters": 80, "start_sweeps": 5,
                  "dense_limit": 300, "lemke_limit": 400, "compiled_limit": 50_000,
                  "compiled_work_limit": 2.5e6},
    "pgs": {"tol": _relative, "max_sweeps": 100_000, "check_every": 10},
    "lemke": {"tol": _relative, "max_contacts": 1_500, "max_pivots_per_contact": 50},
    "penalty": {"tol": _relative, "kappa": 1e9, "max_iters": 100, "dense_limit": 300},
    "apgd": {"tol": _relative, "max_iters": 50_000, "check_every": 10},
    # --- frictional solvers written here: tolerance on qpbench's Coulomb residual ---
    # nsgs' pivoting finish: once the best residual has not halved over stall_sweeps sweeps,
    # Lemke on a block of at most pivot_contacts contacts (a dense LCP of 3 per contact)
    "nsgs": {"tol": _relative, "max_sweeps": 100_000, "check_every": 10,
             "stall_sweeps": 1_000, "pivot_contacts": 300, "pivots_per_contact": 50},
    # staggered projections X/staggered: its outer loop and the box Gauss-Seidel written here
    # (the box QP of X = pi, pgs, lemke, ...); each inner solve reads X's own row at inner_accuracy;
    # anderson_depth: the rounds mixed into the next round's start (0: the plain loop; chosen
    # on rough-box-30 seeds, checked on others, docs/notes/pi-robust.md)
    "staggered": {"max_outer": 200, "inner_accuracy": _tenth, "box_max_sweeps": 100_000,
                  "box_check_every": 10, "anderson_depth": 5},
    # --- Siconos (qpbench/solvers/siconos_.py): tol is Siconos' own relative error
    # (||l - max(0, l - w)||_2 / ||q||_2 for an LCP); the dense solvers decline above
    # max_contacts, fc2d's Lemke and enumeration (an LCP of 3 unknowns per contact) above
    # max_frictional_contacts ---
    "siconos-lemke": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500,
                      "max_frictional_contacts": 500},
    "siconos-pivot": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-pivot-lumod": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-murty": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-pgs": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-psor": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-rpgs": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500},
    "siconos-cpg": {"tol": _relative, "max_iter": 100_000, "max_contacts": 1_500,
                    "max_frictional_contacts": 750},
    "siconos-newton-min": {"tol": _relative, "max_iter": 1_000, "max_contacts": 1_500},
    "siconos-newton-fb": {"tol": _relative, "max_iter": 1_000, "max_contacts": 1_500},
    "siconos-newton-min-fb": {"tol": _relative, "max_iter": 1_000, "max_contacts": 1_500},
    "siconos-nsqp": {"tol": _relative, "max_iter": 1_000, "max_contacts": 1_500},
    "siconos-enum": {"tol": _relative, "max_iter": 0, "max_contacts": 16,
                     "max_frictional_contacts": 5},
    "siconos-nsgs": {"tol": _relative, "max_iter": 100_000, "max_contacts": 750},
}


# --- native pairs: each backend through its own Python API, with its qpsolvers twin's row
# (the same options, mapped from eps alike), so that a pair and its twin differ only by the
# call path ---
NATIVE_TWINS: dict[str, str] = {
    "daqp-native": "daqp", "piqp-native": "piqp", "piqp-dense-native": "piqp",
    "osqp-native": "osqp", "clarabel-native": "clarabel", "proxqp-native": "proxqp",
    "proxqp-dense-native": "proxqp", "highs-native": "highs", "quadprog-native": "quadprog",
    "scs-native": "scs", "ecos-native": "ecos", "qpalm-native": "qpalm",
}
OPTIONS.update({native: dict(OPTIONS[twin]) for native, twin in NATIVE_TWINS.items()})


def options_for(solver: str, accuracy: float, scale: float = 1.0) -> dict[str, Any]:
    """The options of ``solver`` for accuracy level ``accuracy`` on a problem of ``scale``.

    Each entry of the solver's row is its constant, or its function evaluated at
    ``(accuracy, scale)``.

    Parameters
    ----------
    solver : str
        The solver's row in OPTIONS.
    accuracy : float
        qpbench's accuracy level eps, a bound on its relative residual.
    scale : float, optional
        The residual's scale ``max(||b||_inf, tiny)`` of the problem (a velocity); 1 by
        default, which makes absolute tolerances equal to relative ones.

    Returns
    -------
    dict[str, Any]
        The backend's option names and their values.

    Raises
    ------
    KeyError
        For a solver without a row (registration refuses those).
    """
    row = OPTIONS[solver]
    return {key: value(accuracy, scale) if callable(value) else value for key, value in row.items()}


@contextlib.contextmanager
def overridden(solver: str, **entries: OptionValue) -> Iterator[None]:
    """The table with ``entries`` replacing those of ``solver``'s row while the block runs.

    For a measurement that changes one setting for every pair alike; the replaced entries are
    restored after the block, also when it raises.

    Parameters
    ----------
    solver : str
        The solver's row in OPTIONS.
    **entries : OptionValue
        Option names of that row and their new values (constants or ``f(eps, scale)``).

    Yields
    ------
    None
        Control, once, while the row holds the new entries.

    Raises
    ------
    KeyError
        When the row has no option of one of the names.
    """
    row = OPTIONS[solver]
    unknown = set(entries) - set(row)
    if unknown:
        raise KeyError(f"{solver} has no option {', '.join(sorted(unknown))}")
    saved = {key: row[key] for key in entries}
    row.update(entries)
    try:
        yield
    finally:
        row.update(saved)


def describe(value: OptionValue) -> str:
    """How a table entry reads in the report: ``eps``, ``eps * scale`` or the constant.

    Parameters
    ----------
    value : OptionValue
        A constant, or a function ``f(eps, scale)`` whose docstring's first line says how
        it follows from eps (``f(eps, scale)`` when it has none).

    Returns
    -------
    str
        The entry's text for the report.
    """
    if value is _absolute:
        return "eps * scale"
    if value is _relative:
        return "eps"
    if callable(value):
        return (value.__doc__ or "f(eps, scale)").strip().splitlines()[0]
    return repr(value)


def table_rows() -> list[dict[str, str]]:
    """One row per (solver, option) with how its value follows from eps, for the report.

    Returns
    -------
    list[dict[str, str]]
        Rows with keys ``solver``, ``option`` and ``value`` (as :func:`describe` reads it),
        in the table's order.
    """
    return [
        {"solver": solver, "option": option, "value": describe(value)}
        for solver, row in OPTIONS.items()
        for option, value in row.items()
    ]
