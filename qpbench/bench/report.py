"""The Markdown report of a results table (REPORT.md, with its PNG figures beside it).

Sections: what was run; the comparison first (per family and level the fastest pair of each
formulation and the fastest external pair beside the fastest of ours, frictionless and
frictional; what each further digit costs the pairs whose time grows with the level; what
each wrapper adds to a native pair); a summary per level; machine and version provenance;
per accuracy level the success rate, shifted geometric mean time and residuals; formulations
side by side; work-precision diagrams per family; Dolan-More profiles; the time at each level
of the most reliable pairs; warm against cold starts; the sections the caller brings (the
targets of our own solver); friction; status honesty; known defects; the accuracy-options
table; any extra sections other parts of qpbench left as JSON files (a
``"markdown"`` key) in the results folder; and the counts of a ``qpbench fuzz`` run whose
``fuzz.json`` lies there.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from qpbench.atomic import atomic_path
from qpbench.bench import below_floor, html_report, imported_problems, plots, sim_precision, stats
from qpbench.bench.formatting import level, number, percent
from qpbench.bench.results import ResultStore, split_kinds
from qpbench.errors import InputError
from qpbench.solvers import accuracy as accuracy_table
from qpbench.solvers import defects as defect_table
from qpbench.solvers.base import TIME_S_COVERS
from qpbench.solvers.run import NO_SOLUTION

PROFILE_LEVELS = (1e-4, 1e-8)

Formatter = Callable[[Any], str]
# a section of the summary that the caller brings (the report itself knows no solver): its
# title and its Markdown from the cold frictionless rows and the SGM shift
SummarySection = tuple[str, Callable[[pd.DataFrame, float], str]]
INDEX_POINTER = ("At a glance, interactive and offline: [index.html](index.html) (open it in a "
                 "browser).\n\n")


# --- formatting ------------------------------------------------------------------------------
def _maybe_level(value: Any) -> str:
    return "-" if value is None or pd.isna(value) else level(value)


def markdown_table(frame: pd.DataFrame, formats: dict[str, Formatter] | None = None,
                   index: bool = False) -> str:
    """Write ``frame`` as a GitHub Markdown table.

    Parameters
    ----------
    frame : pandas.DataFrame
        The rows.
    formats : dict of str to callable, optional
        column -> formatter of its cells; :func:`number` for the others.
    index : bool, optional
        Show the index as the first columns; False by default.

    Returns
    -------
    str
        The table's lines (``|`` in a cell escaped), or ``_(no rows)_`` for an empty frame.
    """
    formats = formats or {}
    if index:
        frame = frame.reset_index()
    if frame.empty:
        return "_(no rows)_\n"
    header = "| " + " | ".join(str(column) for column in frame.columns) + " |"
    rule = "|" + "|".join("---" for _ in frame.columns) + "|"
    lines = [header, rule]
    for _, row in frame.iterrows():
        cells = [formats.get(column, number)(row[column]) for column in frame.columns]
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
    return "\n".join(lines) + "\n"


def _image(path: Path | None, folder: Path, alt: str) -> str:
    if path is None:
        return f"_(no data for {alt})_\n"
    return f"![{alt}]({os.path.relpath(path, folder)})\n"


# --- sections ----------------------------------------------------------------------------------
def _overview(frame: pd.DataFrame, source: Path) -> str:
    statuses = frame["status"].astype(str).value_counts()
    lines = [
        f"Results: `{source.name}`, {len(frame)} solves of {frame['problem'].nunique()} "
        f"problems ({', '.join(sorted(frame['family'].dropna().astype(str).unique()))}) by "
        f"{stats.solver_keys(frame).nunique()} solver/formulation pairs at accuracy levels "
        f"{', '.join(level(a) for a in sorted(frame['accuracy'].unique(), reverse=True))}; "
        f"modes {', '.join(sorted(frame['mode'].dropna().astype(str).unique()))}.",
        "",
        "Statuses: " + ", ".join(f"{status} {count}" for status, count in statuses.items()) + ".",
        "",
        "`solved` = finite impulses with qpbench's residual <= the accuracy level; a solver's own "
        "status is recorded but never trusted. `crashed`, `timeout` and `out-of-memory` are "
        "solves whose isolated worker process died, ran past the time limit or hit the memory "
        "cap.",
    ]
    floor = below_floor.note(frame)
    return "\n".join(lines + (["", floor] if floor else [])) + "\n"


def _provenance(frame: pd.DataFrame) -> str:
    def values(column: str) -> str:
        if column not in frame:
            return "-"
        found = sorted(frame[column].dropna().astype(str).unique())
        return ", ".join(found) if found else "-"

    overhead = frame["timer_overhead_s"].dropna() if "timer_overhead_s" in frame else []
    rows = pd.DataFrame([
        {"item": "qpbench", "value": values("qpbench_version")},
        {"item": "package lock (requirements.lock, SHA-256)", "value": values("lock_hash")},
        {"item": "Python", "value": values("python_version")},
        {"item": "NumPy", "value": values("numpy_version")},
        {"item": "platform", "value": values("platform")},
        {"item": "CPU", "value": values("cpu_model")},
        {"item": "hosts", "value": values("hostname")},
        {"item": "dates (UTC)", "value": (f"{frame['date'].dropna().min()} .. "
                                          f"{frame['date'].dropna().max()}")
         if "date" in frame and frame["date"].notna().any() else "-"},
        {"item": "time limit per solve [s]", "value": values("time_limit_s")},
        {"item": "memory cap per worker [MiB]", "value": values("memory_limit_mb")},
        {"item": "timed repeats (time_s = min)", "value": values("repeats_requested")},
        {"item": "repeat budget per solve [s] (fewer repeats once they took this long)",
         "value": values("repeat_budget_s")},
        {"item": "timer overhead (perf_counter back-to-back, min)",
         "value": f"{np.median(overhead) * 1e9:.0f} ns" if len(overhead) else "-"},
        {"item": "fastest solve measured (time_s)", "value": _fastest(frame, overhead)},
        {"item": "spread of repeats (median of max / min time)", "value": _spread(frame)},
    ])
    versions = (frame.assign(key=stats.solver_keys(frame))
                .groupby("key")[["backend", "solver_version"]].first().reset_index()
                .rename(columns={"key": "solver/formulation"}))
    return (markdown_table(rows, {"value": str}) + "\nSolver versions:\n\n"
            + markdown_table(versions, {c: str for c in versions.columns}))


def _fastest(frame: pd.DataFrame, overhead: Any) -> str:
    """The smallest solver time in the table and how many timer overheads it spans."""
    times = frame["time_s"].dropna()
    times = times[times > 0]
    if not len(times):
        return "-"
    fastest = float(times.min())
    if not len(overhead):
        return f"{fastest:.3g} s"
    return f"{fastest:.3g} s = {fastest / float(np.median(overhead)):.0f} x the timer overhead"


def _spread(frame: pd.DataFrame) -> str:
    """How much repeated timings of one solve differ: median over solves of max / min."""
    if "time_max_s" not in frame or "repeats" not in frame:
        return "-"
    repeated = frame[(frame["repeats"].fillna(0) > 1) & (frame["time_s"] > 0)]
    if repeated.empty:
        return "- (one repeat per solve)"
    ratio = (repeated["time_max_s"] / repeated["time_s"]).astype(float)
    return f"{float(ratio.median()):.3g} over {len(repeated)} repeated solves"


def _levels(summary: pd.DataFrame, shift: float) -> str:
    parts = [
        f"Shifted geometric mean (SGM) of time with shift {shift:.3g} s = "
        f"{stats.SHIFT_FACTOR:g} x the median over problems and levels of the fastest "
        "successful solve (the problems' own time scale); a failed solve is charged the time "
        f"limit. {TIME_S_COVERS}\n",
    ]
    for accuracy in sorted(summary["accuracy"].unique(), reverse=True):
        table = summary[summary["accuracy"] == accuracy].drop(columns="accuracy")
        table = table.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True])
        parts.append(f"\n### Accuracy {level(accuracy)}\n\n" + markdown_table(
            table.head(TOP_ROWS), {"success_rate": percent}) + _more(len(table)))
    return "".join(parts)


TOP_ROWS = 12  # rows of a ranking in REPORT.md; index.html has every pair


def _more(rows: int) -> str:
    """The pointer under a table cut to TOP_ROWS rows."""
    if rows <= TOP_ROWS:
        return ""
    return f"\n_{rows - TOP_ROWS} more pairs: every one in [index.html](index.html)._\n"


PAIRS_PER_TABLE = 8  # pair columns of one time-per-digit table


def _cold(frame: pd.DataFrame) -> pd.DataFrame:
    """The cold-start rows, or every row where there are none."""
    cold = frame[frame["mode"].astype(str) == "cold"]
    return frame if cold.empty else cold


def _comparison(frame: pd.DataFrame, heading: str) -> str:
    """Per level (loosest first) a table with a row per family (all problems first): the
    fastest pair of each formulation that solves the family at the level (the fastest of the
    row in bold), the fastest external pair, the fastest of ours and how many times faster
    ours is (stats.fastest_pairs)."""
    summarised = html_report.summaries(frame)
    fastest = stats.fastest_pairs(summarised, stats.pair_backends(frame))
    cells = {(row.family, row.level, row.column): row
             for row in fastest.itertuples(index=False)}
    formulations = stats.formulations_in_order(frame)
    parts = []
    for accuracy in sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True):
        rows = []
        for family, _shift, _summary in summarised:
            found = {column: cells.get((family, accuracy, column))
                     for column in (*formulations, stats.EXTERNAL, stats.OURS)}
            times = [found[name].sgm_time_s for name in formulations if found[name] is not None]
            row = {"family": family}
            for name in formulations:
                item = found[name]
                text = "-" if item is None else \
                    f"`{item.pair.split('/', 1)[0]}` {number(item.sgm_time_s)}"
                row[name] = f"**{text}**" if item is not None and item.sgm_time_s == min(times) \
                    else text
            external, ours = found[stats.EXTERNAL], found[stats.OURS]
            for name, item in (("fastest external", external), ("fastest of ours", ours)):
                row[name] = "-" if item is None else f"`{item.pair}` {number(item.sgm_time_s)}"
            row["external / ours"] = (
                f"{external.sgm_time_s / ours.sgm_time_s:.3g}"
                if external is not None and ours is not None and ours.sgm_time_s > 0 else "-")
            rows.append(row)
        table = pd.DataFrame(rows)
        parts.append(f"\n### {heading}{level(accuracy)}\n\n"
                     + markdown_table(table, {column: str for column in table.columns}))
    return "".join(parts)


def _accuracy_cost(frame: pd.DataFrame, figure: Path | None, folder: Path) -> str:
    """The pairs whose time grows with the level (stats.iterative_pairs): how much each grows
    from the loosest level, down to which level it solves, and per family the factor each
    further digit multiplies its time by (stats.time_per_digit); with ``figure``, the chart of
    their time relative to the loosest level."""
    levels = sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True)
    pairs = stats.iterative_pairs(frame)
    target = next((a for a in levels if math.isclose(a, stats.GROWTH_LEVEL)), levels[-1])
    if not pairs:
        return (f"_No pair's time grows by {stats.ITERATIVE_GROWTH:g} x or more from "
                f"{level(levels[0])} to {level(target)} here._\n")
    growth = stats.time_growth(frame)
    per_digit = stats.time_per_digit(frame, pairs)
    solved = frame.assign(key=stats.solver_keys(frame),
                          solved=frame["success"].fillna(False).astype(bool))
    rates = solved.groupby(["key", "accuracy"])["solved"].mean()
    parts = []
    for start in range(0, len(pairs), PAIRS_PER_TABLE):
        chunk = pairs[start:start + PAIRS_PER_TABLE]
        rows = [{"": f"time {level(target)} / {level(levels[0])}",
                 **{key: f"{growth[key]:.3g}" for key in chunk}},
                {"": f"solves (>= {percent(stats.SOLVES_SHARE)}) down to",
                 **{key: _maybe_level(min((a for (k, a), rate in rates.items()
                                           if k == key and rate >= stats.SOLVES_SHARE),
                                          default=None)) for key in chunk}}]
        rows += [{"": f"per digit, {family}",
                  **{key: number(per_digit.loc[key, family]) for key in chunk}}
                 for family in per_digit.columns]
        table = pd.DataFrame(rows)
        parts.append(markdown_table(table, {column: str for column in table.columns}) + "\n")
    text = (f"{len(pairs)} pair{'s' if len(pairs) > 1 else ''} whose time at {level(target)} "
            "is at least "
            f"{stats.ITERATIVE_GROWTH:g} x their time at {level(levels[0])} (geometric mean over "
            "the problems each solves at both: methods whose iterations follow the "
            "tolerance, where a direct factorization costs the same at every level), steepest "
            "first. Per family, the factor each "
            "further digit multiplies the time by: the geometric mean over the family's "
            "problems solved at two consecutive levels a > b of (t_b / t_a)^(1 / log10(a / b)) "
            "(- : no such problem).\n\n" + "".join(parts))
    if figure is not None:
        text += "\n" + _image(plots.cost_of_accuracy(stats.relative_time(frame, pairs), figure),
                              folder, "cost of accuracy")
    return text


def _wrapper_costs(frame: pd.DataFrame) -> str:
    """Per native pair, its qpsolvers and cvxpy twins (stats.wrapper_costs)."""
    table = stats.wrapper_costs(frame)
    if table.empty:
        return ("_No native pairs (`<solver>-native`, a backend through its own Python API) "
                "with a twin in these results._\n")
    table = table.rename(columns={
        "native": "native pair", "twin": "twin pair", "cells": "cells both ran",
        "native_success_rate": "native solved", "twin_success_rate": "twin solved",
        "both_solved": "cells both solved", "time_ratio": "twin time / native time"})
    return ("Each native pair (`<solver>-native`: the backend through its own Python API) "
            "against the same solver on the same formulation through qpsolvers (`<solver>`) "
            "and through cvxpy (`cvxpy-<solver>`), on the cells (problem, level) both ran in "
            "these results: the share each solved, and the median over the cells both solved "
            "of the twin's time over the native pair's (what the wrapper adds; above 1 it is "
            "slower).\n\n"
            + markdown_table(table, {"native solved": percent, "twin solved": percent,
                                     "native pair": lambda v: f"`{v}`",
                                     "twin pair": lambda v: f"`{v}`"}))


def _lead(frame: pd.DataFrame, frictional: pd.DataFrame, folder: Path) -> str:
    """The report's opening: the fastest pairs per family and level, frictionless then
    frictional; what accuracy costs the pairs whose time grows with it; what each wrapper
    adds to a native pair."""
    main = _cold(frame) if not frame.empty else frame
    solvable = stats.without_unsolvable(frictional) if not frictional.empty else frictional
    parts = ["\n## Fastest pairs, per family and level\n\n"
             "Among the pairs that *solve* a family at a level (at least "
             f"{percent(stats.SOLVES_SHARE)} of its problems; success = qpbench's residual <= "
             "the level): the fastest pair of each formulation (solver named; the fastest of "
             "the row in bold), the fastest external pair (a backend not written here), the "
             "fastest of ours, and `external / ours`, how many times faster ours is. Time = "
             "shifted geometric mean of time_s [s] over the family's problems with the "
             "family's own shift, failures charged the time limit; - : no pair solves. "
             "Frictional problems without a solution are left out, and so are the cells "
             "below a problem's double-precision floor (`below-floor`); `ccp` answers are "
             "judged by the relaxed model's residual.\n"]
    if not main.empty:
        parts.append(_comparison(main, "Accuracy "))
    if not solvable.empty:
        parts.append(_comparison(solvable, "Frictional problems, accuracy "))
    parts.append("\n## What accuracy costs, where it costs\n\n")
    if not main.empty and main["accuracy"].nunique() > 1:
        parts.append(_accuracy_cost(main, folder / "figures" / "cost_of_accuracy.png", folder))
    if not solvable.empty and solvable["accuracy"].nunique() > 1:
        parts.append("\n### Frictional problems\n\n" + _accuracy_cost(solvable, None, folder))
    if parts[-1].startswith("\n## What accuracy costs"):
        parts.append("_A single accuracy level: nothing to compare._\n")
    parts.append("\n## Wrapper costs\n\n" + _wrapper_costs(main if not main.empty else frame))
    return "".join(parts)


def _families(frame: pd.DataFrame) -> str:
    """Success rate per solver/formulation (rows) and family (columns) at the tightest level."""
    tightest = float(frame["accuracy"].min())
    at_level = frame[np.isclose(frame["accuracy"].astype(float), tightest)]
    at_level = at_level.assign(key=stats.solver_keys(at_level),
                               solved=at_level["success"].fillna(False).astype(bool))
    table = at_level.pivot_table(index="key", columns="family", values="solved", aggfunc="mean")
    table.index.name = "solver"
    return (f"\nAt accuracy {level(tightest)}, the share of each family's problems solved.\n\n"
            + markdown_table(table, {column: percent for column in table.columns}, index=True))


def _formulations(summary: pd.DataFrame) -> str:
    split = summary["solver"].str.split("/", n=1, expand=True)
    summary = summary.assign(name=split[0], formulation=split[1])
    parts = []
    for accuracy in sorted(summary["accuracy"].unique(), reverse=True):
        at_level = summary[summary["accuracy"] == accuracy]
        cells = at_level.assign(cell=[f"{percent(r)} / {number(t)} s" for r, t in
                                      zip(at_level["success_rate"], at_level["sgm_time_s"],
                                          strict=True)])
        table = cells.pivot(index="name", columns="formulation", values="cell").fillna("")
        parts.append(f"\n### Accuracy {level(accuracy)} (success rate / SGM time)\n\n"
                     + markdown_table(table, {c: str for c in table.columns}, index=True)
                     .replace("| name |", "| solver |", 1))
    return "".join(parts)


def _summary(summary: pd.DataFrame) -> str:
    """Per level: the most reliable solver/formulation and the fastest of those that solved
    at least SUMMARY_SUCCESS of the problems."""
    rows = []
    for accuracy, group in summary.groupby("accuracy"):
        ranked = group.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True])
        reliable = ranked.iloc[0]
        fast = group[group["success_rate"] >= SUMMARY_SUCCESS].sort_values("sgm_time_s")
        fastest = (f"`{fast.iloc[0]['solver']}` ({number(fast.iloc[0]['sgm_time_s'])} s)"
                   if len(fast) else "none")
        rows.append({
            "level": level(accuracy),
            "most reliable": f"`{reliable['solver']}` ({percent(reliable['success_rate'])}, "
                             f"{number(reliable['sgm_time_s'])} s)",
            f"fastest with >= {percent(SUMMARY_SUCCESS)} solved": fastest,
            f"pairs with >= {percent(SUMMARY_SUCCESS)} solved":
                f"{int((group['success_rate'] >= SUMMARY_SUCCESS).sum())} of {len(group)}",
        })
    return ("Per level, over every problem (success = qpbench's residual <= the level; time = "
            "shifted geometric mean, failures charged the time limit):\n\n"
            + markdown_table(pd.DataFrame(rows), {c: str for c in rows[0]}) if rows else "")


def _warm_cold(frame: pd.DataFrame, shift: float) -> str:
    if set(frame["mode"].dropna().astype(str)) != {"cold", "warm"}:
        return ""
    frame = frame.assign(key=stats.solver_keys(frame), charged=stats.charged_times(frame))
    rows = []
    for (key, accuracy), group in frame.groupby(["key", "accuracy"]):
        cold = group[group["mode"] == "cold"]
        warm = group[group["mode"] == "warm"]
        if cold.empty or warm.empty:
            continue
        rows.append({
            "solver": key, "accuracy": accuracy,
            "uses warm start": bool(warm["warm_start_used"].fillna(False).any()),
            "SGM cold [s]": stats.shifted_geometric_mean(cold["charged"], shift),
            "SGM warm [s]": stats.shifted_geometric_mean(warm["charged"], shift),
            "success cold": percent(cold["success"].fillna(False).astype(bool).mean()),
            "success warm": percent(warm["success"].fillna(False).astype(bool).mean()),
        })
    if not rows:  # no cell was run both ways
        return ""
    table = pd.DataFrame(rows).sort_values(["solver", "accuracy"], ascending=[True, False])
    sources = ", ".join(sorted(frame.loc[frame["mode"] == "warm", "warm_start_source"]
                               .dropna().astype(str).unique()))
    return ("\n## Warm against cold starts\n\nWarm starts are the impulses the simulator "
            "carried into the step from the previous one, where the captured scene caches "
            "impulses (`previous`); a problem without them is solved cold (`none`). Never "
            "anything derived from the reference. Used here: " + (sources or "-") + ".\n\n"
            + markdown_table(table, {"success cold": str, "success warm": str,
                                     "accuracy": level}))


def _friction(frame: pd.DataFrame, folder: Path) -> str:
    """The frictional problems: per level and formulation the share solved and the SGM time,
    the best pair of each formulation, which inner backend serves ``staggered`` best, the
    outer-loop counts of ``staggered``, the model error of ``ccp`` and what accuracy costs.
    Problems with no solution are counted apart, never against a solver."""
    if frame.empty:
        return "_No frictional problems in these results._\n"
    # a problem known to have no solution: all its rows go, a timeout on it included
    hopeless = set(frame.loc[frame["status"].astype(str) == NO_SOLUTION, "problem"])
    problems = frame["problem"].nunique()
    without = len(hopeless)
    frame = frame[~frame["problem"].isin(hopeless)]
    families = ", ".join(sorted(frame["family"].dropna().astype(str).unique()))
    parts = [f"{problems} frictional problems ({families}), "
             f"{without} of them without a solution (counted apart). `ccp` answers are judged "
             "by the relaxed model's own residual (sliding contacts separate there); their "
             "Coulomb residual is the model error. Every other formulation is judged by the "
             "natural map of Coulomb's law with the De Saxce term.\n"]
    if frame.empty:
        return "".join(parts)
    shift = stats.time_scale_shift(frame)
    summary = stats.level_summary(frame, shift)
    split = summary["solver"].str.split("/", n=1, expand=True)
    summary = summary.assign(name=split[0], formulation=split[1])
    rows = []
    for (accuracy, formulation), group in summary.groupby(["accuracy", "formulation"]):
        best = group.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True]).iloc[0]
        rows.append({"level": level(accuracy), "formulation": formulation,
                     "pairs": len(group), "best pair": f"`{best['solver']}`",
                     "solved by it": percent(best["success_rate"]),
                     "its SGM [s]": number(best["sgm_time_s"]),
                     "median pair solved": percent(group["success_rate"].median())})
    table = pd.DataFrame(rows).sort_values(["level", "formulation"], ascending=[False, True])
    parts.append("\n### Formulations at each level\n\n"
                 + markdown_table(table, {column: str for column in table.columns}))
    staggered = summary[summary["formulation"] == "staggered"]
    if not staggered.empty:
        tightest = staggered[staggered["accuracy"] == staggered["accuracy"].min()]
        ranked = tightest.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True])
        ranked = ranked[["solver", "ours", "success_rate", "sgm_time_s"]].head(12)
        outer = frame[frame["formulation"].astype(str) == "staggered"]
        counts = outer.groupby("solver")["outer_iterations"].median() \
            if "outer_iterations" in outer else pd.Series(dtype=float)
        ranked = ranked.assign(median_outer_iterations=[
            counts.get(key.split("/")[0], math.nan) for key in ranked["solver"]])
        parts.append(f"\n### Inner backends of `staggered` at {level(tightest['accuracy'].iloc[0])}"
                     "\n\n" + markdown_table(ranked, {"success_rate": percent}))
    ccp = frame[frame["formulation"].astype(str) == "ccp"]
    if not ccp.empty and "model_error" in ccp:
        errors = ccp[ccp["success"].fillna(False).astype(bool)].groupby("family")["model_error"]
        table = pd.DataFrame({"median model error": errors.median(),
                              "max model error": errors.max()}).reset_index()
        parts.append("\n### Model error of `ccp` (Coulomb residual of its solved answers)\n\n"
                     + markdown_table(table))
    cost = stats.cost_of_accuracy(frame, shift)
    if not cost.empty:
        best = summary[summary["accuracy"] == summary["accuracy"].min()].sort_values(
            ["success_rate", "sgm_time_s"], ascending=[False, True])["solver"].head(8)
        cost = cost.loc[[key for key in best if key in cost.index]]
        parts.append("\n### What accuracy costs (the 8 most reliable pairs at the tightest "
                     "level)\n\n" + markdown_table(cost.reset_index().rename(
                         columns={"index": "solver"})))
    path = plots.success_by_level(summary.drop(columns=["name", "formulation"]),
                                  folder / "figures" / "friction_success_by_level.png")
    parts.append("\n" + _image(path, folder, "frictional success by level"))
    return "".join(parts)


def _honesty(frame: pd.DataFrame) -> str:
    """The pairs whose claims disagreed with qpbench's verdict (least honest first); the rest
    are counted."""
    table = stats.honesty(frame)
    if table.empty:
        return "_(no solves returned)_\n"
    wrong = table[table["honesty_rate"] < 1.0].sort_values("honesty_rate")
    return (markdown_table(wrong.head(TOP_ROWS), {"honesty_rate": percent}) + _more(len(wrong))
            + f"\n{len(table) - len(wrong)} of {len(table)} pairs claimed exactly what qpbench "
            "found.\n")


def _defects() -> str:
    """The table of known defects (qpbench/solvers/defects.toml), with whether each applies to
    the versions installed here."""
    rows = [{"solver": f"{d.solver}/{d.formulation}", "package": d.package,
             "versions": d.versions, "installed": d.installed_version() or "-",
             "applies here": "yes" if d.applies_here() else "no", "problems": d.problems,
             "effect": d.effect, "what goes wrong": d.what}
            for d in defect_table.defects()]
    return ("Data, not code: `qpbench/solvers/defects.toml`, which the tests read too. A row "
            "whose version range excludes the installed version no longer applies.\n\n"
            + markdown_table(pd.DataFrame(rows), {key: str for key in rows[0]} if rows else {}))


def extra_sections(folders: Iterable[Path]) -> list[tuple[str, str]]:
    """Collect the sections other parts of qpbench left as JSON files in ``folders``.

    Every ``*.json`` with a ``"markdown"`` key gives one section; its title is its ``title``,
    else the Markdown's own heading, else the file's name. Unreadable files are skipped.

    Parameters
    ----------
    folders : iterable of pathlib.Path
        The folders to search, each file read once.

    Returns
    -------
    list of tuple of (str, str)
        (title, markdown) of each section, by folder then file name.
    """
    found: list[tuple[str, str]] = []
    seen: set[Path] = set()
    for folder in folders:
        for path in sorted(folder.glob("*.json")):
            if path.resolve() in seen:
                continue
            seen.add(path.resolve())
            try:
                content = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError, RecursionError):
                continue
            if isinstance(content, dict) and isinstance(content.get("markdown"), str):
                title = str(content.get("title") or path.stem.replace("_", " ").capitalize())
                body = content["markdown"].strip()
                if body.startswith("#"):  # the section brings its own heading
                    heading, _, body = body.partition("\n")
                    title = heading.lstrip("#").strip()
                found.append((title, body.strip() + "\n"))
    return found


SIM_PRECISION_FILE = "sim_precision.json"


def sim_precision_report(folders: Iterable[Path]) -> dict[str, Any] | None:
    """Read the first ``sim_precision.json`` (``qpbench sim-precision``) in ``folders``.

    Parameters
    ----------
    folders : iterable of pathlib.Path
        The folders to search, in order.

    Returns
    -------
    dict of str to Any or None
        The report; None when there is none or it is not one.
    """
    for folder in folders:
        try:
            content = json.loads((folder / SIM_PRECISION_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            continue
        if isinstance(content, dict) and isinstance(content.get("rows"), list):
            return content
    return None


def sim_precision_figure(report: dict[str, Any], out: Path) -> str | None:
    """Draw ``report``'s work-precision figure into ``out/figures``.

    Parameters
    ----------
    report : dict of str to Any
        The report of :func:`qpbench.bench.sim_precision.sim_precision`.
    out : pathlib.Path
        The report's folder.

    Returns
    -------
    str or None
        A Markdown image line to follow its section; None when there is nothing to draw.
    """
    if sim_precision.figure(report, out / "figures" / "sim_precision.png") is None:
        return None
    return ("\n![Final-state error against the inner solves' total time, per pair and "
            "level](figures/sim_precision.png)\n")


FUZZ_FILE = "fuzz.json"
FUZZ_PASSING = ("ok", "solve-failed", "input-error")


def fuzz_section(folders: Iterable[Path]) -> str | None:
    """Summarise the first ``fuzz.json`` (written by ``qpbench fuzz``) in ``folders``.

    Cases, failures and outcomes per kind, the attributes covered and the first failures.

    Parameters
    ----------
    folders : iterable of pathlib.Path
        The folders to search, in order.

    Returns
    -------
    str or None
        The section's Markdown; None when there is none or it is not a fuzz report.
    """
    for folder in folders:
        try:
            content = json.loads((folder / FUZZ_FILE).read_text(encoding="utf-8"))
            kinds = {kind: content["kinds"][kind] for kind in ("scene", "problem")}
            outcomes = sorted({outcome for counts in kinds.values()
                               for outcome in counts["outcomes"]},
                              key=lambda outcome: (outcome not in FUZZ_PASSING, outcome))
        except (OSError, ValueError, RecursionError, KeyError, TypeError, AttributeError):
            continue
        verdict = ("every case passed" if content.get("passed") else
                   f"**{content.get('failed')} cases failed**")
        lines = [f"`qpbench fuzz` (seed {content.get('seed')}, {content.get('steps')} steps "
                 f"per scene, {content.get('time_limit_s')} s and "
                 f"{content.get('memory_limit_mb')} MiB per case): {verdict}. Passing: exit 0, "
                 "or exit 1/2 with one `qpbench ...` line on stderr.", "",
                 "| kind | cases | failed | " + " | ".join(outcomes) + " |",
                 "|---|---:|---:|" + "---:|" * len(outcomes)]
        for kind, counts in kinds.items():
            lines.append(f"| {kind} | {counts.get('cases')} | {counts.get('failed')} | "
                         + " | ".join(str(counts["outcomes"].get(outcome, 0))
                                      for outcome in outcomes) + " |")
        for dialect, covered in (content.get("coverage") or {}).items():
            lines.append(f"\n{dialect}: {covered.get('touched')} of {covered.get('known')} "
                         "attributes qpbench reads set to bad values or deleted.")
        failures = (content.get("failures") or [])[:5]
        lines.extend(["", "First failures:", ""] if failures else [])
        for failure in failures:
            lines.append(f"- {failure.get('kind')} case {failure.get('case')}: "
                         f"{failure.get('outcome')} (`{' '.join(failure.get('command') or [])}`)")
        return "\n".join(lines) + "\n"
    return None


SUMMARY_SUCCESS = 0.95


# --- the report -----------------------------------------------------------------------------
def _frictionless(frame: pd.DataFrame, folder: Path, budget_s: float | None,
                  sections: Sequence[SummarySection] = ()) -> tuple[list[str], list[str]]:
    """(summary sections, the rest) of the frictionless rows (cold starts where there are);
    ``sections`` close the rest."""
    figures = folder / "figures"
    main = frame[frame["mode"].astype(str) == "cold"]
    if main.empty:
        main = frame
    shift = stats.time_scale_shift(main)
    budget = budget_s if budget_s is not None else shift
    summary = stats.level_summary(main, shift)
    top = ["\n## Summary\n\n" + _summary(summary) + f"\n{TIME_S_COVERS} Solvers marked "
           "`ours` are written here and stop on qpbench's own residual.\n"]
    out: list[str] = []
    out.append("\n## Per accuracy level (cold starts)\n\n" + _levels(summary, shift))
    out.append("\n" + _image(plots.success_by_level(summary, figures / "success_by_level.png"),
                             folder, "success rate by level"))
    out.append("\n## Success by family\n" + _families(main))
    out.append("\n## Formulations side by side\n" + _formulations(summary))

    out.append("\n## Work-precision diagrams\n\nEach curve is one solver/formulation; each "
               "point one accuracy level at (median solver time, median v_error) over the "
               "family's problems that returned an answer (v_error below 1e-17 is drawn at "
               "1e-17; failed solves have no point, see the tables).\n")
    for family in sorted(main["family"].dropna().astype(str).unique()):
        path = plots.work_precision(main[main["family"] == family], family,
                                    figures / f"work_precision_{plots.slug(family)}.png")
        out.append(f"\n### Family {family}\n\n" + _image(path, folder, f"work-precision {family}"))

    out.append("\n## Performance profiles\n\nDolan-More: the share of problems each "
               "solver/formulation solves within tau times the fastest time on that problem "
               "(failures never count).\n")
    for accuracy in PROFILE_LEVELS:
        at_level = main[np.isclose(main["accuracy"].astype(float), accuracy)]
        if at_level.empty:
            out.append(f"\n_(no solves at accuracy {level(accuracy)})_\n")
            continue
        path = plots.profile(at_level, accuracy, figures / f"profile_{level(accuracy)}.png")
        out.append(f"\n### Accuracy {level(accuracy)}\n\n"
                   + _image(path, folder, f"profile {level(accuracy)}"))

    cost = stats.cost_of_accuracy(main, shift)
    reliable = _most_reliable(summary)
    out.append("\n## Time at each level, the most reliable pairs\n\nSGM time at each level "
               "and the ratio from each level to the next tighter one (a ratio of 2 means the "
               f"tighter level takes twice as long), for the {TOP_ROWS} most reliable pairs at "
               "the tightest level.\n\n"
               + markdown_table(cost.loc[[k for k in reliable if k in cost.index]]
                                .reset_index().rename(columns={"index": "solver"}))
               + _more(len(cost)) if not cost.empty else "")
    paired = stats.paired_cost_of_accuracy(main)
    out.append("\nThe same step measured only on problems solved at both levels (median over "
               "those problems of the time ratio), so that failures charged the time limit do "
               "not make a looser level look slower:\n\n"
               + markdown_table(paired.loc[[k for k in reliable if k in paired.index]]
                                .reset_index()) + _more(len(paired)))
    tightest = float(main["accuracy"].min())
    out.append("\n" + _image(plots.time_by_size(
        main[np.isclose(main["accuracy"].astype(float), tightest)], tightest,
        figures / "time_by_size.png"), folder, "time by size"))
    within = stats.accuracy_within_budget(main, budget)
    out.append(f"\nWithin a budget of {budget:.3g} s per solve (the SGM shift unless set with "
               "--budget): the tightest level solved on at least 90% of problems, and the "
               "median over problems of the best v_error reached.\n\n"
               + markdown_table(within, {"tightest_level": _maybe_level}))
    out.append(_warm_cold(frame, shift))
    out.extend(f"\n## {title}\n\n" + section(main, shift) for title, section in sections)
    return top, out


def _most_reliable(summary: pd.DataFrame) -> list[str]:
    """The TOP_ROWS pairs with the highest success rate (then the lowest SGM time) at the
    tightest level."""
    tightest = summary[summary["accuracy"] == summary["accuracy"].min()]
    ranked = tightest.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True])
    return list(ranked["solver"].head(TOP_ROWS))


def write_report(results: str | os.PathLike[str], folder: str | os.PathLike[str] | None = None,
                 budget_s: float | None = None, sections: Sequence[SummarySection] = ()
                 ) -> Path:
    """Write ``folder/REPORT.md``, its PNG figures and ``index.html``.

    Frictionless and frictional rows are reported apart (a table of either alone works);
    ``sections`` (title, its Markdown from the cold frictionless rows and the SGM shift) close
    the frictionless part, after the comparison of every pair, as the studies of our own
    solver bring theirs (``qpbench.studies.targets``).

    Parameters
    ----------
    results : str or os.PathLike
        The results table (its part files are read too).
    folder : str or os.PathLike, optional
        The report's folder, created when missing; None: the results' folder.
    budget_s : float, optional
        The time budget per solve of the accuracy-within-budget table; None: the SGM shift.
    sections : sequence of SummarySection, optional
        Sections the caller brings; none by default.

    Returns
    -------
    pathlib.Path
        The path of REPORT.md.

    Raises
    ------
    InputError
        When the results table does not exist, cannot be read or has no rows.
    """
    results = Path(results)
    if not results.exists() and not ResultStore(results).part_files():
        raise InputError(str(results), "no such results file")
    everything = ResultStore(results).read()
    if everything.empty:
        raise InputError(str(results), "the results table has no rows")
    folder = Path(folder) if folder is not None else results.parent
    folder.mkdir(parents=True, exist_ok=True)
    # cells double precision cannot decide are charged to no solver (see run.judge)
    frame, frictional = (stats.without_below_floor(rows) for rows in split_kinds(everything))
    top, rest = _frictionless(frame, folder, budget_s, sections) if not frame.empty else (
        ["\n_No frictionless problems in these results._\n"], [])

    simulations = sim_precision_report(dict.fromkeys([results.parent, folder]))
    html_report.write_html(everything, folder, results.name, simulations)
    out: list[str] = ["# qpbench report\n\n", INDEX_POINTER, _overview(everything, results),
                      _lead(frame, frictional, folder), *top]
    out.append("\n## Machine and versions\n\n" + _provenance(everything))
    imported = imported_problems.describe_imported(everything)
    if not imported.empty:
        out.append(f"\n## {imported_problems.TITLE}\n\n{imported_problems.INTRO}\n\n"
                   + markdown_table(imported, {column: str for column in imported.columns})
                   + imported_problems.note(imported))
    out.extend(rest)
    out.append("\n## Friction\n\n" + _friction(frictional, folder))
    out.append("\n## Status honesty\n\nHow often a solver's own success claim agrees with "
               "qpbench's verdict (solves that returned an answer or a status). Solvers marked "
               "`ours` stop on qpbench's own residual, so theirs is 100% by construction.\n\n"
               + _honesty(everything))
    out.append("\n## Known solver defects\n\n" + _defects())
    options = pd.DataFrame(accuracy_table.table_rows())
    out.append("\n## Accuracy options\n\nHow each solver's own options follow from the level eps "
               "(scale = max(||b||_inf, tiny)).\n\n"
               + markdown_table(options, {c: str for c in options.columns}))
    for title, markdown in extra_sections(dict.fromkeys([results.parent, folder])):
        out.append(f"\n## {title}\n\n{markdown}")
    precision = None if simulations is None else sim_precision_figure(simulations, folder)
    if precision is not None:
        out.append(precision)
    fuzzing = fuzz_section(dict.fromkeys([results.parent, folder]))
    if fuzzing is not None:
        out.append(f"\n## Fuzzing\n\n{fuzzing}")

    report = folder / "REPORT.md"
    with atomic_path(report) as temporary:
        temporary.write_text("".join(out), encoding="utf-8")
    return report
