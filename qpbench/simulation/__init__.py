"""Simulation of SCISim scenes: broad phase, contacts, impact operators, integrators, stepper."""
