"""SCISim 2D scenes: the model, the parser, solver names, builders and a writer."""

from qpbench.scenes.model import Bodies, ImpactOperator, Scene, SolverChoice
from qpbench.scenes.parser import load_scene, parse_scene

__all__ = ["Bodies", "ImpactOperator", "Scene", "SolverChoice", "load_scene", "parse_scene"]
