"""Silencing C code that prints on file descriptor 1, shared by the backends that need it."""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator

_SILENCE_LOCK = threading.Lock()
_silence_depth = 0
_saved_stdout: int | None = None


@contextlib.contextmanager
def c_stdout_silenced() -> Iterator[None]:
    """Sends file descriptor 1 to /dev/null for the block.

    OSQP's and IPOPT's C code print ("Polishing not needed ...") even when not verbose,
    which would corrupt ``--json``. Nested and concurrent blocks share one redirection; the
    last to leave restores fd 1.

    Yields
    ------
    None
        Control, once, while fd 1 is silenced.
    """
    global _silence_depth, _saved_stdout
    with _SILENCE_LOCK:
        if _silence_depth == 0:
            sys.stdout.flush()
            _saved_stdout = os.dup(1)
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.close(devnull)
        _silence_depth += 1
    try:
        yield
    finally:
        with _SILENCE_LOCK:
            _silence_depth -= 1
            if _silence_depth == 0 and _saved_stdout is not None:
                sys.stdout.flush()
                os.dup2(_saved_stdout, 1)
                os.close(_saved_stdout)
                _saved_stdout = None


_highs_banner_printed = False


def highs_banner_silenced() -> None:
    """Creates a first ``highspy.Highs`` object with file descriptor 1 silenced.

    The first one of a process prints HiGHS's banner on standard output, whatever its
    options, which would corrupt ``--json``. Every pair that reaches HiGHS calls it as its
    ``SolverSpec.prepare``, outside the clock; later calls return at once, and without
    highspy it does nothing.
    """
    global _highs_banner_printed
    if _highs_banner_printed:
        return
    try:
        import highspy  # an optional backend
    except ImportError:
        return
    with c_stdout_silenced():
        highspy.Highs()
    _highs_banner_printed = True
