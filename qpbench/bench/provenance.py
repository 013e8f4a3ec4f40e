"""Where a row was measured: qpbench's version, the package lock, Python, NumPy, the machine.

Every row carries these columns; rows of a worker that died (crash, timeout) get them from
the runner, so no row is without its provenance.
"""

from __future__ import annotations

import platform
import socket
from functools import cache
from typing import Any

import numpy as np

from qpbench import __version__
from qpbench.bench.lock import lock_label


def cpu_model() -> str:
    """Read the CPU's model name.

    Returns
    -------
    str
        The model name from /proc/cpuinfo, else platform.processor() (or the machine type).
    """
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as stream:
            for line in stream:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance() -> dict[str, Any]:
    """Give the machine and version columns common to every row this process writes.

    Returns
    -------
    dict of str to Any
        ``qpbench_version``, ``lock_hash``, ``python_version``, ``numpy_version``,
        ``platform``, ``cpu_model`` and ``hostname`` (read once, returned as a fresh dict).
    """
    return dict(_provenance())


@cache
def _provenance() -> dict[str, Any]:
    return {
        "qpbench_version": __version__,
        "lock_hash": lock_label(),
        "python_version": platform.python_version(),
        "numpy_version": np.__version__,
        "platform": platform.platform(),
        "cpu_model": cpu_model(),
        "hostname": socket.gethostname(),
    }
