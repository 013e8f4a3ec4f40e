"""The pairs ``qpbench head-to-head`` measures (``qpbench.studies.head_to_head``): pi-robust's own,
and the fastest external ones of the main benchmark's table, chosen by measurement.

For impact problems the external candidates are the fastest pairs over the families of
CANDIDATE_FAMILIES and each of those families' own fastest; on a hard family's set, that
family's fastest too. For frictional problems they are chosen per model (``coulomb``: the
exact law, whichever formulation solves it, ``staggered``, ``lcp``, ``nsgs`` or Siconos'
``fc2d``; ``ccp``: Anitescu's relaxation): the fastest pairs of the model and each of its
formulations' fastest, so that pi-robust as staggered projections' inner solver meets the
field's contact solvers (Siconos) on the law they solve, not only other inner solvers.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from qpbench.bench import stats
from qpbench.bench.results import frictional_rows
from qpbench.problem.friction import MODELS, model_of
from qpbench.studies.head_to_head_sets import HARD_FAMILIES

OWN_IMPACT = ("pi-robust/lcp",)
OWN_FRICTIONAL = ("pi-robust/staggered", "pi-robust/ccp")
# the main benchmark's families whose fastest external pairs are the impact candidates
CANDIDATE_FAMILIES = ("dump", "grid", "box", "scene:grid5_itr_0")
# each of those families' (and each hard family's) own fastest external pairs measured besides:
# the main table's ranking is made under another protocol (five repeats, not twenty, other
# problems between them), so the pair fastest here may rank second or third there
FAMILY_CANDIDATES = 3
# the columns of the main benchmark's table that fastest_external ranks by
BENCH_COLUMNS = ("problem", "family", "kind", "solver", "formulation", "backend", "accuracy",
                 "success", "time_s", "time_limit_s")


def fastest_external(bench: pd.DataFrame, candidates: int, accuracy: float) -> dict[str, Any]:
    """The external pairs to measure, chosen from the main benchmark's table.

    {"impact": the ``candidates`` fastest external impact pairs on CANDIDATE_FAMILIES, and the
    FAMILY_CANDIDATES fastest on each of those families where they are not among them already,
    "frictional": per model (MODELS), the ``candidates // 3`` (at least one) fastest external
    pairs over the formulations of that model (:func:`~qpbench.problem.friction.model_of`) and
    the fastest of each of those formulations besides, "families": per hard family
    (HARD_FAMILIES), its FAMILY_CANDIDATES fastest external pairs not among "impact" (measured
    on the family's set only)}, by :func:`ranked` at ``accuracy``.

    Parameters
    ----------
    bench : pd.DataFrame
        The main benchmark's rows, with BENCH_COLUMNS.
    candidates : int
        How many of the fastest external impact pairs.
    accuracy : float
        The level ranked at.

    Returns
    -------
    dict
        ``impact`` and ``frictional`` pair keys, fastest first, and ``families``: family ->
        pair keys.
    """
    level = bench[np.isclose(bench["accuracy"].astype(float), accuracy)
                  & (bench["backend"].astype(str) != stats.OWN_BACKEND)]
    frictional = frictional_rows(level)
    chosen: dict[str, Any] = {}
    impact = level[~frictional & level["family"].astype(str).isin(CANDIDATE_FAMILIES)]
    chosen["impact"] = ranked(impact)[:candidates]
    for family in CANDIDATE_FAMILIES:  # a family's own fastest, should they rank lower overall
        for key in ranked(impact[impact["family"].astype(str) == family])[:FAMILY_CANDIDATES]:
            if key not in chosen["impact"]:
                chosen["impact"].append(key)
    chosen["frictional"] = []
    formulations = level["formulation"].astype(str)
    for model in MODELS:
        of_model = frictional & (formulations.map(model_of) == model)
        keys = ranked(level[of_model])[:max(1, candidates // 3)]
        for formulation in sorted(set(formulations[of_model])):
            keys += ranked(level[of_model & (formulations == formulation)])[:1]
        chosen["frictional"] += list(dict.fromkeys(keys))  # each once, in order
    chosen["families"] = {}
    for family in HARD_FAMILIES:
        rows = level[~frictional & (level["family"].astype(str) == family)]
        fastest = [key for key in ranked(rows)[:FAMILY_CANDIDATES]
                   if key not in chosen["impact"]]
        if fastest:
            chosen["families"][family] = fastest
    return chosen


def ranked(frame: pd.DataFrame) -> list[str]:
    """``solver/formulation`` keys of a results table's rows, fastest first.

    Ranked by the shifted geometric mean of their charged times (``qpbench.bench.stats``);
    only pairs with a row for every problem of ``frame``.

    Parameters
    ----------
    frame : pd.DataFrame
        Result rows of one accuracy level.

    Returns
    -------
    list of str
        The pair keys, fastest first; empty for an empty frame.
    """
    if frame.empty:
        return []
    frame = frame.assign(key=stats.solver_keys(frame), charged=stats.charged_times(frame))
    shift = stats.time_scale_shift(frame)
    problems = frame["problem"].nunique()
    sgm = {key: stats.shifted_geometric_mean(group["charged"], shift)
           for key, group in frame.groupby("key") if group["problem"].nunique() == problems}
    return sorted(sgm, key=sgm.get)
