"""Every solver family, one module each. A module whose backend package is missing registers
its solvers as unusable with the reason (a guarded import inside the module, where its
solver names are listed once), so a missing backend drops out and says why.

Add a backend: write ``qpbench/solvers/<family>_.py`` that calls ``registry.register`` for
each solver/formulation (and ``registry.register_unusable`` when its package is missing),
give each solver its row in ``qpbench/solvers/accuracy.py``, then name the module here. The
order of FAMILIES does not matter: pairs derived from others (the frictional twins) are made
by the registry once every family is imported (``registry.register_derivation``).
"""

from __future__ import annotations

import importlib

FAMILIES = ("qpsolvers_", "cvxpy_", "ipopt_", "policy_iteration", "pi_robust", "pgs", "lemke",
            "penalty", "apgd", "nsgs",
            # the frictional twins of the frictionless dual/lcp solvers (a derivation)
            "friction_ccp", "friction_staggered",
            # each QP backend through its own Python API (backend "native"), impact problems
            "native.daqp_", "native.piqp_", "native.osqp_", "native.clarabel_",
            "native.proxqp_", "native.highs_", "native.quadprog_", "native.scs_",
            "native.ecos_", "native.qpalm_",
            # Siconos, run by the system interpreter behind a pipe (backend "siconos")
            "siconos_")

for _module in FAMILIES:
    importlib.import_module(f"qpbench.solvers.{_module}")
