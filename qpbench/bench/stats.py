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
from qpbench.solvers.run import BELOW_FLOOR, NO_SOLUTION

SHIFT_FACTOR = 10.0
OWN_BACKEND = "qpbench"  # the backend name of the solvers written here
NATIVE_BACKEND = "native"  # pairs ``<solver>-native``: a backend through its own Python API
WRAPPERS = {"qpsolvers": "{}", "cvxpy": "cvxpy-{}"}  # backend -> a native pair's twin's name
ALL_PROBLEMS = "all problems"
# a pair *solves* a family at a level when it solves at least this share of its problems
SOLVES_SHARE = 0.95
# a pair is *iterative* when its time on the problems it solves at both the loosest level and
# GROWTH_LEVEL grows by at least ITERATIVE_GROWTH (geometric mean over those problems)
GROWTH_LEVEL = 1e-8
ITERATIVE_GROWTH = 1.25
PROFILE_TAUS = np.logspace(0, 4, 200)


def solver_keys(frame: pd.DataFrame) -> pd.Series:
    """Give ``solver/formulation`` for every row.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows with ``solver`` and ``formulation`` columns.

    Returns
    -------
    pandas.Series
        The pair's key of each row, on ``frame``'s index.
    """
    return frame["solver"].astype(str) + "/" + frame["formulation"].astype(str)


def charged_times(frame: pd.DataFrame) -> pd.Series:
    """Give each row's time charged: ``time_s`` where the solve succeeded, else the time limit.

    A row without a time limit is charged the largest time seen (1 s when there is none).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows with ``time_s``, ``success`` and, optionally, ``time_limit_s``.

    Returns
    -------
    pandas.Series
        The charged time in seconds of each row, on ``frame``'s index.
    """
    fallback = float(np.nanmax(frame["time_s"].to_numpy(dtype=float), initial=1.0))
    limit = frame["time_limit_s"].astype(float).fillna(fallback) if "time_limit_s" in frame \
        else pd.Series(fallback, index=frame.index)
    success = frame["success"].fillna(False).astype(bool)
    times = frame["time_s"].astype(float)
    return times.where(success & times.notna(), limit)


def time_scale_shift(frame: pd.DataFrame, factor: float = SHIFT_FACTOR) -> float:
    """Compute the shift of the geometric mean on the problems' own time scale.

    The shift is ``factor * median over (problem, accuracy) of the fastest successful
    time_s``; it falls back to ``factor`` times the median of all positive times, then to 1 s.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows with ``problem``, ``accuracy``, ``success`` and ``time_s``.
    factor : float, optional
        The multiple of the median; SHIFT_FACTOR (10) by default.

    Returns
    -------
    float
        The shift in seconds.
    """
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
    """Compute the shifted geometric mean SGM = exp(mean(log(t_i + shift))) - shift.

    Parameters
    ----------
    times : sequence of float or numpy.ndarray
        The times t_i in seconds.
    shift : float
        The shift in seconds (:func:`time_scale_shift`).

    Returns
    -------
    float
        The SGM in seconds; NaN for no times.
    """
    values = np.asarray(times, dtype=float)
    if values.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(values + shift))) - shift)


def level_summary(frame: pd.DataFrame, shift: float) -> pd.DataFrame:
    """Summarise each (accuracy, solver/formulation) of a results table.

    Per pair and level: solves, success rate, SGM of charged time, median formulation time
    (building its matrices, outside time_s), median and max residual, max v_error, counts of
    crashed / timeout / out-of-memory rows.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    shift : float
        The shift of the SGM in seconds (:func:`time_scale_shift`).

    Returns
    -------
    pandas.DataFrame
        One row per (accuracy, pair), sorted: columns accuracy, solver (the pair), ours,
        solves, success_rate, sgm_time_s, median_formulation_s, median_residual, max_residual,
        max_v_error, crashed, timeout, out_of_memory.
    """
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
    """Tabulate the performance ratios r = t / min over solvers of t (inf on failure).

    Problems no solver solved are dropped (no ratio exists).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows of one accuracy level.

    Returns
    -------
    pandas.DataFrame
        problem x solver/formulation table of r.
    """
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
    """Compute the Dolan-More profile rho_s(tau): the share of problems with r_{p,s} <= tau.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows of one accuracy level.
    taus : numpy.ndarray, optional
        The values of tau; PROFILE_TAUS (200 points from 1 to 1e4) by default.

    Returns
    -------
    pandas.DataFrame
        tau (index) x solver/formulation table of rho; no columns when no problem was solved.
    """
    ratios = performance_ratios(frame)
    if ratios.empty:
        return pd.DataFrame(index=pd.Index(taus, name="tau"))
    values = ratios.to_numpy()
    profile = {key: (values[:, j][None, :] <= taus[:, None]).mean(axis=1)
               for j, key in enumerate(ratios.columns)}
    return pd.DataFrame(profile, index=pd.Index(taus, name="tau"))


