"""The metrics now live in :mod:`qpbench.problem.metrics`, beside the problem they measure,
so the dependency runs one way (problem.impact <- problem.metrics <- problem.reference).

This module only keeps ``from qpbench import metrics`` working for the callers not moved yet
(qpbench/solvers/run.py, qpbench/solvers/lcp.py, qpbench/bench/speed.py); it goes once they
import ``qpbench.problem.metrics``.
"""

from qpbench.problem.metrics import (  # noqa: F401
    TINY,
    complementarity,
    energy_change_identity,
    energy_gain,
    energy_identity_gap,
    evaluate,
    infeasibility,
    is_finite,
    natural_map,
    residual,
    v_error,
)
