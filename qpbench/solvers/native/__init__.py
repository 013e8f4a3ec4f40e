"""Backends called through their own Python APIs, one module per backend (``<solver>-native``
pairs, backend ``native``): the same problems and the same accuracy options as their
qpsolvers twins, so that a pair and its twin differ only by the call path."""
