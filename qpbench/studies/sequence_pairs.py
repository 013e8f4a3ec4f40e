"""The pairs sequence mode replays by default: pi-robust, every usable warm-startable external
impact pair, and the main table's fastest pairs that take no warm start, shown beside them
(``qpbench.studies.sequence``; which of them leave a scene is the replay's rule there)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from qpbench.bench.defaults import SEQUENCE_ACCURACY
from qpbench.bench.results import frictional_rows
from qpbench.bench.stats import OWN_BACKEND, solver_keys
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import usable_solvers
from qpbench.studies.head_to_head_pairs import ranked
from qpbench.studies.sequence import OWN

COLD_PAIRS = 4  # the fastest pairs without warm starts of the main table, shown beside


def fastest_cold(bench: pd.DataFrame, count: int = COLD_PAIRS,
                 accuracy: float = SEQUENCE_ACCURACY) -> list[str]:
    """The ``count`` fastest external impact pairs that take no warm start.

    Ranked on the captured scenes (families ``scene:*``) of the main table at ``accuracy`` (SGM
    of charged times).

    Parameters
    ----------
    bench : pd.DataFrame
        The main benchmark's rows.
    count : int, optional
        How many pairs; COLD_PAIRS by default.
    accuracy : float, optional
        The level ranked at; SEQUENCE_ACCURACY by default.

    Returns
    -------
    list of str
        The pair keys, fastest first.
    """
    cold_only = {spec.key for spec in usable_solvers()
                 if not spec.warm_start and spec.backend != OWN_BACKEND}
    level = bench[np.isclose(bench["accuracy"].astype(float), accuracy)
                  & bench["family"].astype(str).str.startswith("scene:")
                  & ~frictional_rows(bench)]
    return ranked(level[solver_keys(level).isin(cold_only)])[:count]


def default_solvers(cold: Sequence[str] = ()) -> list[SolverSpec]:
    """pi-robust, every usable warm-startable external impact pair, and the pairs ``cold``.

    Frictional formulations (``nsgs``, ``ccp``, ``staggered``) are left out.

    Parameters
    ----------
    cold : sequence of str, optional
        Keys of the fastest pairs that take no warm start (:func:`fastest_cold`); none by
        default.

    Returns
    -------
    list of SolverSpec
        The pairs, in the registry's order.
    """
    chosen = []
    for spec in usable_solvers():
        if spec.formulation in ("nsgs", "ccp", "staggered") or "staggered" in spec.name:
            continue
        if spec.key == OWN or spec.key in cold or (
                spec.warm_start and spec.backend != OWN_BACKEND):
            chosen.append(spec)
    return chosen
