"""qpbench: which formulation and solver gets simultaneous-impact impulses right, how fast."""

__version__ = "0.1.0"

# numerical libraries limited to one thread: solvers are timed single-threaded
SINGLE_THREAD_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
# modules named here (``module,module``) are imported by the solver registry and register more
# solvers (e.g. test-only ones); worker processes inherit the variable, so see them too
EXTRA_SOLVERS_ENV = "QPBENCH_EXTRA_SOLVERS"
