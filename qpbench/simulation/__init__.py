"""Simulation of SCISim 2D scenes, one concept per module.

* ``broad_phase``: candidate pairs from a uniform grid (linear in the number of balls);
* ``contacts``: ball-ball (continuous over the step), ball-plane and ball-drum contacts, and G;
* ``integrators``: symplectic Euler and velocity Verlet, with gravity only if declared;
* ``operators``: the impact operators lcp, gr, grr and gauss_seidel, inner solves judged;
* ``stepper``: SCISim's geometric splitting; every impact event an ImpactProblem;
* ``checks``: energy and momentum; ``scaling``: cost per ball per step; ``render``: pictures.
"""
