"""Tests time nothing, but BLAS threads fighting over 2 shared cores make them slow: one thread.

A suite started in the background of a non-interactive shell (``make test &``, ``nohup``)
inherits SIGINT ignored, and a process that starts with SIGINT ignored passes that on to every
child it starts, whose Python then never raises KeyboardInterrupt: the tests that press Ctrl-C
on a child would see it go on. SIGINT gets Python's own handler here, so that children start
with the default disposition whatever started the suite.
"""

import os
import signal
from collections.abc import Callable

import pytest

from qpbench import SINGLE_THREAD_ENV

for variable, value in SINGLE_THREAD_ENV.items():
    os.environ.setdefault(variable, value)

if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def pi_robust_methods(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The order in which pi-robust's Python path calls policy iteration and the interior
    point, recorded from the test's start."""
    from qpbench.solvers import pi_robust

    called: list[str] = []

    def recorded(method: str, inner: Callable) -> Callable:
        def call(*args: object, **kwargs: object) -> object:
            called.append(method)
            return inner(*args, **kwargs)
        return call

    for name, method in (("_prox_policy_iteration", "policy iteration"),
                         ("interior_point", "interior point")):
        monkeypatch.setattr(pi_robust, name, recorded(method, getattr(pi_robust, name)))
    return called
