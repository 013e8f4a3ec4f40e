"""Memory guards: an address-space cap, size checks before large allocations, and one line
instead of a MemoryError.

* :func:`limit_memory` caps the process's address space with ``RLIMIT_AS``: an allocation
  beyond it raises MemoryError (numpy's and numba's allocators too) instead of growing until
  the kernel's OOM killer ends some process of the machine. ``run``'s workers and the
  commands that build things (``simulate``, ``render``, ``generate``, ``build-set``) use it;
  :func:`default_limit_mb` is the commands' default cap.
* :func:`require` compares the bytes an allocation needs, estimated from sizes known before
  it is made (bodies, contacts, a family's balls), with :func:`budget_bytes`, what the cap and
  the machine still allow, and refuses in one line naming both. The estimates are lower
  bounds of what the allocation takes, so a refused request could not have succeeded; the
  cap catches what they do not foresee.
* :func:`out_of_memory_as_error` turns a MemoryError under the cap into the same kind of
  line: what was being built, the cap, and how to raise it.
"""

from __future__ import annotations

import math
import resource
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import psutil

from qpbench.errors import QpbenchError

MIB = 1024 * 1024
# the default cap of a command: this fraction of the memory available when it starts
DEFAULT_FRACTION = 0.8
LIMIT_OPTION = "--memory-limit"
# :func:`require` lets smaller requests through unchecked (the cap still bounds them), so that
# a check on every simulation step costs nothing measurable
UNCHECKED_BYTES = 64 * MIB


class OutOfMemory(QpbenchError):
    """A request refused by a size check, or an allocation that failed under the cap."""


# the cap this process applied with :func:`apply_limit` (MiB, 0: none), named in messages
_applied_limit_mb = 0


