"""The report's figures as PNG files (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker as ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from qpbench.atomic import atomic_path
from qpbench.bench.stats import performance_profile, solver_keys  # noqa: E402

DPI = 110
LINE_STYLES = ("-", "--", ":", "-.")


def style(index: int) -> dict[str, str]:
    """Give the colour and line style of curve ``index``: ten colours, then the next line style.

    Parameters
    ----------
    index : int
        The curve's position, from 0.

    Returns
    -------
    dict of str to str
        matplotlib's ``color`` and ``linestyle``.
    """
    return {"color": f"C{index % 10}", "linestyle": LINE_STYLES[(index // 10) % 4]}


def _legend(axes: plt.Axes, curves: int) -> None:
    """Inside the plot for a few curves, beside it for many."""
    if curves <= 10:
        axes.legend(fontsize=7, loc="best")
    else:
        axes.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                    ncol=1 + curves // 30)


MAX_LINES = 12  # no static chart draws more curves than this; index.html has every pair


def best(scores: pd.DataFrame, limit: int = MAX_LINES) -> list[str]:
    """Rank pairs: the most reliable, then the fastest, and keep the first ``limit``.

    Parameters
    ----------
    scores : pandas.DataFrame
        One row per pair (the index) with columns ``solved`` (higher first) and ``time``
        (lower first).
    limit : int, optional
        How many to keep; MAX_LINES by default.

    Returns
    -------
    list of str
        The first ``limit`` index entries of the ranking.
    """
    ranked = scores.assign(_s=-scores["solved"].astype(float), _t=scores["time"].astype(float))
    ranked = ranked.sort_values(["_s", "_t"], kind="stable")
    return [str(key) for key in ranked.index[:limit]]


def _note(shown: int, total: int) -> str:
    return f" (best {shown} of {total}; every pair in index.html)" if shown < total else ""


def slug(text: str) -> str:
    """Turn ``text`` into a file-name-safe form.

    Parameters
    ----------
    text : str
        Any text (a family's name, say).

    Returns
    -------
    str
        ``text`` with every run of other characters than letters, digits, ``.``, ``+`` and
        ``-`` replaced by ``_``; ``all`` when nothing is left.
    """
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_") or "all"


# progress hooks (on_figure): each is told the path of every figure as its writing starts
_figure_listeners: list[Callable[[Path], None]] = []


@contextmanager
def on_figure(listener: Callable[[Path], None]) -> Iterator[None]:
    """Tell ``listener(path)`` as each figure of this module starts being written, within the block.

    Drawing a figure to PNG is most of its time: this is a progress hook for the report.

    Parameters
    ----------
    listener : callable
        Called with the path of each figure.

    Yields
    ------
    None
        Control to the block, with the listener registered.
    """
    _figure_listeners.append(listener)
    try:
        yield
    finally:
        _figure_listeners.remove(listener)


def _save(figure: plt.Figure, path: Path) -> Path:
    for listener in list(_figure_listeners):
        listener(path)
    try:
        with atomic_path(path) as temporary:
            figure.savefig(temporary, dpi=DPI, bbox_inches="tight", format="png")
    finally:
        plt.close(figure)
    return path


def work_precision(frame: pd.DataFrame, family: str, path: Path) -> Path | None:
    """Plot achieved error against time across the accuracy sweep of one family.

    One panel per formulation and one curve per solver: each point is one level, at (median
    time_s, median v_error) over the family's problems that returned an answer. Uses the
    residual where no problem has a verified reference. A solver keeps its colour and line
    style in every panel; each panel draws at most MAX_LINES solvers (:func:`best`).

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows of the family.
    family : str
        The family's name, for the title.
    path : pathlib.Path
        The PNG file to write.

    Returns
    -------
    pathlib.Path or None
        ``path``; None when no row has an answer (nothing written).
    """
    answered = frame[frame["residual"].notna() & frame["time_s"].notna()]
    if answered.empty:
        return None
    error_column = "v_error" if answered["v_error"].notna().any() else "residual"
    formulations = sorted(answered["formulation"].astype(str).unique())
    solver_index = {name: i for i, name in enumerate(sorted(answered["solver"].astype(str)
                                                            .unique()))}
    columns = min(2, len(formulations))
    rows = -(-len(formulations) // columns)
    figure, grid = plt.subplots(rows, columns, figsize=(6.4 * columns, 4.6 * rows),
                                sharex=True, sharey=True, squeeze=False)
    floor = 1e-17
    for panel, formulation in zip(grid.flat, formulations, strict=False):
        subset = answered[answered["formulation"].astype(str) == formulation]
        scores = subset.groupby(subset["solver"].astype(str)).agg(
            solved=("success", lambda s: s.fillna(False).astype(bool).mean()),
            time=("time_s", "median"))
        keep = best(scores)
        groups = [(name, group) for name, group in subset.groupby(subset["solver"].astype(str))
                  if name in keep]
        for name, group in groups:
            points = group.groupby("accuracy").agg(time=("time_s", "median"),
                                                   error=(error_column, "median"))
            points = points.sort_index(ascending=False)
            panel.plot(points["time"], np.maximum(points["error"], floor), marker="o",
                       markersize=4, label=name, **style(solver_index[name]))
        panel.set_xscale("log")
        panel.set_yscale("log")
        panel.set_title(f"{formulation}{_note(len(groups), len(scores))}", fontsize=10)
        panel.grid(True, which="both", alpha=0.3)
        _legend(panel, len(groups))
    figure.subplots_adjust(wspace=0.55, hspace=0.25)  # room for legends beside panels
    for panel in grid.flat[len(formulations):]:
        panel.set_visible(False)
    for panel in grid[-1, :]:
        panel.set_xlabel("median solver time per problem [s]")
    for panel in grid[:, 0]:
        panel.set_ylabel(f"median {error_column}")
    figure.suptitle(f"Work-precision, family {family} (points: accuracy levels; "
                    + ("v_error = ||v+ - v+_ref||_M / ||v-||_M)" if error_column == "v_error"
                       else "no reference: residual)"))
    return _save(figure, path)


def profile(frame: pd.DataFrame, accuracy: float, path: Path) -> Path | None:
    """Plot the Dolan-More performance profile at one accuracy level.

    Each curve is the share of problems solved within tau times the fastest solver's time; at
    most MAX_LINES curves, those of largest area.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows of the level.
    accuracy : float
        The level, for the title.
    path : pathlib.Path
        The PNG file to write.

    Returns
    -------
    pathlib.Path or None
        ``path``; None when no problem was solved (nothing written).
    """
    curves = performance_profile(frame)
    if curves.empty or curves.shape[1] == 0:
        return None
    total = curves.shape[1]
    curves = curves[best(pd.DataFrame({"solved": curves.mean(), "time": 0.0}))]
    figure, axes = plt.subplots(figsize=(6.4, 4.6))
    for index, key in enumerate(curves.columns):
        axes.step(curves.index, curves[key], where="post", label=key, **style(index))
    axes.set_xscale("log")
    axes.set_ylim(0, 1.02)
    axes.set_xlabel("tau (time / fastest time on the problem)")
    axes.set_ylabel("share of problems solved within tau")
    axes.set_title(f"Performance profile at accuracy {accuracy:.0e}"
                   + _note(curves.shape[1], total).replace(" (best", "\n(largest area:"))
    axes.grid(True, which="both", alpha=0.3)
    _legend(axes, curves.shape[1])
    return _save(figure, path)


def success_by_level(summary: pd.DataFrame, path: Path) -> Path | None:
    """Plot the success rate of each solver/formulation at each accuracy level (grouped bars).

    Parameters
    ----------
    summary : pandas.DataFrame
        :func:`~qpbench.bench.stats.level_summary` of the results.
    path : pathlib.Path
        The PNG file to write.

    Returns
    -------
    pathlib.Path or None
        ``path``; None for an empty summary (nothing written).
    """
    if summary.empty:
        return None
    table = summary.pivot(index="solver", columns="accuracy", values="success_rate")
    table = table[sorted(table.columns, reverse=True)]
    figure, axes = plt.subplots(figsize=(max(6.4, 0.45 * len(table) + 2), 4.2))
    width = 0.8 / max(1, table.shape[1])
    positions = np.arange(len(table))
    for i, level in enumerate(table.columns):
        axes.bar(positions + i * width, table[level], width=width, label=f"{level:.0e}")
    axes.set_xticks(positions + width * (table.shape[1] - 1) / 2)
    axes.set_xticklabels(table.index, rotation=60, ha="right", fontsize=7)
    axes.set_ylim(0, 1.05)
    axes.set_ylabel("success rate")
    axes.set_title("Success rate by accuracy level")
    axes.legend(title="accuracy", fontsize=7)
    return _save(figure, path)


def cost_of_accuracy(relative: pd.DataFrame, path: Path) -> Path | None:
    """Plot each pair's time relative to the loosest level against the level.

    What each further digit costs the pairs whose time grows with it; one line per pair of
    ``relative``, the first MAX_LINES drawn.

    Parameters
    ----------
    relative : pandas.DataFrame
        Pairs (rows) x levels (columns, loosest first), as
        :func:`~qpbench.bench.stats.relative_time` gives.
    path : pathlib.Path
        The PNG file to write.

    Returns
    -------
    pathlib.Path or None
        ``path``; None with no pair or fewer than two levels (nothing written).
    """
    if relative.empty or relative.shape[1] < 2:
        return None
    shown = relative.head(MAX_LINES)
    figure, axes = plt.subplots(figsize=(6.4, 4.6))
    for index, (key, values) in enumerate(shown.iterrows()):
        values = values.dropna()
        axes.plot(values.index.astype(float), values.to_numpy(dtype=float), marker="o",
                  markersize=4, label=str(key), **style(index))
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.invert_xaxis()  # tighter levels to the right
    axes.set_xlabel("accuracy level (residual bound)")
    axes.set_ylabel(f"time relative to {float(relative.columns[0]):.0e}")
    axes.yaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    axes.yaxis.set_minor_formatter(ticker.FormatStrFormatter("%g"))
    axes.set_title("What accuracy costs, the pairs whose time grows with the level"
                   + _note(len(shown), len(relative)).replace(" (best", "\n(steepest"))
    axes.grid(True, which="both", alpha=0.3)
    _legend(axes, len(shown))
    return _save(figure, path)


def time_by_size(frame: pd.DataFrame, accuracy: float, path: Path) -> Path | None:
    """Plot solver time against the number of contacts at one level (successful solves only).

    One marker series per solver/formulation, at most MAX_LINES, those that solved most.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows of the level.
    accuracy : float
        The level, for the title.
    path : pathlib.Path
        The PNG file to write.

    Returns
    -------
    pathlib.Path or None
        ``path``; None when nothing was solved (nothing written).
    """
    solved = frame[frame["success"].fillna(False).astype(bool) & frame["time_s"].notna()
                   & (frame["contacts"].fillna(0) > 0)]
    if solved.empty:
        return None
    solved = solved.assign(key=solver_keys(solved))
    scores = solved.groupby("key").agg(solved=("success", "size"), time=("time_s", "median"))
    keep = best(scores)
    figure, axes = plt.subplots(figsize=(6.4, 4.6))
    groups = [(key, group) for key, group in solved.groupby("key") if key in keep]
    for index, (key, group) in enumerate(groups):
        axes.plot(group["contacts"].astype(float), group["time_s"], marker="o", markersize=3,
                  linestyle="none", label=key, color=style(index)["color"],
                  alpha=0.8 if index < 10 else 0.5)
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("contacts n")
    axes.set_ylabel("solver time [s]")
    axes.set_title(f"Time against problem size at accuracy {accuracy:.0e} (solved only)"
                   + _note(len(groups), len(scores)).replace(" (best", "\n(most solved"))
    axes.grid(True, which="both", alpha=0.3)
    _legend(axes, len(groups))
    return _save(figure, path)
