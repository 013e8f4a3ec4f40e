"""Statistics of a results table: shifted geometric means, performance profiles, cost of accuracy.

Times are ``time_s`` (the solver call alone, minimum over repeats). A solve that
did not succeed is *charged* the time limit of its run (``time_limit_s``), so a
solver cannot look fast by failing quickly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from qpbench.bench.settings import CRASHED, OUT_OF_MEMORY, TIMEOUT

SHIFT_FACTOR = 10.0
OWN_BACKEND = "qpbench"  # the backend name of the solvers written here
PROFILE_TAUS = np.logspace(0, 4, 200)


def solver_keys(frame: pd.DataFrame) -> pd.Series:
    """``solver/formulation`` for every row."""
    return frame["solver"].astype(str) + "/" + frame["formulation"].astype(str)


def charged_times(frame: pd.DataFrame) -> pd.Series:
    """time_s where the solve succeeded, else the run's time limit (or the largest time seen)."""
    fallback = float(np.nanmax(frame["time_s"].to_numpy(dtype=float), initial=1.0))
    limit = frame["time_limit_s"].astype(float).fillna(fallback) if "time_limit_s" in frame \
        else pd.Series(fallback, index=frame.index)
    success = frame["success"].fillna(False).astype(bool)
    times = frame["time_s"].astype(float)
    return times.where(success & times.notna(), limit)


def time_scale_shift(frame: pd.DataFrame, factor: float = SHIFT_FACTOR) -> float:
    """The shift of the geometric mean on the problems' own time scale:
    ``factor * median over (problem, accuracy) of the fastest successful time_s``.

    Falls back to ``factor`` times the median of all finite times, then to 1 s."""
    solved = frame[frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()]
    if len(solved):
        fastest = solved.groupby(["problem", "accuracy"])["time_s"].min()
        value = float(fastest.median())
        if value > 0:
            return factor * value
    finite = frame["time_s"].dropna()
    finite = finite[finite > 0]
    return factor * float(finite.median()) if len(finite) else 1.0


def shifted_geometric_mean(times: Sequence[float] | np.ndarray, shift: float) -> float:
    """SGM = exp(mean(log(t_i + shift))) - shift; NaN for no times."""
    values = np.asarray(times, dtype=float)
    if values.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(values + shift))) - shift)


def level_summary(frame: pd.DataFrame, shift: float) -> pd.DataFrame:
    """Per (accuracy, solver/formulation): solves, success rate, SGM of charged time, median
    formulation time (building its matrices, outside time_s), median and max residual, max v_error,
    counts of crashed / timeout / out-of-memory rows."""
    frame = frame.assign(key=solver_keys(frame), charged=charged_times(frame))
    rows = []
    for (accuracy, key), group in frame.groupby(["accuracy", "key"], sort=True):
        status = group["status"].astype(str)
        rows.append({
            "accuracy": accuracy,
            "solver": key,
            "ours": own_mark(group),
            "solves": len(group),
            "success_rate": float(group["success"].fillna(False).astype(bool).mean()),
            "sgm_time_s": shifted_geometric_mean(group["charged"], shift),
            "median_formulation_s": float(group["formulation_time_s"].median())
            if "formulation_time_s" in group else math.nan,
            "median_residual": float(group["residual"].median()),
            "max_residual": float(group["residual"].max()),
            "max_v_error": float(group["v_error"].max()),
            "crashed": int((status == CRASHED).sum()),
            "timeout": int((status == TIMEOUT).sum()),
            "out_of_memory": int((status == OUT_OF_MEMORY).sum()),
        })
    return pd.DataFrame(rows)


def performance_ratios(frame: pd.DataFrame) -> pd.DataFrame:
    """problem x solver/formulation table of r = t / min over solvers of t (inf on failure).

    Problems no solver solved are dropped (no ratio exists)."""
    frame = frame.assign(key=solver_keys(frame))
    success = frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()
    times = frame["time_s"].astype(float).where(success, np.inf)
    table = frame.assign(t=times).pivot_table(index="problem", columns="key", values="t",
                                              aggfunc="min")
    table = table.fillna(np.inf)
    best = table.min(axis=1)
    table = table[np.isfinite(best)]
    return table.div(table.min(axis=1), axis=0)


def performance_profile(frame: pd.DataFrame, taus: np.ndarray = PROFILE_TAUS) -> pd.DataFrame:
    """Dolan-More profile: rho_s(tau) = share of problems with r_{p,s} <= tau (index tau)."""
    ratios = performance_ratios(frame)
    if ratios.empty:
        return pd.DataFrame(index=pd.Index(taus, name="tau"))
    values = ratios.to_numpy()
    profile = {key: (values[:, j][None, :] <= taus[:, None]).mean(axis=1)
               for j, key in enumerate(ratios.columns)}
    return pd.DataFrame(profile, index=pd.Index(taus, name="tau"))