def virtual_memory_mb() -> float:
    """This process's address space (VmSize) in MiB, NaN where /proc is missing.

    Returns
    -------
    float
        VmSize of ``/proc/self/status`` in MiB, or NaN when it cannot be read.
    """
    try:
        with open("/proc/self/status", encoding="utf-8") as stream:
            for line in stream:
                if line.startswith("VmSize:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return math.nan


def limit_memory(limit_mb: int) -> int:
    """Caps the address space at ``limit_mb`` MiB with ``RLIMIT_AS``.

    The cap is raised to VmSize + limit_mb if the loaded process already exceeds it, and never
    exceeds the hard limit.

    Parameters
    ----------
    limit_mb : int
        The cap in MiB; 0 or less applies none.

    Returns
    -------
    int
        The cap applied in MiB (0: no cap).
    """
    if limit_mb <= 0:
        return 0
    current = virtual_memory_mb()
    applied = limit_mb if not current >= limit_mb else int(current) + limit_mb
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = applied * 1024 * 1024
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    return applied


def available_mb() -> int:
    """The memory the machine has available for new allocations, in MiB.

    This is psutil's ``available``: free memory plus what the kernel can reclaim without
    swapping.

    Returns
    -------
    int
        The available memory in whole MiB.
    """
    return int(psutil.virtual_memory().available // MIB)


def default_limit_mb() -> int:
    """A command's default cap in MiB: :data:`DEFAULT_FRACTION` of :func:`available_mb`.

    Where the process already exceeds that, :func:`limit_memory` raises it to the process's
    present address space plus that.

    Returns
    -------
    int
        The cap in MiB, at least 1.
    """
    return max(1, int(DEFAULT_FRACTION * available_mb()))


def apply_limit(limit_mb: int) -> int:
    """:func:`limit_memory` for a command, remembered for messages.

    The cap is remembered so that the messages of :func:`require` and
    :func:`out_of_memory_as_error` name it.

    Parameters
    ----------
    limit_mb : int
        The cap in MiB (``--memory-limit``); 0: no cap.

    Returns
    -------
    int
        The cap applied in MiB (0: no cap).
    """
    global _applied_limit_mb
    _applied_limit_mb = limit_memory(limit_mb)
    return _applied_limit_mb


def budget_bytes() -> int:
    """Bytes this process can still allocate.

    The machine's available memory, or the room left under the ``RLIMIT_AS`` cap (the cap
    less the present address space) when that is smaller.

    Returns
    -------
    int
        The budget in bytes, never negative.
    """
    budget = int(psutil.virtual_memory().available)
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    current = virtual_memory_mb()
    if soft != resource.RLIM_INFINITY and math.isfinite(current):
        budget = min(budget, int(soft - current * MIB))
    return max(budget, 0)


def describe_bytes(count: float) -> str:
    """``count`` bytes as a short figure: ``512 MB``, ``37.3 GB`` (binary units).

    Parameters
    ----------
    count : float
        A number of bytes; a negative one shows as ``0 KB``.

    Returns
    -------
    str
        Three significant digits and the largest unit (KB, MB, GB, TB) not above ``count``.
    """
    for unit, scale in (("TB", 1024**4), ("GB", 1024**3), ("MB", MIB)):
        if count >= scale:
            return f"{count / scale:.3g} {unit}".replace("e+", "e")
    return f"{max(count, 0) / 1024:.3g} KB"


def _limit_hint() -> str:
    """How the cap was set and how to change it, for a message."""
    if _applied_limit_mb:
        return (f"; memory limit {_applied_limit_mb} MB ({LIMIT_OPTION} MB raises it, "
                f"{LIMIT_OPTION} 0 removes it)")
    return ""


def require(need_bytes: float, what: str) -> None:
    """Refuses a request that needs more memory than :func:`budget_bytes`.

    OutOfMemory naming ``what`` (the size asked, e.g. ``scene.xml: 100000 balls``), the bytes
    it needs and the memory available, when ``need_bytes`` exceeds :func:`budget_bytes`;
    nothing otherwise (at once below :data:`UNCHECKED_BYTES`).

    Parameters
    ----------
    need_bytes : float
        A lower bound of the bytes the allocation takes.
    what : str
        What is asked for, which starts the message.

    Raises
    ------
    OutOfMemory
        When ``need_bytes`` exceeds the budget.
    """
    if need_bytes < UNCHECKED_BYTES:
        return
    budget = budget_bytes()
    if need_bytes > budget:
        raise OutOfMemory(f"{what}: needs at least {describe_bytes(need_bytes)} of memory, "
                          f"{describe_bytes(budget)} available{_limit_hint()}")


def product_entries(per_row: np.ndarray) -> int:
    """The entries scipy reserves for the sparse product ``A^T A``.

    When row k of A holds ``per_row[k]`` non-zeros that is ``sum_k per_row[k]^2``, the bound
    it allocates before the product (duplicates are merged only afterwards).

    Parameters
    ----------
    per_row : np.ndarray
        Non-zeros of each row of A, integers of shape (rows,).

    Returns
    -------
    int
        The number of entries reserved.
    """
    counts = np.asarray(per_row, dtype=np.int64)
    return int(np.dot(counts, counts))


def product_bytes(per_row: np.ndarray) -> int:
    """The bytes of the arrays scipy allocates for ``A^T A``.

    These are :func:`product_entries` values of 8 bytes and indices of 4, or of 8 beyond 2^31
    entries.

    Parameters
    ----------
    per_row : np.ndarray
        Non-zeros of each row of A, integers of shape (rows,).

    Returns
    -------
    int
        The bytes of the product's values and indices.
    """
    entries = product_entries(per_row)
    return entries * (16 if entries >= 2**31 else 12)


def out_of_memory(what: str, detail: str = "") -> OutOfMemory:
    """The one-line error of an allocation that failed.

    ``out of memory while WHAT (DETAIL)`` and the cap with how to change it.

    Parameters
    ----------
    what : str
        What was being built, e.g. ``building the Delassus matrix``.
    detail : str, optional
        The MemoryError's text (cut to 160 characters); empty by default, then left out.

    Returns
    -------
    OutOfMemory
        The error, to be raised by the caller.
    """
    detail = detail.strip().rstrip(".")
    detail = f" ({detail[:160]})" if detail else ""
    return OutOfMemory(f"out of memory while {what}{detail}{_limit_hint()}")


@contextmanager
def out_of_memory_as_error(what: str) -> Iterator[None]:
    """Turns a MemoryError raised in the block into :func:`out_of_memory`.

    The MemoryError is an allocation refused under the cap or by the machine; the error keeps
    the allocation that failed where numpy names it.

    Parameters
    ----------
    what : str
        What the block builds, named in the message.

    Yields
    ------
    None
        Control to the block.

    Raises
    ------
    OutOfMemory
        When a MemoryError is raised in the block.
    """
    try:
        yield
    except MemoryError as error:
        raise out_of_memory(what, str(error)) from None