def cost_of_accuracy(frame: pd.DataFrame, shift: float) -> pd.DataFrame:
    """Tabulate each pair's SGM charged time at each level and its growth from level to level.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    shift : float
        The shift of the SGM in seconds (:func:`time_scale_shift`).

    Returns
    -------
    pandas.DataFrame
        Per solver/formulation (rows) the SGM charged time at each level (columns
        ``SGM @ a``, loosest first), and the ratio from each level to the next tighter one
        (columns ``a -> b``); empty without rows.
    """
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
    """Tabulate each pair's time ratio from each level to the next, on problems solved at both.

    For each level and the next tighter one (columns ``a -> b``): the median over problems
    solved at BOTH levels of ``t_b / t_a``, so failures at either level do not enter.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        Per solver/formulation (rows, index ``solver``) the median ratio of each step; NaN
        where no problem is solved at both levels.
    """
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
    """Tabulate what each pair reaches within ``budget_s`` seconds per solve.

    * ``tightest_level``: the smallest accuracy level at which it succeeded within the budget
      on at least ``share`` of the problems (NaN: none);
    * ``median_best_v_error``: over problems, the median of the smallest v_error among its
      successful solves within the budget (inf for a problem with none).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    budget_s : float
        The time budget per solve in seconds.
    share : float, optional
        The share of problems a level must be reached on; 0.9 by default.

    Returns
    -------
    pandas.DataFrame
        One row per pair: solver, problems, tightest_level, median_best_v_error.
    """
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
    """Mark the rows of a solver written here.

    Such a solver (backend ``qpbench``) stops on qpbench's own residual, so its claim agrees
    with the verdict by construction.

    Parameters
    ----------
    group : pandas.DataFrame
        The rows of one pair, with a ``backend`` column.

    Returns
    -------
    str
        ``ours`` when a row's backend is ``qpbench``, else ``''``.
    """
    return "ours" if (group["backend"].astype(str) == OWN_BACKEND).any() else ""


def honesty(frame: pd.DataFrame) -> pd.DataFrame:
    """Tabulate how often each pair's own claim of success agrees with qpbench's verdict.

    Over solves judged on merit (``solved``, ``inaccurate`` or ``failed``: no crash, timeout or
    out-of-memory, and no undecided ``no-solution`` or ``below-floor``): the share where its own
    claim of success agreed with qpbench's verdict, and the two ways it can disagree (claimed
    success but failed; claimed failure but solved). Our own solvers are marked (``ours``):
    their honesty is 100% by construction, not an achievement.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        One row per pair: solver, ours, solves, honesty_rate, false_success_claims,
        false_failure_claims.
    """
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


# --- the comparison: per family and level the fastest pair of each formulation -----------------
EXTERNAL = "external"  # the comparison's column of the fastest pair of another backend
OURS = "ours"  # ... and of the fastest pair written here
# the comparison's formulation columns in this order (any others after them, by name)
FORMULATION_ORDER = ("dual", "lcp", "primal", "dual-factored", "nsgs", "staggered", "ccp",
                     "fc2d")


def formulations_in_order(frame: pd.DataFrame) -> list[str]:
    """List the formulations of ``frame``'s rows, those of FORMULATION_ORDER first in its order.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows with a ``formulation`` column.

    Returns
    -------
    list of str
        The formulations present; those not in FORMULATION_ORDER follow, by name.
    """
    present = set(frame["formulation"].dropna().astype(str))
    return ([name for name in FORMULATION_ORDER if name in present]
            + sorted(present - set(FORMULATION_ORDER)))


