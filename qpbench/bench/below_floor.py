"""The reports' sentence on the cells double precision cannot decide (verdict ``below-floor``).

A (problem, level) cell is below the floor when the level is below the least residual a double
vector is known to reach on the problem (``qpbench.solvers.run.judge``); the reports leave such
cells out of every rate, time and profile (``qpbench.bench.stats.without_below_floor``) and
say so with :func:`note`, in plain text that both the Markdown and the HTML report print.
"""

from __future__ import annotations

import pandas as pd

from qpbench.bench import stats
from qpbench.bench.formatting import level

NAMED_PROBLEMS = 10  # problems the sentence names; the rest are counted


def note(frame: pd.DataFrame) -> str:
    """Say how many cells were below a problem's floor and on which problems, at which levels.

    Parameters
    ----------
    frame : pandas.DataFrame
        Results rows (every kind, before any is left out).

    Returns
    -------
    str
        One sentence (plain text, no markup), naming up to NAMED_PROBLEMS problems, each with
        its levels loosest first; empty when no cell is below a floor.
    """
    cells = stats.below_floor_cells(frame)
    if cells.empty:
        return ""
    levels = cells.groupby("problem", sort=True)["accuracy"].apply(
        lambda found: ", ".join(level(value) for value in found))
    named = [f"{problem} at {text}" for problem, text in levels.head(NAMED_PROBLEMS).items()]
    rest = len(levels) - len(named)
    if rest:
        named.append(f"and {rest} more problem{'s' if rest > 1 else ''}")
    count = len(cells)
    cell, lie, are = ("cells", "lie", "are") if count > 1 else ("cell", "lies", "is")
    return (f"{count} {cell} (problem, level) of {int(cells['rows'].sum())} solves {lie} "
            "below the problem's double-precision residual floor (status below-floor: no "
            "double vector is known to reach the level, so no answer there is judged on "
            f"merit) and {are} left out of every success rate, time and profile: "
            f"{'; '.join(named)}.")
