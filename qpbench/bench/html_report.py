"""``index.html``: one self-contained page of a results table, beside REPORT.md.

The comparison first: per family and accuracy level the fastest pair of each formulation
and the fastest external pair beside the fastest of ours; what each further digit costs the
pairs whose time grows with the level (a table and a chart); what each wrapper adds to a
native pair. Then per family the fastest pair overall at each level (and how much each
further digit multiplies its time), interactive
work-precision diagrams, performance profiles, a sortable and filterable table aggregated per
pair x family x level, a per-problem view, the frictional problems apart, and provenance.

The page works offline from the file system: Plotly's script is embedded once, the data is
embedded as JSON, and the page fetches nothing.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from qpbench.atomic import atomic_path
from qpbench.bench import below_floor, imported_problems, sim_precision, stats
from qpbench.bench.html_assets import SCRIPT, STYLE, TEMPLATE
from qpbench.bench.results import split_kinds
from qpbench.solvers.run import NO_SOLUTION

FRONTIER_SUCCESS = stats.SOLVES_SHARE  # a pair "reaches" a level: solves this share of them
PROFILE_LEVELS = (1e-4, 1e-8)
ALL = stats.ALL_PROBLEMS
FRICTIONAL = "frictional"
ERROR_FLOOR = 1e-17
PROFILE_VISIBLE = 10  # profile curves drawn at first; the rest wait in the legend


# --- small helpers -----------------------------------------------------------------------------
def _finite(value: Any, digits: int = 4) -> float | None:
    """``value`` rounded to ``digits`` significant digits; None for NaN, inf or missing."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(number):
        return None
    return float(f"{number:.{digits}g}")


def _text(value: Any) -> str:
    return html.escape(str(value))


def _seconds(value: Any) -> str:
    number = _finite(value, 3)
    return "-" if number is None else f"{number:.3g} s"


def _percent(value: Any) -> str:
    number = _finite(value)
    return "-" if number is None else f"{100 * number:.1f}%"


def _level(value: float) -> str:
    return f"{float(value):.0e}"


def _table(header: list[str], rows: list[list[str]], css: str = "") -> str:
    """An HTML table whose cells are already escaped HTML."""
    if not rows:
        return "<p class='none'>(no rows)</p>"
    head = "".join(f"<th>{cell}</th>" for cell in header)
    body = "".join("<tr>" + "".join(f"<td>{cell}</td>" for cell in row) + "</tr>"
                   for row in rows)
    return (f"<table class='static {css}'><thead><tr>{head}</tr></thead>"
            f"<tbody>{body}</tbody></table>")


def _strings(frame: pd.DataFrame, column: str) -> pd.Series:
    if column not in frame:
        return pd.Series("", index=frame.index, dtype=object)
    return frame[column].astype("string").fillna("").astype(str)


# --- the data the page's scripts draw ----------------------------------------------------------
def dataset(frame: pd.DataFrame, error_column: str = "v_error") -> dict[str, Any]:
    """Lay out the solves of ``frame`` column by column for the page's scripts.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    error_column : str, optional
        The column drawn as the error against time; ``v_error`` by default (NaN where
        ``frame`` lacks it).

    Returns
    -------
    dict of str to Any
        Lookup tables ``levels`` (loosest first), ``pairs`` and ``problems``; ``error`` (the
        column's name); and per solve the ``pair``, ``problem`` and ``level`` indices,
        ``time``, ``residual``, ``v_error`` (the error column) and ``success`` (0 or 1).
    """
    levels = sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True)
    keys = stats.solver_keys(frame)
    pair_frame = (frame.assign(key=keys, backend=_strings(frame, "backend"))
                  .groupby("key", sort=True)
                  .agg(solver=("solver", "first"), formulation=("formulation", "first"),
                       backend=("backend", "first")))
    ours = set(keys[_strings(frame, "backend") == stats.OWN_BACKEND])
    pairs = [{"key": key, "solver": str(row.solver), "formulation": str(row.formulation),
              "backend": str(row.backend), "ours": key in ours}
             for key, row in pair_frame.iterrows()]
    problem_frame = (frame.assign(family=_strings(frame, "family"))
                     .groupby("problem", sort=True)
                     .agg(family=("family", "first"), contacts=("contacts", "first")))
    problems = [{"name": str(name), "family": str(row.family),
                 "contacts": _finite(row.contacts)} for name, row in problem_frame.iterrows()]
    pair_index = {pair["key"]: i for i, pair in enumerate(pairs)}
    problem_index = {problem["name"]: i for i, problem in enumerate(problems)}
    level_index = {level: i for i, level in enumerate(levels)}
    error = frame[error_column] if error_column in frame else pd.Series(np.nan, frame.index)
    return {
        "levels": levels,
        "pairs": pairs,
        "problems": problems,
        "error": error_column,
        "pair": [pair_index[key] for key in keys],
        "problem": [problem_index[str(name)] for name in frame["problem"]],
        "level": [level_index.get(float(a), 0) for a in frame["accuracy"]],
        "time": [_finite(v) for v in frame["time_s"]],
        "residual": [_finite(v) for v in frame["residual"]],
        "v_error": [_finite(v) for v in error],
        "success": [1 if bool(v) else 0 for v in frame["success"].fillna(False)],
    }


