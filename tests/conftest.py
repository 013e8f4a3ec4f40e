"""Tests time nothing, but BLAS threads fighting over 2 shared cores make them slow: one thread."""

import os

from qpbench import SINGLE_THREAD_ENV

for variable, value in SINGLE_THREAD_ENV.items():
    os.environ.setdefault(variable, value)
