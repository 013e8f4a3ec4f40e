"""Every solver family, registered by a guarded import: a missing backend drops out and says why.

Add a backend: write ``qpbench/solvers/<family>_.py`` that calls
``registry.register`` for each solver/formulation, then name it in ``_FAMILIES``.
"""

from __future__ import annotations

import importlib

from qpbench.solvers.registry import register_unusable

# module -> (solver names it provides, formulations, backend) to report when it cannot import
_FAMILIES: dict[str, tuple[tuple[str, ...], tuple[str, ...], str]] = {
    "qpsolvers_": (("osqp", "clarabel", "proxqp", "piqp", "daqp", "highs", "scs", "ecos",
                    "cvxopt", "quadprog", "qpalm"), ("dual", "primal", "dual-factored"),
                   "qpsolvers"),
    "cvxpy_": (tuple(f"cvxpy-{name}" for name in ("clarabel", "osqp", "scs", "ecos", "piqp",
                                                  "proxqp", "cvxopt", "daqp", "highs",
                                                  "ipopt")),
               ("dual", "primal", "dual-factored"), "cvxpy"),
    "ipopt_": (("ipopt",), ("dual", "primal"), "cyipopt"),
    "policy_iteration": (("pi", "pi-v2"), ("lcp",), "qpbench"),
    "pi_robust": (("pi-robust",), ("lcp",), "qpbench"),
    "pgs": (("pgs",), ("lcp",), "qpbench"),
    "lemke": (("lemke",), ("lcp",), "qpbench"),
    "penalty": (("penalty",), ("lcp",), "qpbench"),
    "apgd": (("apgd",), ("lcp",), "qpbench"),
}

for _module, (_names, _formulations, _backend) in _FAMILIES.items():
    try:
        importlib.import_module(f"qpbench.solvers.{_module}")
    except ImportError as _error:
        for _name in _names:
            register_unusable(_name, _formulations, _backend, f"import failed: {_error}")
