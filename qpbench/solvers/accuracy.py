"""THE table that maps qpbench's accuracy levels to each solver's own options.

qpbench's accuracy level eps is a bound on its own residual,
``||min(D l, Q l + b)||_inf / scale`` with ``scale = max(||b||_inf, tiny)``.
Backends use absolute tolerances on their own residuals, so each row maps
``(eps, scale)`` to that backend's options. A value is either a constant or a
function ``f(eps, scale)``. This module is the only place solver options are set.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

LEVELS: tuple[float, ...] = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
DEFAULT_TIME_LIMIT_S = 60.0

OptionValue = Any | Callable[[float, float], Any]


def _absolute(eps: float, scale: float) -> float:
    """eps * scale: our relative level as an absolute velocity tolerance."""
    return eps * scale


def _relative(eps: float, scale: float) -> float:
    return eps


OPTIONS: dict[str, dict[str, OptionValue]] = {
    # --- through qpsolvers (and cvxpy, same option names) ---------------------
    "osqp": {"eps_abs": _absolute, "eps_rel": _relative, "polishing": True,
             "max_iter": 200_000, "time_limit": DEFAULT_TIME_LIMIT_S},
    "clarabel": {"tol_gap_abs": _absolute, "tol_gap_rel": _relative, "tol_feas": _relative,
                 "tol_ktratio": lambda eps, scale: min(1e-6, eps), "max_iter": 500,
                 "time_limit": DEFAULT_TIME_LIMIT_S},
    # --- solvers written here: tolerance on qpbench's own relative residual ---
    "pi": {"tol": _relative, "max_iters": 100},
}


def options_for(solver: str, accuracy: float, scale: float = 1.0) -> dict[str, Any]:
    """The options of ``solver`` for accuracy level ``accuracy`` on a problem of ``scale``."""
    row = OPTIONS.get(solver, {})
    return {key: value(accuracy, scale) if callable(value) else value for key, value in row.items()}


def describe(value: OptionValue) -> str:
    """How a table entry reads in the report: ``eps``, ``eps * scale`` or the constant."""
    if value is _absolute:
        return "eps * scale"
    if value is _relative:
        return "eps"
    if callable(value):
        return (value.__doc__ or "f(eps, scale)").strip().splitlines()[0]
    return repr(value)


def table_rows() -> list[dict[str, str]]:
    """One row per (solver, option) with how its value follows from eps, for the report."""
    return [
        {"solver": solver, "option": option, "value": describe(value)}
        for solver, row in OPTIONS.items()
        for option, value in row.items()
    ]
