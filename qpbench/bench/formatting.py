"""How the reports write a value: a number, an accuracy level, a share.

One place for the text of the values that the Markdown report, its sections and the tables
built for it (imported problems, the cells below a floor, the targets) print, so that a value
reads the same wherever it stands.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd


def number(value: Any) -> str:
    """Format a value with three significant digits; '-' for missing.

    Parameters
    ----------
    value : Any
        A number, a missing value (None, NaN, ``pd.NA``) or anything else (shown as ``str``).

    Returns
    -------
    str
        The value's text; ``inf`` for an infinite float.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA:
        return "-"
    if isinstance(value, float | np.floating):
        return "inf" if math.isinf(value) else f"{value:.3g}"
    return str(value)


def level(accuracy: float) -> str:
    """Format an accuracy level as ``1e-08``.

    Parameters
    ----------
    accuracy : float
        The level.

    Returns
    -------
    str
        The level's text.
    """
    return f"{float(accuracy):.0e}"


def percent(value: Any) -> str:
    """Format a share as a percentage with one decimal: 0.5 as ``50.0%``; '-' for missing.

    Parameters
    ----------
    value : Any
        A share in [0, 1], None or NaN.

    Returns
    -------
    str
        The percentage's text.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{100.0 * float(value):.1f}%"