def summaries(frame: pd.DataFrame) -> list[tuple[str, float, pd.DataFrame]]:
    """Summarise all problems, then each family, each with its own SGM shift.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    list of tuple of (str, float, pandas.DataFrame)
        (family or ALL, its SGM shift, :func:`level_summary`), ALL first, families by name.
    """
    family = _strings(frame, "family")
    groups = [(ALL, frame)] + [(name, frame[family == name])
                               for name in sorted(family.unique()) if name]
    found = []
    for name, group in groups:
        shift = stats.time_scale_shift(group)
        found.append((name, shift, level_summary(group, shift)))
    return found


def level_summary(frame: pd.DataFrame, shift: float) -> pd.DataFrame:
    """Compute the columns of stats.level_summary the page uses, by one vectorised group-by.

    The columns are accuracy, solver, solves, success_rate, sgm_time_s and median_residual:
    the same numbers as :func:`qpbench.bench.stats.level_summary`, fast enough for every family
    of a full run.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    shift : float
        The shift of the SGM in seconds.

    Returns
    -------
    pandas.DataFrame
        One row per (accuracy, pair), sorted.
    """
    success = frame["success"].fillna(False).astype(bool)
    work = pd.DataFrame({
        "accuracy": frame["accuracy"].astype(float), "solver": stats.solver_keys(frame),
        "success": success.astype(float),
        "log": np.log(stats.charged_times(frame).astype(float) + shift),
        "residual": frame["residual"].astype(float)})
    grouped = work.groupby(["accuracy", "solver"], sort=True)
    summary = grouped.agg(solves=("success", "size"), success_rate=("success", "mean"),
                          log=("log", "mean"), median_residual=("residual", "median"))
    summary["sgm_time_s"] = np.exp(summary.pop("log")) - shift
    return summary.reset_index()


def frontier(frame: pd.DataFrame,
             summarised: list[tuple[str, float, pd.DataFrame]] | None = None
             ) -> list[dict[str, Any]]:
    """Find per family and level the fastest pair among those that solve the family.

    Per family (and all problems) and level, loosest first: the pair with the lowest SGM
    time (the family's own shift, failures charged the limit) among those solving at least
    FRONTIER_SUCCESS of the family's problems, and the factor each further digit multiplies
    the time by from the previous level's pair.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    summarised : list of tuple of (str, float, pandas.DataFrame), optional
        :func:`summaries` of ``frame``; None computes it.

    Returns
    -------
    list of dict
        Per (family, level): family, level, qualified, pairs, shift, pair, time, success,
        per_digit (``pair`` and the rest None when no pair qualifies).
    """
    rows = []
    for family, shift, summary in summarised or summaries(frame):
        previous: tuple[float, float] | None = None
        for accuracy in sorted(summary["accuracy"].unique(), reverse=True):
            at_level = summary[summary["accuracy"] == accuracy]
            qualified = at_level[at_level["success_rate"] >= FRONTIER_SUCCESS]
            row: dict[str, Any] = {"family": family, "level": float(accuracy),
                                   "qualified": len(qualified), "pairs": len(at_level),
                                   "shift": shift}
            if qualified.empty:
                row.update(pair=None, time=None, success=None, per_digit=None)
                previous = None
            else:
                best = qualified.sort_values(["sgm_time_s", "solver"]).iloc[0]
                time = float(best["sgm_time_s"])
                per_digit = None
                if previous is not None and previous[1] > 0:
                    digits = math.log10(previous[0] / float(accuracy))
                    if digits > 0:
                        per_digit = (time / previous[1]) ** (1.0 / digits)
                row.update(pair=str(best["solver"]), time=time,
                           success=float(best["success_rate"]), per_digit=per_digit)
                previous = (float(accuracy), time)
            rows.append(row)
    return rows


