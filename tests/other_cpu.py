"""Run a test module as a script in a process that rounds as another CPU would (no tests here).

OpenBLAS picks its kernels for the CPU at run time, and a dot product's kernel sets the order
of its sums; NumPy dispatches its loops to the vector instructions the CPU has. A process with
``OPENBLAS_CORETYPE`` set to an old CPU's kernels and ``NPY_DISABLE_CPU_FEATURES`` cutting
NumPy to its baseline rounds as such a CPU does wherever the order of a sum is left to them.
"""

from __future__ import annotations

import os
import subprocess
import sys


def dispatched_features() -> str:
    """The vector instruction sets NumPy dispatches to on this CPU, space-separated."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    return " ".join(name for name in __cpu_dispatch__ if __cpu_features__.get(name))


def printed_elsewhere(script: str, *arguments: str, core_type: str = "Prescott",
                      baseline_numpy: bool = True, timeout: float = 300) -> list[str]:
    """The lines ``python script arguments`` prints with OpenBLAS's kernels of ``core_type``
    and, with ``baseline_numpy``, NumPy's vector dispatch turned off.

    Parameters
    ----------
    script : str
        A test module whose ``__main__`` prints the figures compared.
    *arguments : str
        Its command-line arguments.
    core_type : str, optional
        An ``OPENBLAS_CORETYPE`` (an x86 core whose kernels run on any later one).
    baseline_numpy : bool, optional
        Whether to disable NumPy's dispatch to the vector instructions this CPU has.
    timeout : float, optional
        Seconds the script may take.

    Returns
    -------
    list of str
        Its standard output's lines.
    """
    changed = {"OPENBLAS_CORETYPE": core_type}
    if baseline_numpy:
        changed["NPY_DISABLE_CPU_FEATURES"] = dispatched_features()
    run = subprocess.run([sys.executable, script, *arguments], env={**os.environ, **changed},
                         capture_output=True, text=True, timeout=timeout)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout.splitlines()