def cost_of_accuracy(frame: pd.DataFrame, shift: float) -> pd.DataFrame:
    """Per solver/formulation (rows) the SGM charged time at each level, and the ratio from each
    level to the next tighter one (columns ``a -> b``)."""
    summary = level_summary(frame, shift)
    if summary.empty:
        return summary
    sgm = summary.pivot(index="solver", columns="accuracy", values="sgm_time_s")
    levels = sorted(sgm.columns, reverse=True)  # loosest first
    table = pd.DataFrame(index=sgm.index)
    for level in levels:
        table[f"SGM @ {level:.0e}"] = sgm[level]
    for looser, tighter in zip(levels, levels[1:], strict=False):
        table[f"{looser:.0e} -> {tighter:.0e}"] = sgm[tighter] / sgm[looser]
    return table


def paired_cost_of_accuracy(frame: pd.DataFrame) -> pd.DataFrame:
    """Per solver/formulation (rows), for each level and the next tighter one (columns
    ``a -> b``): the median over problems solved at BOTH levels of ``t_b / t_a``, so failures
    at either level do not enter (NaN: no problem solved at both)."""
    frame = frame.assign(key=solver_keys(frame))
    solved = frame[frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()]
    times = solved.pivot_table(index=["key", "problem"], columns="accuracy", values="time_s",
                               aggfunc="min")
    levels = sorted(frame["accuracy"].unique(), reverse=True)  # loosest first
    table = pd.DataFrame(index=sorted(frame["key"].unique()))
    for looser, tighter in zip(levels, levels[1:], strict=False):
        column = f"{looser:.0e} -> {tighter:.0e}"
        if looser in times and tighter in times:
            ratio = (times[tighter] / times[looser]).dropna()
            table[column] = ratio.groupby(level="key").median()
        else:
            table[column] = math.nan
    table.index.name = "solver"
    return table


def accuracy_within_budget(frame: pd.DataFrame, budget_s: float, share: float = 0.9
                           ) -> pd.DataFrame:
    """Per solver/formulation, what it reaches within ``budget_s`` seconds per solve:

    * ``tightest_level``: the smallest accuracy level at which it succeeded within the budget
      on at least ``share`` of the problems (NaN: none);
    * ``median_best_v_error``: over problems, the median of the smallest v_error among its
      successful solves within the budget (inf for a problem with none)."""
    frame = frame.assign(key=solver_keys(frame))
    in_budget = (frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()
                 & (frame["time_s"] <= budget_s))
    frame = frame.assign(in_budget=in_budget)
    problems = frame.groupby("key")["problem"].nunique()
    rows = []
    for key, group in frame.groupby("key"):
        rates = group.groupby("accuracy")["in_budget"].mean()
        reached = [level for level, rate in rates.items() if rate >= share]
        best = group[group["in_budget"]].groupby("problem")["v_error"].min()
        best = best.reindex(group["problem"].unique()).fillna(np.inf)
        rows.append({
            "solver": key,
            "problems": int(problems[key]),
            "tightest_level": min(reached) if reached else math.nan,
            "median_best_v_error": float(best.median()) if len(best) else math.nan,
        })
    return pd.DataFrame(rows)


def own_mark(group: pd.DataFrame) -> str:
    """``ours`` for the rows of a solver written here (backend ``qpbench``): it stops on
    qpbench's own residual, so its claim agrees with the verdict by construction."""
    return "ours" if (group["backend"].astype(str) == OWN_BACKEND).any() else ""


def honesty(frame: pd.DataFrame) -> pd.DataFrame:
    """Per solver/formulation, over solves that returned (no crash, timeout or out-of-memory):
    the share where its own claim of success agreed with qpbench's verdict, and the two ways
    it can disagree (claimed success but failed; claimed failure but solved). Our own solvers
    are marked (``ours``): their honesty is 100% by construction, not an achievement."""
    returned = frame[frame["status"].isin(["solved", "inaccurate", "failed"])]
    returned = returned.assign(key=solver_keys(returned))
    rows = []
    for key, group in returned.groupby("key"):
        claimed = group["claimed_success"].fillna(False).astype(bool)
        success = group["success"].fillna(False).astype(bool)
        rows.append({
            "solver": key,
            "ours": own_mark(group),
            "solves": len(group),
            "honesty_rate": float((claimed == success).mean()),
            "false_success_claims": int((claimed & ~success).sum()),
            "false_failure_claims": int((~claimed & success).sum()),
        })
    return pd.DataFrame(rows)
