"""The call of the kernel's narrow entry from Python, past numba's dispatcher where it may be.

A call of a compiled function through numba's dispatcher first types every argument to pick
the machine code compiled for those types (numba's ``typeof``: an array's dtype, dimensions,
layout and whether it is writeable), and compiles new machine code for types it has not met.
On a problem of a few contacts, called after other solvers' work has taken over the caches,
that typing is a large part of the call: its code has to come back into the caches first
(docs/notes/pi-robust.md, section "The call boundary").

:func:`call_pi_robust_into` therefore checks in Python that Q's arrays and b are what the
kernel is compiled for (``pi_robust_into``'s overload for C-contiguous, one-dimensional arrays:
int32 indices, float64 values, the types ``entry.warm_up`` compiles; the two arrays its caller
makes, the one that receives l and the packed options, are of those types by construction)
and then calls that overload's machine code directly (numba's
``Dispatcher.overloads[signature].entry_point``, the function the dispatcher itself calls).
Read-only arrays pass: numba would compile other machine code for them, which reads them
alike. Any other argument goes through the dispatcher, which types it as always; so does every
call before the overload exists. The check decides which way the call goes, never what it
computes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from qpbench.solvers.pi_robust_kernel import entry

INDEX = np.dtype(np.int32)
VALUE = np.dtype(np.float64)
# the strides of a one-dimensional contiguous array of each (a tuple of one entry per dimension)
INDEX_STRIDES = (INDEX.itemsize,)
VALUE_STRIDES = (VALUE.itemsize,)
ARRAY = np.ndarray

# pi_robust_into's compiled overload for arrays of INDEX and VALUE: None until looked up,
# False when there is none (then the dispatcher takes every call)
_entry_point: Callable[..., tuple] | None | bool = None


def _compiled_entry_point() -> Callable[..., tuple] | bool:
    """The machine code of ``entry.pi_robust_into`` for arrays of INDEX and VALUE, once
    ``entry.warm_up`` has compiled or loaded it; False when the dispatcher holds none."""
    from numba import types

    index, value = types.Array(types.int32, 1, "C"), types.Array(types.float64, 1, "C")
    signature = (index, index, value, value, value, value)
    compiled = getattr(entry.pi_robust_into, "overloads", {}).get(signature)
    return False if compiled is None else compiled.entry_point


def warm_up() -> None:
    """Compile the kernel or load it from numba's cache (``entry.warm_up``), then look up the
    machine code :func:`call_pi_robust_into` calls directly; once per process, outside any
    clock."""
    global _entry_point
    if _entry_point is None:
        entry.warm_up()
        _entry_point = _compiled_entry_point()


def call_pi_robust_into(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                        b: np.ndarray, out: np.ndarray, call_options: np.ndarray) -> tuple:
    """``entry.pi_robust_into(indptr, indices, data, b, out, call_options)``, past numba's
    dispatcher when Q's arrays and b are of the compiled types (module docstring).

    Parameters
    ----------
    indptr, indices, data : np.ndarray
        Q's CSC arrays.
    b : np.ndarray
        The LCP's constant term.
    out : np.ndarray
        A new array of n floats made by the caller (``np.empty``): in, the start, unless
        ``call_options`` says to start from zero; out, l.
    call_options : np.ndarray
        The packed options, an array made by ``entry.call_options_of``.

    Returns
    -------
    tuple
        ``entry.pi_robust_into``'s converged, path, solves, interior iterations,
        factorizations and certified.

    Raises
    ------
    np.linalg.LinAlgError
        When a factor fails in the kernel.
    """
    if _entry_point is None:
        warm_up()
    # Q's arrays and b: NumPy arrays (not subclasses) of the compiled dtype whose strides are
    # those of one dimension, contiguous. Written out, not in a helper, and ``out`` and
    # ``call_options`` (the caller's own, see above) not checked: this runs inside the
    # stopwatch on every call (module docstring)
    if (_entry_point
            and type(indptr) is ARRAY and indptr.dtype is INDEX and indptr.strides == INDEX_STRIDES
            and type(indices) is ARRAY and indices.dtype is INDEX
            and indices.strides == INDEX_STRIDES
            and type(data) is ARRAY and data.dtype is VALUE and data.strides == VALUE_STRIDES
            and type(b) is ARRAY and b.dtype is VALUE and b.strides == VALUE_STRIDES):
        return _entry_point(indptr, indices, data, b, out, call_options)
    return entry.pi_robust_into(indptr, indices, data, b, out, call_options)
