"""The head-to-head's problems of a few contacts: is pi-robust's call the cheapest of any pair?

On a problem of a few contacts a solve is mostly the call itself (the conversion into the
backend's format, its set-up, the caches and branches it finds cold), so issue 56 asks there
not for a speedup but for the lowest time of any pair, problem by problem. This module reads
the head-to-head's rows (``qpbench.studies.head_to_head.measure_batch``): for every problem of
at most ``FEW_CONTACTS`` contacts in every set, pi-robust's pair of that set that solved it
fastest against the fastest external pair that solved it, each solve's ``time_s`` the fastest
over the passes. A frictional problem is in two sets (``coulomb`` and ``ccp``), each
comparing the pairs of one law, and counts once in each. A problem pi-robust did not
solve counts against it; one no external pair solved, for it; one no pair solved is left out.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from typing import Any

import pandas as pd

FEW_CONTACTS = 10  # the most contacts of a problem counted here


def few_contacts_summary(rows: Sequence[dict[str, Any]], undecided: Sequence[str]
                         ) -> dict[str, Any]:
    """Per problem of at most ``FEW_CONTACTS`` contacts, pi-robust's time against the fastest
    external pair's; how many it is the fastest on.

    Parameters
    ----------
    rows : sequence of dict
        The head-to-head's rows, every pass (fields ``problem``, ``set``, ``solver``, ``own``,
        ``contacts``, ``status``, ``success``, ``time_s``).
    undecided : sequence of str
        The verdicts that charge no solver (no solution, residual floor above the accuracy);
        such problems are left out.

    Returns
    -------
    dict
        ``few_contacts`` (the bound), ``problems`` (one per set and problem: ``set``,
        ``problem``, ``contacts``, ``own`` and ``external``, the fastest pair of each kind that
        solved it or None, their times ``own_s`` and ``external_s`` or None, ``ratio``
        ``external_s / own_s``, infinite when no external pair solved it, 0 when pi-robust did
        not, and ``lowest``), ``lowest`` (how many pi-robust is the fastest on) and
        ``target_met`` (on every one); empty when no problem is that small (or solved by any
        pair).
    """
    frame = pd.DataFrame(list(rows))
    if frame.empty:
        return {}
    frame = frame[(frame["contacts"] <= FEW_CONTACTS) & ~frame["status"].isin(undecided)
                  & frame["success"]]
    problems = []
    for (set_name, problem), group in frame.groupby(["set", "problem"], sort=True):
        by_pair = group.groupby("solver")
        fastest, is_own = by_pair["time_s"].min(), by_pair["own"].first().astype(bool)
        own, external = fastest[is_own], fastest[~is_own]
        own_s = float(own.min()) if len(own) else None
        external_s = float(external.min()) if len(external) else None
        ratio = (math.inf if external_s is None else 0.0 if own_s is None
                 else external_s / own_s)
        problems.append({"set": set_name, "problem": problem,
                         "contacts": int(group["contacts"].iloc[0]),
                         "own": str(own.idxmin()) if len(own) else None, "own_s": own_s,
                         "external": str(external.idxmin()) if len(external) else None,
                         "external_s": external_s, "ratio": ratio, "lowest": ratio > 1.0})
    if not problems:
        return {}
    lowest = sum(entry["lowest"] for entry in problems)
    return {"few_contacts": FEW_CONTACTS, "problems": problems, "lowest": lowest,
            "target_met": lowest == len(problems)}


def few_contacts_markdown(summary: dict[str, Any]) -> str:
    """The summary as one paragraph of the head-to-head's section ("" when empty).

    Parameters
    ----------
    summary : dict
        :func:`few_contacts_summary`'s answer.

    Returns
    -------
    str
        The paragraph: how many problems, in which sets, pi-robust is the fastest on, the
        range and median of the fastest external pair's time over pi-robust's, and the
        problem where that ratio is least.
    """
    if not summary:
        return ""
    problems = summary["problems"]
    ratios = sorted(entry["ratio"] for entry in problems)
    closest = min(problems, key=lambda entry: entry["ratio"])
    sets = sorted({entry["set"] for entry in problems})
    against = ("no external pair solved it" if closest["external"] is None else
               f"`{closest['external']}` took {closest['ratio']:.2f}x the time of "
               f"`{closest['own']}`" if closest["own"] is not None else
               f"`{closest['external']}` solved it and pi-robust did not")
    verdict = "met" if summary["target_met"] else "not met"
    return (f"Problems of at most {summary['few_contacts']} contacts, where a solve is mostly "
            f"the call itself ({len(problems)} in the sets {', '.join(sets)}; a frictional "
            "problem once per law): pi-robust's pair is the fastest of all pairs on "
            f"{summary['lowest']} of {len(problems)} (target: on every one, **{verdict}**); "
            "the fastest external pair takes "
            f"{_ratio(ratios[0])}-{_ratio(ratios[-1])} its time, median "
            f"{_ratio(statistics.median(ratios))}; the closest is {closest['problem']} "
            f"({closest['set']}), where {against}.")


def _ratio(value: float) -> str:
    """A time ratio for the paragraph (``inf`` where no external pair solved the problem)."""
    return "inf" if math.isinf(value) else f"{value:.2f}x"