def without_unsolvable(frame: pd.DataFrame) -> pd.DataFrame:
    """Drop the rows of the problems known to have no solution.

    A problem with a ``no-solution`` row loses all its rows (a timeout on it included), never
    counted against a solver.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        The rows of the other problems.
    """
    hopeless = set(frame.loc[frame["status"].astype(str) == NO_SOLUTION, "problem"])
    return frame[~frame["problem"].isin(hopeless)]


# the cell double precision cannot decide: a problem at an accuracy level
FLOOR_CELL = ["problem", "accuracy"]


def below_floor_cells(frame: pd.DataFrame) -> pd.DataFrame:
    """List the (problem, level) cells below the problem's double-precision residual floor.

    A cell is below the floor when one of its rows has the verdict ``below-floor``
    (``qpbench.solvers.run.judge``: the level is below the least residual a double vector is
    known to reach on the problem).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        Columns problem, accuracy and rows (the cell's rows, of every pair and mode), sorted
        by problem, then level loosest first; no rows when no cell is below a floor.
    """
    marked = frame.loc[frame["status"].astype(str) == BELOW_FLOOR, FLOOR_CELL]
    cells = marked.drop_duplicates()
    if cells.empty:
        return pd.DataFrame({"problem": pd.Series(dtype=str),
                             "accuracy": pd.Series(dtype=float),
                             "rows": pd.Series(dtype=int)})
    rows = frame[FLOOR_CELL].merge(cells, on=FLOOR_CELL).groupby(FLOOR_CELL).size()
    found = rows.rename("rows").reset_index()
    return found.sort_values(["problem", "accuracy"], ascending=[True, False],
                             ignore_index=True)


def without_below_floor(frame: pd.DataFrame) -> pd.DataFrame:
    """Drop the rows of the cells below a problem's double-precision residual floor.

    Every row of such a (problem, level) cell goes (a timeout in it included), never counted
    against a solver nor for one; the problem's other levels stay.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        The rows of the other cells.
    """
    cells = below_floor_cells(frame)
    if cells.empty:
        return frame
    keys = pd.MultiIndex.from_frame(frame[FLOOR_CELL])
    return frame[~keys.isin(pd.MultiIndex.from_frame(cells[FLOOR_CELL]))]


def pair_backends(frame: pd.DataFrame) -> dict[str, str]:
    """Map each ``solver/formulation`` to the backend of its rows.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows, with or without a ``backend`` column.

    Returns
    -------
    dict of str to str
        pair -> the backend of its first row ('' where the column is missing).
    """
    backend = (frame["backend"].astype("string").fillna("").astype(str) if "backend" in frame
               else pd.Series("", index=frame.index))
    return {str(key): str(value) for key, value in
            backend.groupby(solver_keys(frame)).first().items()}


def fastest_pairs(summarised: Sequence[tuple[str, float, pd.DataFrame]],
                  backends: dict[str, str]) -> pd.DataFrame:
    """Pick, per family and level, the fastest pair of each formulation, of others and of ours.

    Per family and level (loosest first), among the pairs that solve the family at the level
    (at least SOLVES_SHARE of its problems): the fastest pair of each formulation (``column``
    the formulation), the fastest pair of a backend other than ours (``column`` EXTERNAL) and
    the fastest pair written here (``column`` OURS). A column with no pair that solves has no
    row; ties go to the first pair by name.

    Parameters
    ----------
    summarised : sequence of tuple of (str, float, pandas.DataFrame)
        (family, shift, summary) with a summary's columns ``accuracy``, ``solver`` (the pair),
        ``success_rate`` and ``sgm_time_s`` (:func:`level_summary`).
    backends : dict of str to str
        pair -> its backend (:func:`pair_backends`).

    Returns
    -------
    pandas.DataFrame
        Columns family, level, column, pair, sgm_time_s, success_rate.
    """
    rows = []
    for family, _shift, summary in summarised:
        solving = summary[summary["success_rate"] >= SOLVES_SHARE]
        solving = solving.assign(
            formulation=solving["solver"].astype(str).str.split("/", n=1).str[1],
            own=[backends.get(str(key)) == OWN_BACKEND for key in solving["solver"]])
        solving = solving.sort_values(["sgm_time_s", "solver"], kind="stable")
        for accuracy in sorted(summary["accuracy"].unique(), reverse=True):
            at_level = solving[solving["accuracy"] == accuracy]
            columns = list(at_level.groupby("formulation", sort=True))
            columns += [(EXTERNAL, at_level[~at_level["own"]]), (OURS, at_level[at_level["own"]])]
            for column, group in columns:
                if group.empty:
                    continue
                best = group.iloc[0]
                rows.append({"family": family, "level": float(accuracy), "column": column,
                             "pair": str(best["solver"]),
                             "sgm_time_s": float(best["sgm_time_s"]),
                             "success_rate": float(best["success_rate"])})
    return pd.DataFrame(rows, columns=["family", "level", "column", "pair", "sgm_time_s",
                                       "success_rate"])


