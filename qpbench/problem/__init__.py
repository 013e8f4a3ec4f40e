"""Impact problems: the data (G, M^-1, v-, c, nrel), file format, generators, references."""

from qpbench.problem.impact import ImpactProblem, Reference

__all__ = ["ImpactProblem", "Reference"]
