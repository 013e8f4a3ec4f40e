"""qpbench: which formulation and solver gets the impulses of simultaneous collisions right, how fast."""

__version__ = "0.1.0"