# --- what accuracy costs where it costs ---------------------------------------------------------
def _solved_times(frame: pd.DataFrame) -> pd.DataFrame:
    """(pair, problem) x level table of the time of each successful solve (NaN elsewhere)."""
    frame = frame.assign(key=solver_keys(frame))
    solved = frame[frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()
                   & (frame["time_s"].astype(float) > 0)]
    return solved.pivot_table(index=["key", "problem"], columns="accuracy", values="time_s",
                              aggfunc="min")


def time_growth(frame: pd.DataFrame) -> pd.Series:
    """Measure how each pair's time grows from the loosest level to GROWTH_LEVEL.

    Per pair: the geometric mean, over the problems it solves at both the loosest level and
    GROWTH_LEVEL (the tightest level where that is absent), of the time at the tighter level
    divided by the time at the loosest. Pairs without such a problem are left out.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.Series
        pair -> growth factor; empty with fewer than two levels.
    """
    levels = sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True)
    times = _solved_times(frame)
    if len(levels) < 2 or times.empty:
        return pd.Series(dtype=float)
    target = next((a for a in levels if math.isclose(a, GROWTH_LEVEL)), levels[-1])
    if levels[0] not in times or target not in times:
        return pd.Series(dtype=float)
    logs = np.log((times[target] / times[levels[0]]).dropna())
    return np.exp(logs.groupby(level="key").mean())


def iterative_pairs(frame: pd.DataFrame) -> list[str]:
    """List the pairs whose time grows with the level (time_growth >= ITERATIVE_GROWTH).

    These are the first-order and splitting methods, whose iterations follow the tolerance,
    where a direct method's factorization costs the same at every level.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    list of str
        The pairs, the steepest first.
    """
    growth = time_growth(frame)
    growth = growth[growth >= ITERATIVE_GROWTH]
    return [str(key) for key in growth.sort_values(ascending=False, kind="stable").index]


def _step_logs(frame: pd.DataFrame) -> pd.DataFrame:
    """Per (pair, problem) solved at two consecutive levels a > b: ``log(t_b / t_a)`` and the
    number of digits between them; columns key, problem, looser, log, digits."""
    times = _solved_times(frame)
    levels = sorted(times.columns, reverse=True)
    steps = []
    for looser, tighter in zip(levels, levels[1:], strict=False):
        log = np.log((times[tighter] / times[looser]).dropna())
        steps.append(pd.DataFrame({"key": log.index.get_level_values("key"),
                                   "problem": log.index.get_level_values("problem"),
                                   "looser": float(looser), "log": log.to_numpy(),
                                   "digits": math.log10(float(looser) / float(tighter))}))
    return pd.concat(steps, ignore_index=True) if steps else pd.DataFrame(
        columns=["key", "problem", "looser", "log", "digits"])


def time_per_digit(frame: pd.DataFrame, pairs: Sequence[str]) -> pd.DataFrame:
    """Tabulate the factor each further digit of accuracy multiplies a pair's time by.

    Per pair and family: the geometric mean over the family's problems it solves at two
    consecutive levels a > b of ``(t_b / t_a) ** (1 / log10(a / b))``.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    pairs : sequence of str
        The pairs to tabulate.

    Returns
    -------
    pandas.DataFrame
        Pairs (rows, in the order of ``pairs``) x families (columns, ALL_PROBLEMS first); NaN
        where a pair solves no problem at two consecutive levels.
    """
    steps = _step_logs(frame[solver_keys(frame).isin(list(pairs))])
    family = frame.assign(family=frame["family"].astype("string").fillna("").astype(str)) \
        .groupby("problem")["family"].first()
    steps = steps.assign(per_digit=steps["log"] / steps["digits"],
                         family=steps["problem"].map(family))
    table = {ALL_PROBLEMS: np.exp(steps.groupby("key")["per_digit"].mean())}
    for name, group in steps.groupby("family", sort=True):
        if name:
            table[str(name)] = np.exp(group.groupby("key")["per_digit"].mean())
    return pd.DataFrame(table, columns=list(table)).reindex(list(pairs)).astype(float)


