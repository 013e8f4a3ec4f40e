"""Imported by the runner's fork server before it forks any worker: every backend is imported
and every solver prepared once there, so each forked worker starts with both done."""

from qpbench.bench.worker import prepare_solvers

prepare_solvers()