def aggregate(frame: pd.DataFrame,
              summarised: list[tuple[str, float, pd.DataFrame]] | None = None
              ) -> list[list[Any]]:
    """Build the rows of the page's table: per family (and all problems) x pair x level.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.
    summarised : list of tuple of (str, float, pandas.DataFrame), optional
        :func:`summaries` of ``frame``; None computes it.

    Returns
    -------
    list of list
        Per row: family, pair, formulation, backend, level, solves, success rate, SGM time,
        median residual.
    """
    backends = (frame.assign(key=stats.solver_keys(frame), b=_strings(frame, "backend"))
                .groupby("key")["b"].first())
    rows = []
    for family, _shift, summary in summarised or summaries(frame):
        for item in summary.itertuples(index=False):
            formulation = str(item.solver).split("/", 1)[1]
            rows.append([family, item.solver, formulation, backends.get(item.solver, ""),
                         float(item.accuracy), int(item.solves), _finite(item.success_rate),
                         _finite(item.sgm_time_s), _finite(item.median_residual)])
    return rows


def profiles(frame: pd.DataFrame) -> list[dict[str, Any]]:
    """Compute the Dolan-More profiles at PROFILE_LEVELS for the page's charts.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    list of dict
        Per level with solves: level, problems, taus and per pair (largest area first) the
        share solved within tau, the first PROFILE_VISIBLE marked visible.
    """
    found = []
    for accuracy in PROFILE_LEVELS:
        at_level = frame[np.isclose(frame["accuracy"].astype(float), accuracy)]
        if at_level.empty:
            continue
        curves = stats.performance_profile(at_level)
        if curves.shape[1] == 0:
            continue
        ranked = curves.mean().sort_values(ascending=False)
        found.append({
            "level": accuracy,
            "problems": int(stats.performance_ratios(at_level).shape[0]),
            "taus": [_finite(t) for t in curves.index],
            "curves": [{"key": key, "values": [round(float(v), 4) for v in curves[key]],
                        "visible": rank < PROFILE_VISIBLE}
                       for rank, key in enumerate(ranked.index)],
        })
    return found


def provenance(frame: pd.DataFrame) -> list[tuple[str, str]]:
    """Collect the machine and version items from the rows' provenance columns.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows.

    Returns
    -------
    list of tuple of (str, str)
        (item, value) pairs: qpbench, lock, Python, NumPy, platform, CPU, hosts, dates, time
        limit, backends and versions ('-' where none).
    """
    def values(column: str) -> str:
        found = sorted(set(_strings(frame, column)) - {""})
        return ", ".join(found) if found else "-"

    dates = _strings(frame, "date")
    dates = dates[dates != ""]
    versions = (frame.assign(key=stats.solver_keys(frame),
                             v=_strings(frame, "solver_version"), b=_strings(frame, "backend"))
                .groupby("key")[["b", "v"]].first())
    packages = sorted({f"{b} {v}" for b, v in zip(versions["b"], versions["v"], strict=True)
                       if b or v})
    return [
        ("qpbench", values("qpbench_version")),
        ("package lock (requirements.lock, SHA-256)", values("lock_hash")),
        ("Python", values("python_version")),
        ("NumPy", values("numpy_version")),
        ("platform", values("platform")),
        ("CPU", values("cpu_model")),
        ("hosts", values("hostname")),
        ("dates (UTC)", f"{dates.min()} .. {dates.max()}" if len(dates) else "-"),
        ("time limit per solve [s]", values("time_limit_s")),
        ("backends and versions", "; ".join(packages) if packages else "-"),
    ]