def relative_time(frame: pd.DataFrame, pairs: Sequence[str]) -> pd.DataFrame:
    """Tabulate each pair's time relative to the loosest level, at each level.

    The relative time is the product of the steps up to the level, each step the geometric
    mean over the problems solved at both its levels of the time ratio.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    pairs : sequence of str
        The pairs to tabulate.

    Returns
    -------
    pandas.DataFrame
        Pairs (rows, in the order of ``pairs``) x levels (columns, loosest first, where the
        value is 1); NaN from the first step without a problem solved at both levels on.
    """
    levels = sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True)
    steps = _step_logs(frame[solver_keys(frame).isin(list(pairs))])
    mean = steps.groupby(["key", "looser"])["log"].mean()
    table = pd.DataFrame(math.nan, index=list(pairs), columns=levels)
    for key in table.index:
        total = 0.0
        table.loc[key, levels[0]] = 1.0
        for looser, tighter in zip(levels, levels[1:], strict=False):
            if (key, looser) not in mean.index:
                break
            total += float(mean[(key, looser)])
            table.loc[key, tighter] = math.exp(total)
    return table


def wrapper_costs(frame: pd.DataFrame) -> pd.DataFrame:
    """Compare each native pair with its twins that call the same solver through a wrapper.

    Per native pair (backend NATIVE_BACKEND, ``<solver>-native``) and each twin that calls
    the same solver on the same formulation through a wrapper (WRAPPERS: the qpsolvers pair
    ``<solver>``, the cvxpy pair ``cvxpy-<solver>``) in ``frame``: over the cells (problem,
    level, mode) both ran, the success rate of each, and the median over the cells both solved
    of the twin's time divided by the native pair's (what the wrapper adds: above 1 it is
    slower).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    pandas.DataFrame
        Columns native, wrapper, twin, cells, native_success_rate, twin_success_rate,
        both_solved, time_ratio; empty without a ``backend`` column.
    """
    columns = ["native", "wrapper", "twin", "cells", "native_success_rate",
               "twin_success_rate", "both_solved", "time_ratio"]
    if "backend" not in frame:
        return pd.DataFrame(columns=columns)
    cell = ["problem", "accuracy", "mode"]
    frame = frame.assign(key=solver_keys(frame),
                         backend=frame["backend"].astype("string").fillna("").astype(str),
                         mode=frame["mode"].astype("string").fillna("").astype(str),
                         success=frame["success"].fillna(False).astype(bool),
                         time_s=frame["time_s"].astype(float))
    frame = frame[cell + ["key", "backend", "success", "time_s"]].drop_duplicates(cell + ["key"])
    rows = []
    for key in sorted(frame.loc[frame["backend"] == NATIVE_BACKEND, "key"].unique()):
        solver, formulation = key.split("/", 1)
        native = frame[frame["key"] == key]
        for wrapper, pattern in WRAPPERS.items():
            twin_key = f"{pattern.format(solver.removesuffix('-native'))}/{formulation}"
            twin = frame[(frame["key"] == twin_key) & (frame["backend"] == wrapper)]
            both = native.merge(twin, on=cell, suffixes=("_native", "_twin"))
            if both.empty:
                continue
            solved = (both["success_native"] & both["success_twin"]
                      & (both["time_s_native"] > 0) & (both["time_s_twin"] > 0))
            ratio = (both["time_s_twin"] / both["time_s_native"])[solved]
            rows.append({"native": key, "wrapper": wrapper, "twin": twin_key,
                         "cells": len(both),
                         "native_success_rate": float(both["success_native"].mean()),
                         "twin_success_rate": float(both["success_twin"].mean()),
                         "both_solved": int(solved.sum()),
                         "time_ratio": float(ratio.median()) if len(ratio) else math.nan})
    return pd.DataFrame(rows, columns=columns)
