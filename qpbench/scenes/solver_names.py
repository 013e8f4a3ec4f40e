"""SCISim's names for impact solvers and the qpbench solvers that stand in for them.

A scene names a SCISim solver (``<solver name="ipopt"/>``); qpbench runs the
solver mapped here. When that solver is not registered or not usable here, the
simulator falls back to :data:`FALLBACK` and says so once.
"""

from __future__ import annotations

SCISIM_TO_QPBENCH: dict[str, str] = {
    "ipopt": "ipopt",
    "apgd": "apgd",
    "policy_iteration": "pi",
    "penalty": "penalty",
    "ql": "pi-robust",
    "solver3": "pi-robust",
    "lcp_solver_isaiah_debug": "pi-robust",
}

FALLBACK = "clarabel/dual"


def qpbench_name(scisim_name: str) -> str | None:
    """The qpbench solver for a SCISim solver name, or None when SCISim has no such name.

    Parameters
    ----------
    scisim_name : str
        The ``name`` of a scene's ``<solver>``.

    Returns
    -------
    str or None
        The qpbench solver name from :data:`SCISIM_TO_QPBENCH`, or None.
    """
    return SCISIM_TO_QPBENCH.get(scisim_name)
