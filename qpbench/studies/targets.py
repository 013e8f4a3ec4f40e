"""The report's section on the targets of our own solver, pi-robust, on the hard families at
accuracy 1e-8: (1) it succeeds on every solve with ``v_error <= TARGET_V_ERROR``; (2) its
shifted geometric mean time (charged: failures cost the time limit) is at least
``TARGET_SPEEDUP`` times below that of the fastest external backend on the same problems.

The harness's report (``qpbench.bench.report.write_report``) knows no solver: the command
line hands it :data:`SECTIONS`, which it places in its summary.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from qpbench.bench import stats
from qpbench.bench.defaults import TARGET_SPEEDUP
from qpbench.bench.formatting import number, percent
from qpbench.bench.report import SummarySection

HARD_FAMILIES = ("k3", "k4", "k4-middle", "cradle", "grid", "box", "mass-ratio",
                 "near-duplicate", "dump")
ROBUST_SOLVER = "pi-robust"
TARGET_LEVEL = 1e-8
TARGET_V_ERROR = 1e-7
TITLE = "pi-robust: its targets (hard families, accuracy 1e-8)"


def robust_targets(frame: pd.DataFrame, shift: float) -> str:
    """The two targets of our own solver on the hard families at 1e-8, met or not, with figures.

    Read from the cold frictionless rows ``frame`` and the report's SGM ``shift``: (1) the
    success rate and the largest ``v_error`` of pi-robust's solves, per family too; (2) its
    shifted geometric mean time, failures charged the time limit, against that of the fastest
    external backend on the same problems.

    Parameters
    ----------
    frame : pd.DataFrame
        The result rows (cold starts, frictionless problems).
    shift : float
        The shift of the shifted geometric mean, in seconds.

    Returns
    -------
    str
        Markdown: a numbered item per target, or one line when pi-robust has no solves there.
    """
    hard = frame[frame["family"].astype(str).isin(HARD_FAMILIES)
                 & np.isclose(frame["accuracy"].astype(float), TARGET_LEVEL)]
    robust = hard[hard["solver"].astype(str) == ROBUST_SOLVER]
    if robust.empty:
        return (f"_`{ROBUST_SOLVER}` has no solves at {TARGET_LEVEL:g} on the hard families "
                "in these results._\n")
    lines = []
    success_rate = float(robust["success"].fillna(False).astype(bool).mean())
    max_v_error = float(robust["v_error"].max()) if robust["v_error"].notna().any() else math.nan
    met = success_rate == 1.0 and not max_v_error > TARGET_V_ERROR
    per_family = (robust.groupby("family")["success"]
                  .apply(lambda s: percent(s.fillna(False).astype(bool).mean())))
    lines.append(f"1. `{ROBUST_SOLVER}` succeeds on {percent(success_rate)} of "
                 f"{len(robust)} hard-family solves at {TARGET_LEVEL:g} (target 100%), max "
                 f"v_error {number(max_v_error)} (target <= {TARGET_V_ERROR:g}): "
                 f"**{'met' if met else 'not met'}**. Per family: "
                 + ", ".join(f"{family} {rate}" for family, rate in per_family.items()) + ".")
    hard = hard.assign(key=stats.solver_keys(hard), charged=stats.charged_times(hard))
    problems = set(robust["problem"])
    sgm = {key: stats.shifted_geometric_mean(group["charged"], shift)
           for key, group in hard[hard["problem"].isin(problems)].groupby("key")}
    robust_key = min((k for k in sgm if k.split("/")[0] == ROBUST_SOLVER), key=sgm.get)
    external = hard[hard["backend"].astype(str) != stats.OWN_BACKEND]
    external_keys = [k for k in sgm if k in set(external["key"])]
    if not external_keys:
        lines.append("2. No external backend has solves on the same problems: no ratio.")
    else:
        fastest = min(external_keys, key=sgm.get)
        ratio = sgm[fastest] / sgm[robust_key]
        lines.append(f"2. Fastest external backend `{fastest}`: SGM {number(sgm[fastest])} s; "
                     f"`{robust_key}`: {number(sgm[robust_key])} s; ratio {ratio:.2f} "
                     f"(target >= {TARGET_SPEEDUP:g}): "
                     f"**{'met' if ratio >= TARGET_SPEEDUP else 'not met'}**.")
    return "\n".join(lines) + "\n"


# the sections of the report's summary that the command line hands to write_report
SECTIONS: tuple[SummarySection, ...] = ((TITLE, robust_targets),)