# --- sections ----------------------------------------------------------------------------------
def _frontier_html(rows: list[dict[str, Any]]) -> str:
    levels = sorted({row["level"] for row in rows}, reverse=True)
    families = list(dict.fromkeys(row["family"] for row in rows))
    cell = {(row["family"], row["level"]): row for row in rows}
    body = []
    for family in families:
        cells = [f"<th>{_text(family)}</th>"]
        for accuracy in levels:
            row = cell.get((family, accuracy))
            if row is None:
                cells.append("<td>-</td>")
            elif row["pair"] is None:
                cells.append(f"<td class='none'>none of {row['pairs']}</td>")
            else:
                digit = (f"<span class='digit'>x{row['per_digit']:.2g} per digit</span>"
                         if row["per_digit"] is not None else "")
                cells.append(f"<td><code>{_text(row['pair'])}</code>"
                             f"<span class='time'>{_seconds(row['time'])}</span>{digit}"
                             f"<span class='small'>{_percent(row['success'])} solved, "
                             f"{row['qualified']} of {row['pairs']} pairs qualify</span></td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    head = "<th>family</th>" + "".join(f"<th>{_level(a)}</th>" for a in levels)
    return (f"<table id='frontier' class='static frontier'><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")


def _comparison_html(frame: pd.DataFrame, summarised: list[tuple[str, float, pd.DataFrame]],
                     caption: str) -> str:
    """Per level (loosest first) a table with a row per family: the fastest pair of each
    formulation that solves the family at the level (the fastest of the row marked ``best``),
    the fastest external pair, the fastest of ours and how many times faster ours is
    (stats.fastest_pairs)."""
    fastest = stats.fastest_pairs(summarised, stats.pair_backends(frame))
    cells = {(row.family, row.level, row.column): row
             for row in fastest.itertuples(index=False)}
    formulations = stats.formulations_in_order(frame)
    head = "".join(f"<th>{_text(name)}</th>" for name in
                   ("family", *formulations, "fastest external", "fastest of ours",
                    "external / ours"))
    parts = []
    for accuracy in sorted({float(a) for a in frame["accuracy"].dropna()}, reverse=True):
        body = []
        for family, _shift, _summary in summarised:
            found = {column: cells.get((family, accuracy, column))
                     for column in (*formulations, stats.EXTERNAL, stats.OURS)}
            times = [found[name].sgm_time_s for name in formulations if found[name] is not None]
            row = [f"<th>{_text(family)}</th>"]
            for column in (*formulations, stats.EXTERNAL, stats.OURS):
                item = found[column]
                if item is None:
                    row.append(f"<td class='none' data-column='{_text(column)}'>-</td>")
                    continue
                best = column in formulations and item.sgm_time_s == min(times)
                name = item.pair if column in (stats.EXTERNAL, stats.OURS) \
                    else item.pair.split("/", 1)[0]
                css = " class='best'" if best else ""
                row.append(f"<td{css} data-column='{_text(column)}' data-pair='{_text(item.pair)}'>"
                           f"<code>{_text(name)}</code> "
                           f"<span class='time'>{_seconds(item.sgm_time_s)}</span></td>")
            external, ours = found[stats.EXTERNAL], found[stats.OURS]
            ratio = (f"{external.sgm_time_s / ours.sgm_time_s:.3g}"
                     if external is not None and ours is not None and ours.sgm_time_s > 0
                     else "-")
            body.append("<tr>" + "".join(row) + f"<td class='num'>{ratio}</td></tr>")
        parts.append(f"<h3>{_text(caption)}{_level(accuracy)}</h3><div class='scroll'>"
                     f"<table class='static comparison' data-level='{_level(accuracy)}'>"
                     f"<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
                     "</div>")
    return "".join(parts)


def _accuracy_cost_html(frame: pd.DataFrame) -> tuple[str, dict[str, Any] | None]:
    """(a table of the pairs whose time grows with the level, stats.iterative_pairs: the growth
    from the loosest level and per family the factor each further digit multiplies the time
    by; the chart's data: each pair's time relative to the loosest level, or None)."""
    pairs = stats.iterative_pairs(frame)
    if not pairs:
        return ("<p class='none'>No pair's time grows by "
                f"{stats.ITERATIVE_GROWTH:g} x or more with the level here.</p>", None)
    growth = stats.time_growth(frame)
    per_digit = stats.time_per_digit(frame, pairs)
    relative = stats.relative_time(frame, pairs)
    levels = [float(a) for a in relative.columns]
    rows = [[f"<code>{_text(key)}</code>", f"{growth[key]:.3g}",
             *(f"{value:.3g}" if _finite(value) is not None else "-"
               for value in per_digit.loc[key])] for key in pairs]
    table = _table(["pair", f"time at the tighter level / at {_level(levels[0])}",
                    *(f"per digit, {_text(family)}" for family in per_digit.columns)], rows,
                   "accuracy-cost")
    chart = {"levels": levels,
             "pairs": [{"key": key, "relative": [_finite(value) for value in values]}
                       for key, values in relative.iterrows()]}
    return f"<div class='scroll'>{table}</div>", chart


def _wrapper_html(frame: pd.DataFrame) -> str:
    """Per native pair and each of its wrapper twins: the share each solved and the median
    time ratio on the cells both solved (stats.wrapper_costs)."""
    table = stats.wrapper_costs(frame)
    rows = [[f"<code>{_text(row.native)}</code>", _text(row.wrapper),
             f"<code>{_text(row.twin)}</code>", str(row.cells),
             _percent(row.native_success_rate), _percent(row.twin_success_rate),
             str(row.both_solved), "-" if _finite(row.time_ratio) is None
             else f"{row.time_ratio:.3g}"] for row in table.itertuples(index=False)]
    if not rows:
        return ("<p class='none'>No native pairs (<code>&lt;solver&gt;-native</code>) with a "
                "twin in these results.</p>")
    return _table(["native pair", "wrapper", "twin pair", "cells both ran", "native solved",
                   "twin solved", "cells both solved", "twin time / native time"], rows,
                  "wrappers")


def _lead_html(main: pd.DataFrame, summarised: list[tuple[str, float, pd.DataFrame]] | None,
               frictional: pd.DataFrame, data: dict[str, Any]) -> list[str]:
    """The page's opening sections: the comparison, what accuracy costs where it costs (its
    chart's data into ``data["accuracy_cost"]``) and the wrapper costs."""
    solvable = stats.without_unsolvable(frictional) if not frictional.empty else frictional
    comparison = ["<section id='comparison'><h2>Fastest pairs, per family and level</h2>"
                  "<p>Among the pairs that solve a family at a level (at least "
                  f"{stats.SOLVES_SHARE:.0%} of its problems; success = qpbench's residual "
                  "&lt;= the level): the fastest pair of each formulation (solver named; the "
                  "fastest of the row highlighted), the fastest external pair (a backend not "
                  "written here), the fastest of ours, and how many times faster ours is. Time "
                  "= shifted geometric mean of time_s over the family's problems with the "
                  "family's own shift, failures charged the time limit; - : no pair solves. "
                  "Frictional problems without a solution are left out, and so are the cells "
                  "below a problem's double-precision floor (<code>below-floor</code>).</p>"]
    cost = ["<section id='accuracy-cost'><h2>What accuracy costs, where it costs</h2>"
            f"<p>The pairs whose time at {_level(stats.GROWTH_LEVEL)} (or the tightest level) is "
            f"at least {stats.ITERATIVE_GROWTH:g} x their time at the loosest level (geometric "
            "mean over the problems each solves at both), steepest first; per family the factor "
            "each further digit multiplies the time by (geometric mean over the family's "
            "problems solved at two consecutive levels a &gt; b of "
            "(t_b / t_a)^(1 / log10(a / b))). The chart chains those steps over all problems: "
            "each pair's time relative to the loosest level.</p>"]
    if summarised is not None:
        comparison.append(_comparison_html(main, summarised, "Accuracy "))
        if main["accuracy"].nunique() > 1:
            table, data["accuracy_cost"] = _accuracy_cost_html(main)
            cost.append(table + ("<div id='accuracy-cost-plot' class='plot'></div>"
                                 if data["accuracy_cost"] else ""))
    if not solvable.empty:
        comparison.append(_comparison_html(solvable, summaries(solvable),
                                           "Frictional problems, accuracy "))
        if solvable["accuracy"].nunique() > 1:
            cost.append("<h3>Frictional problems</h3>" + _accuracy_cost_html(solvable)[0])
    wrappers = ("<section id='wrappers'><h2>Wrapper costs</h2><p>Each native pair "
                "(<code>&lt;solver&gt;-native</code>: the backend through its own Python API) "
                "against the same solver on the same formulation through qpsolvers and through "
                "cvxpy, on the cells both ran: the share each solved and the median over the "
                "cells both solved of the twin's time over the native pair's (above 1 the "
                "wrapper is slower).</p>" + _wrapper_html(main) + "</section>")
    return ["".join(comparison) + "</section>", "".join(cost) + "</section>", wrappers]


def _friction_html(frame: pd.DataFrame) -> str:
    """Static tables of the frictional rows: per level and formulation the best pair, and the
    model error of ccp."""
    unsolvable = frame["status"].astype(str) == NO_SOLUTION
    parts = [f"<p>{frame['problem'].nunique()} frictional problems "
             f"({_text(', '.join(sorted(set(_strings(frame, 'family')) - {''})))}), "
             f"{frame.loc[unsolvable, 'problem'].nunique()} of them without a solution "
             "(counted apart). <code>ccp</code> answers are judged by the relaxed model's own "
             "residual; their Coulomb residual is the model error.</p>"]
    frame = frame[~unsolvable]
    if frame.empty:
        return "".join(parts)
    summary = level_summary(frame, stats.time_scale_shift(frame))
    summary = summary.assign(formulation=summary["solver"].str.split("/", n=1).str[1])
    rows = []
    for (accuracy, formulation), group in sorted(summary.groupby(["accuracy", "formulation"]),
                                                 key=lambda item: (-item[0][0], item[0][1])):
        best = group.sort_values(["success_rate", "sgm_time_s"], ascending=[False, True]).iloc[0]
        rows.append([_level(accuracy), _text(formulation), str(len(group)),
                     f"<code>{_text(best['solver'])}</code>", _percent(best["success_rate"]),
                     _seconds(best["sgm_time_s"])])
    parts.append("<h3>Formulations at each level</h3>" + _table(
        ["level", "formulation", "pairs", "best pair", "solved by it", "its SGM time"], rows))
    ccp = frame[_strings(frame, "formulation") == "ccp"]
    if not ccp.empty and "model_error" in ccp:
        solved = ccp[ccp["success"].fillna(False).astype(bool)]
        errors = solved.groupby(_strings(solved, "family"))["model_error"]
        rows = [[_text(family), f"{_finite(median, 3)}", f"{_finite(largest, 3)}"]
                for (family, median), largest in zip(errors.median().items(), errors.max(),
                                                     strict=True)]
        parts.append("<h3>Model error of <code>ccp</code> (Coulomb residual of its solved "
                     "answers)</h3>" + _table(["family", "median", "max"], rows))
    parts.append("<h3>Work-precision (frictional)</h3><div class='controls'>"
                 "<label>family <select id='fwp-family'></select></label></div>"
                 "<div id='fwp' class='plot'></div>")
    return "".join(parts)


def _simulations_html(report: dict[str, Any]) -> str:
    """What accuracy costs a whole simulation (``qpbench sim-precision``): per kind of scene,
    each pair's summed times and errors per level, and per scene the loosest level whose final
    state stays within ``sim_precision.WITHIN`` of the reference."""
    parts = ["<section id='simulations'><h2>What accuracy costs a whole simulation</h2>"
             f"<p>Each scene simulated for {_text(report['steps'])} steps with each pair at "
             "each level; <code>state_error</code> is the final state's relative distance "
             "(mass norm) from a reference run at the tightest level. The figure is in "
             "<a href='REPORT.md'>REPORT.md</a>.</p>"]
    tightest = min(report["levels"])
    for kind in (sim_precision.FRICTIONLESS, sim_precision.FRICTIONAL):
        summary = sim_precision.pair_summary(report["rows"], kind)
        if not summary:
            continue
        parts.append(f"<h3>{_text(kind.capitalize())} scenes</h3>")
        parts.append(_table(
            ["solver", "level", "solve time", "wall time", "largest error", "median error",
             "within", "failed runs"],
            [[_text(item["solver"]), _level(item["accuracy"]),
              _seconds(item["solve_time_s"]), _seconds(item["wall_s"]),
              _text(_finite(item["max_state_error"], 2)),
              _text(_finite(item["median_state_error"], 2)),
              f"{item['within']}/{item['runs']}", _text(item["failed"])] for item in summary]))
        solvers, grid = sim_precision.loosest_grid(report, kind)
        if solvers:
            caption = sim_precision.LOOSEST_CAPTION.format(within=sim_precision.WITHIN,
                                                           tightest=tightest)
            parts.append(f"<p>{_text(caption)}.</p>")
            parts.append(_table(["scene", *map(_text, solvers)],
                                [[_text(scene), *map(_text, cells)] for scene, cells in grid]))
    parts.append("</section>")
    return "".join(parts)


def page(everything: pd.DataFrame, source: str, plotly_js: str,
         simulations: dict[str, Any] | None = None) -> str:
    """Build the HTML of the page for ``everything`` (frictionless and frictional rows).

    Parameters
    ----------
    everything : pandas.DataFrame
        Results rows of every kind.
    source : str
        The results table's name, shown in the summary.
    plotly_js : str
        Plotly's script, embedded in the page.
    simulations : dict of str to Any, optional
        The whole-simulation measurement (``qpbench sim-precision``'s JSON); None leaves its
        section out.

    Returns
    -------
    str
        The page's HTML.
    """
    frictionless, answered_frictional = split_kinds(everything)
    answered = frictionless[_strings(frictionless, "mode") == "cold"]
    if answered.empty:
        answered = frictionless
    # cells double precision cannot decide are charged to no solver (see run.judge); the
    # scatter plots still draw their answers
    main = stats.without_below_floor(answered)
    frictional = stats.without_below_floor(answered_frictional)
    data: dict[str, Any] = {"main": None, "friction": None, "accuracy_cost": None}
    summarised = summaries(main) if not main.empty else None
    sections = _lead_html(main, summarised, frictional, data)
    if summarised is not None:
        rows = frontier(main, summarised)
        data["main"] = dataset(answered)
        data["frontier"] = [{k: row[k] for k in ("family", "level", "time")} for row in rows]
        data["table"] = aggregate(main, summarised)
        data["profiles"] = profiles(main)
        shift_note = ("SGM = shifted geometric mean of time_s over the family's problems, "
                      "failures charged the time limit, with the family's own shift "
                      f"({stats.SHIFT_FACTOR:g} x the median fastest successful solve).")
        sections.append(
            "<section id='answer'><h2>Fastest pair overall, per family</h2>"
            "<p>Per family and accuracy level, the fastest solver/formulation pair among "
            f"those that solve at least {FRONTIER_SUCCESS:.0%} of the family's problems "
            "(success = qpbench's own residual &lt;= the level), its SGM time, and how much "
            f"each further digit multiplies the time from the previous level. {shift_note}</p>"
            + _frontier_html(rows)
            + "<div id='frontier-plot' class='plot small'></div></section>")
        sections.append(
            "<section id='work-precision'><h2>Work-precision</h2>"
            "<p>Every answered solve of the chosen family: time against v_error (the "
            "residual where no reference exists; values below 1e-17 drawn at 1e-17). One "
            "legend entry per pair: click to hide or show it, double-click to show it alone. "
            "The pairs of the family's frontier and the most reliable few are drawn at first."
            "</p><div class='controls'><label>family <select id='wp-family'></select></label>"
            " <button id='wp-all'>show all pairs</button>"
            " <button id='wp-none'>hide all pairs</button></div>"
            "<div id='wp' class='plot'></div></section>")
        sections.append(
            "<section id='profiles'><h2>Performance profiles</h2><p>Dolan-More: the share "
            "of problems each pair solves within tau times the fastest time on that problem "
            "(failures never count). The ten largest areas are drawn at first.</p>"
            + "".join(f"<div id='profile-{i}' class='plot'></div>"
                      for i in range(len(data["profiles"])))
            + ("" if data["profiles"] else "<p class='none'>(no solves at 1e-04 or 1e-08)</p>")
            + "</section>")
        sections.append(
            "<section id='results'><h2>Results table</h2><p>Per family (and all problems), "
            "pair and level: solves, success rate, SGM time, median residual. Click a header "
            "to sort; choose or type to filter.</p><div class='controls' id='filters'>"
            "<label>family <select data-filter='0'></select></label> "
            "<label>formulation <select data-filter='2'></select></label> "
            "<label>backend <select data-filter='3'></select></label> "
            "<label>level <select data-filter='4'></select></label> "
            "<label>pair <input id='pair-filter' type='search' placeholder='e.g. osqp'>"
            "</label></div><p id='table-count' class='small'></p>"
            "<table id='results-table' class='sortable'><thead></thead><tbody></tbody></table>"
            "</section>")
        sections.append(
            "<section id='problem'><h2>One problem</h2><p>Every pair's residual against "
            "time on one problem, one point per level.</p><div class='controls'><label>problem "
            "<select id='problem-select'></select></label></div>"
            "<div id='problem-plot' class='plot'></div></section>")
    else:
        sections.append("<section id='answer'><h2>Fastest pair overall, per family</h2>"
                        "<p class='none'>No frictionless problems in these results.</p>"
                        "</section>")
    if answered_frictional.empty:
        friction = "<p class='none'>No frictional problems in these results.</p>"
    else:
        data["friction"] = dataset(answered_frictional, "coulomb_residual")
        friction = _friction_html(frictional)
    sections.append(f"<section id='friction'><h2>Friction</h2>{friction}</section>")
    if simulations is not None:
        sections.append(_simulations_html(simulations))
    imported = imported_problems.describe_imported(everything)
    if not imported.empty:
        sections.append(f"<section id='imported'><h2>{_text(imported_problems.TITLE)}</h2>"
                        f"<p>{_text(imported_problems.INTRO)} "
                        f"{_text(imported_problems.note(imported).strip())}</p>"
                        + _table(list(imported.columns), [[_text(cell) for cell in row]
                                                          for row in imported.to_numpy()])
                        + "</section>")
    sections.append("<section id='provenance'><h2>Machine and versions</h2>"
                    + _table(["item", "value"], [[_text(k), _text(v)]
                                                 for k, v in provenance(everything)])
                    + "</section>")
    levels = sorted({float(a) for a in everything["accuracy"].dropna()}, reverse=True)
    floor = below_floor.note(everything)
    summary = (f"<code>{_text(source)}</code>: {len(everything)} solves of "
               f"{everything['problem'].nunique()} problems by "
               f"{stats.solver_keys(everything).nunique()} solver/formulation pairs at levels "
               f"{', '.join(_level(a) for a in levels)}. The text summary with every table is "
               "<a href='REPORT.md'>REPORT.md</a>." + (f" {_text(floor)}" if floor else ""))
    payload = json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")
    return TEMPLATE.format(summary=summary, sections="".join(sections), style=STYLE,
                           plotly=plotly_js.replace("</script", "<\\/script"), data=payload,
                           script=SCRIPT)


# progress hooks (on_page): each is told the path of index.html as its building starts
_page_listeners: list[Callable[[Path], None]] = []


@contextmanager
def on_page(listener: Callable[[Path], None]) -> Iterator[None]:
    """Tell ``listener(path)`` as :func:`write_html` starts building a page, within the block.

    A progress hook for the report.

    Parameters
    ----------
    listener : callable
        Called with the path of each page.

    Yields
    ------
    None
        Control to the block, with the listener registered.
    """
    _page_listeners.append(listener)
    try:
        yield
    finally:
        _page_listeners.remove(listener)


def write_html(everything: pd.DataFrame, folder: Path, source: str,
               simulations: dict[str, Any] | None = None) -> Path:
    """Write ``folder/index.html`` for the rows ``everything`` (atomically).

    Parameters
    ----------
    everything : pandas.DataFrame
        Results rows of every kind.
    folder : pathlib.Path
        The report's folder.
    source : str
        The results table's name, shown in the summary.
    simulations : dict of str to Any, optional
        The whole-simulation measurement (see :func:`page`); None leaves its section out.

    Returns
    -------
    pathlib.Path
        The path of index.html.
    """
    from plotly.offline import get_plotlyjs

    path = Path(folder) / "index.html"
    for listener in list(_page_listeners):
        listener(path)
    text = page(everything, source, get_plotlyjs(), simulations)
    with atomic_path(path) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return path
