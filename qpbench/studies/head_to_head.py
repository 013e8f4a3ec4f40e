"""Head to head, no warm start: pi-robust against the fastest external pairs on the sets
that matter, timed interleaved and, beside it, with the CPU caches flushed (cold).

The sets (``problems/head_to_head.toml``, built with ``qpbench build-set``; ``make bench``
adds a seed offset drawn at run time, so that the generated problems are ones nobody tuned on,
and the report lists their seeds, read from the problem files): the SCISim research fork's 50
dumps of its 5x5 grid scene, the first impacts of its 50 7x7 grid scenes, impacts captured
from its 5x5 and 3x3 grid scenes, generated grids and box packings, the first impacts of dense
piles of circles and of boxes (a set per size bucket), the hard families (a set each), the
frictional families and Siconos' granular flows (pi-robust as the inner solver of
``staggered`` and on ``ccp``). A problem's set is named by its family and, for grids, box
packings and piles, its size (``qpbench.studies.head_to_head_sets``).

The external pairs (``qpbench.studies.head_to_head_pairs``): for impact problems the
``candidates`` fastest external pairs of the main benchmark (``results/bench.parquet``:
shifted geometric mean of charged times at 1e-8 over the families ``dump``, ``grid``, ``box``
and the captured grid scenes) and the ``FAMILY_CANDIDATES`` fastest on each of those families
alone (a pair fastest on one set may rank lower over all four, and the main table's protocol
may rank it second), for frictional problems the fastest external pairs of each model there
(Coulomb's law, whatever the formulation: Siconos' own ``fc2d`` solvers too; Anitescu's
``ccp``) and each formulation's fastest, so that the choice is made by measurement, not by
hand. On the set of a hard family, that family's
``FAMILY_CANDIDATES`` fastest external pairs in the main table run too (only there:
``candidates["families"]``). pi-robust's own pairs are ``pi-robust/lcp`` (impact) and
``pi-robust/staggered`` and ``pi-robust/ccp`` (frictional).

An external pair whose times on a set's problems so far, summed, are more than
``out_of_running`` times those of the fastest external pair that solved every problem it
solved is measured no further on that set (:class:`Running`): it cannot be the fastest, and on
the large box packings a dense solver's minute-long solves were most of the benchmark's time.
A pair that left a size bucket is not measured on the family's larger buckets either (the
problems are taken smaller bucket first): a dense factorization's time grows faster with the
contacts than a sparse one's. For the same reason a solve whose untimed warm-up took more than
``solve_cap_s`` (the main table's time limit) is timed no further, its warm-up's time standing
for it, and its pair leaves the set as soon as such a pair within the cap exists (on the dense
piles a dense factorization takes seconds to minutes a solve). The report names every such
pair, where and after how many problems it left, how much slower it was and, for a solve over
the cap, how long it took.

Every solve goes through the one stopwatch (``call_solver``) under the timing protocol
(docs/design.md section 7, ``qpbench.bench.repeats.time_interleaved``): the problems are taken
in small batches of one set (:func:`problem_batches`), and the solves of every running pair on
every problem of a batch are timed together, one untimed warm-up each, then rounds of one timed
call each in a rotated order, so that no repeat follows a repeat of the same (problem, pair);
``time_s`` is the fastest of ``repeats``. Beside it, the cold variant (``time_cold_cache_s``,
``cold_cache`` in a set's summary) is the fastest of ``cold_repeats`` calls, each made after
flushing the CPU caches (outside the stopwatch), in the same schedule. The whole measurement
runs ``passes`` times, one pass after another: the machine's speed drifts over minutes (a
shared host), so each pass alone gives a speedup, and their spread shows how far the drift
moves it. The set's figures below are each problem's fastest over all passes; every answer is
judged by qpbench's residual at ``accuracy``; problems without a solution (``no-solution``), and
those whose residual floor in double precision is above ``accuracy`` (``below-floor``), are
left out of the sets' figures, as the report does. Per set and pair: the shifted geometric mean
(``qpbench.bench.stats``: shift on the set's own time scale) of times charged with the largest
time of the set where a solve failed, and ``speedup = SGM(fastest external) / SGM(pi-robust)``
(above 1: pi-robust faster), against the target of 3, met when every pass alone gives at least
3 too and pi-robust solves every problem the external pair solves. The frictional problems form
two sets, one per model (``coulomb``: pi-robust's ``staggered`` against every formulation of the
exact law; ``ccp``), so that each compares pairs that solve the same law, and Siconos' granular
flows two more; a problem that neither pair solves (staggered projections need not converge) is
charged to both and named. Staggered pairs run here up to ``STAGGERED_MAX_OUTER`` rounds, every
pair alike, instead of the accuracy table's cap: at 1e-8 rough-box-30 of seed 0 needs about
1,700 rounds (with the loop's Anderson mixing too), and under the table's 200 no pair solves it,
so the set would compare nothing there. On the problems of a few contacts, where a solve is
mostly the call itself, the verdict is per problem instead (``qpbench.studies.few_contacts``):
pi-robust the fastest pair on each.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from qpbench.bench import stats
from qpbench.bench.defaults import (
    HEAD_TO_HEAD_BATCH_PROBLEMS,
    HEAD_TO_HEAD_CANDIDATES,
    HEAD_TO_HEAD_COLD_REPEATS,
    HEAD_TO_HEAD_OUT_OF_RUNNING,
    HEAD_TO_HEAD_PASSES,
    HEAD_TO_HEAD_REPEATS,
    HEAD_TO_HEAD_SOLVE_CAP_S,
    TARGET_SPEEDUP,
)
from qpbench.bench.repeats import REPEAT_BUDGET_S, Timing, fastest_output, time_interleaved
from qpbench.bench.schedule import flush_bytes
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy as accuracy_table
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import get
from qpbench.solvers.run import BELOW_FLOOR, NO_SOLUTION, judge
from qpbench.studies.few_contacts import few_contacts_markdown, few_contacts_summary
from qpbench.studies.head_to_head_pairs import (
    FAMILY_CANDIDATES,
    OWN_FRICTIONAL,
    OWN_IMPACT,
    fastest_external,
)
from qpbench.studies.head_to_head_sets import (
    SETS,
    generated_seeds,
    larger_buckets,
    seed_ranges,
    set_of,
    set_rank,
)

ACCURACY = 1e-8
# verdicts that charge no solver (see ``qpbench.solvers.run.judge``): left out of every figure
UNDECIDED = (NO_SOLUTION, BELOW_FLOOR)
STAGGERED_MAX_OUTER = 2_000  # rounds of the staggered loop, for every staggered pair here
# contacts of a batch of problems timed together, at most (a larger problem is timed alone)
BATCH_CONTACTS = 1_000
# where pi-robust's compiled kernel hands a problem to the sparse path: chosen on the grid
# family (other seeds) and a dense pile, so the large grid buckets name it
WORK_LIMIT_CHOSEN = (
    f"compiled_work_limit ({accuracy_table.OPTIONS['pi-robust']['compiled_work_limit']:g}), "
    "where the compiled kernel hands a problem to the sparse path, was chosen on grids of 20 to "
    "30 balls a side of other seeds and on a pile of 1,000 circles; this set's seeds were "
    "drawn afresh")
# options of pi-robust chosen while looking at a set's own problems: the report names them,
# since a speedup there is no claim about problems that were not looked at
TUNED_ON = {
    "fork 5x5 grid dumps": "rho, start_sweeps, backup_steps and pi_budget were swept on "
                           "these dumps; backup_steps (0) and pi_budget (100) were chosen "
                           "here and on the 7x7 scenes, with the other sets checked; so was "
                           "the gate of the nearly-singular rule (4 dependent contacts, most "
                           "of the exchange negative), with the generated hard families "
                           "checked",
    "fork 7x7 grid scenes": "backup_steps (0) and pi_budget (100) were chosen here and on the "
                            "5x5 dumps (rho swept here too: every value within noise of the "
                            "table's); the drift rule (drift_steps 3, its ratio 0.999) was "
                            "designed on these scenes, the ratio set apart from the "
                            "contraction seen on the mass-ratio family; the nearly-singular "
                            "rule (block pivoting on a nearly singular block: it fixed first, "
                            "and now hands over to the active-set method at once) was designed "
                            "on these scenes, its gate chosen here and on the 5x5 dumps",
    "near-duplicate": "the presolve that drops the looser of parallel contacts was designed "
                      "with this family in view (its threshold, PARALLEL_DEFECT 1e-14, set "
                      "from rounding, not tuned) and measured on other seeds of it",
    "grids 16-20": WORK_LIMIT_CHOSEN,
    "grids 30-40": WORK_LIMIT_CHOSEN,
    "dense piles 1k": "these are the very impacts several options were chosen on: "
                      "compiled_work_limit on the first three steps of this pile of 1,000 "
                      "circles (and on grids), the updated finish's start (1e-4) and budget "
                      "(30 solves) on this pile of 1,000 boxes' first step and the first "
                      "steps of a pile of 10,000 circles, its prox weight (1e-9) on piles of "
                      "10,000 circles and boxes, checked on piles of 1,000 to 5,000",
}
def measure_batch(pairs: Sequence[tuple[SolverSpec, ImpactProblem | FrictionalProblem]],
                  repeats: int, accuracy: float = ACCURACY, pass_number: int = 0,
                  cold_repeats: int = HEAD_TO_HEAD_COLD_REPEATS,
                  cap_s: float = math.inf) -> list[dict[str, Any]]:
    """One row per (pair, problem) of ``pairs``, their solves timed together.

    In pass ``pass_number``, under the timing protocol
    (``qpbench.bench.repeats.time_interleaved``: one untimed warm-up each, then up to
    ``repeats`` interleaved timed calls, ``time_s`` the fastest), and beside them up to
    ``cold_repeats`` calls with the CPU caches flushed before each (``time_cold_cache_s``, the
    fastest; NaN with none), in the same schedule. A solve whose warm-up took more than
    ``cap_s`` is timed no further (``time_interleaved``): its row keeps the warm-up's answer
    and time, ``over_cap`` true, and no cold time. The first interleaved answer is judged by
    qpbench.

    Parameters
    ----------
    pairs : sequence of (SolverSpec, ImpactProblem or FrictionalProblem)
        The solves to time.
    repeats : int
        Timed interleaved calls per solve at most.
    accuracy : float, optional
        The level asked and judged; ACCURACY by default.
    pass_number : int, optional
        The pass the rows belong to; 0 by default.
    cold_repeats : int, optional
        Cache-flushed calls per solve; 0 for none; HEAD_TO_HEAD_COLD_REPEATS by default.
    cap_s : float, optional
        Seconds of a warm-up past which a solve is timed no further; infinite by default.

    Returns
    -------
    list of dict
        One row per pair: problem, set, solver, pass, own or not, contacts, status, success,
        residual, iteration counts, ``time_s``, ``time_cold_cache_s`` and ``over_cap``.
    """
    timings = [Timing(spec, problem) for spec, problem in pairs]
    if cold_repeats > 0:
        timings += [Timing(spec, problem, cold=True, repeats=cold_repeats)
                    for spec, problem in pairs]
    outputs = time_interleaved(timings, max(repeats, cold_repeats), accuracy, cap_s=cap_s)
    rows = []
    for number, (spec, problem) in enumerate(pairs):
        warm = outputs[number]
        cold = outputs[len(pairs) + number] if cold_repeats > 0 else []
        row = judge(spec, problem, warm[0], accuracy)
        fastest = fastest_output(warm)
        rows.append({
            "problem": problem.name, "set": set_of(problem, spec.formulation),
            "solver": spec.key, "pass": pass_number,
            "own": spec.backend == stats.OWN_BACKEND, "contacts": problem.n_contacts,
            "status": row["status"], "success": bool(row["success"]),
            "residual": row["residual"], "iterations": row["iterations"],
            "outer_iterations": row["outer_iterations"],
            "time_s": fastest.time_s,
            "time_cold_cache_s": fastest_output(cold).time_s if cold else math.nan,
            "over_cap": bool(fastest.time_s > cap_s)})
    return rows


@dataclass
class Running:
    """Which external pairs are still in the running on each set. After each batch of
    problems, :meth:`update` sums each running external pair's ``time_s`` over the set's rows
    so far (the same problems for all of them: a batch times every running pair on each of
    its problems; those without a solution, which the figures leave out, aside) and takes out
    every pair whose sum is more than ``limit`` times the smallest sum among its paces, and
    every pair with a solve over ``cap_s`` (a row's ``over_cap``, on any problem) that has a
    pace. A pair's paces are the other pairs without a solve over the cap that solved every
    problem it solved, and at least one. ``out[set][pair]`` keeps after how many problems it
    left, how many times slower it was and than which pair, and for a solve over the cap its
    longest time and the cap. A pair that leaves a size
    bucket leaves the family's larger buckets too (:func:`larger_buckets`), before it is
    measured there: ``out`` keeps the same record for them, with ``measured_on`` naming the
    bucket where it left."""

    limit: float
    out: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)
    cap_s: float = math.inf

    def running(self, set_name: str | None, solver: str) -> bool:
        """Whether ``solver`` is still measured on the set ``set_name``.

        Parameters
        ----------
        set_name : str or None
            The set.
        solver : str
            The pair's key.

        Returns
        -------
        bool
            False once :meth:`update` took the pair out of that set.
        """
        return solver not in self.out.get(str(set_name), {})

    def update(self, rows: Sequence[dict[str, Any]], set_name: str) -> None:
        """Take every external pair far slower than the fastest out of ``set_name``.

        The rule and what :attr:`out` keeps are the class docstring's.

        Parameters
        ----------
        rows : sequence of dict
            Every row so far (of :func:`measure_batch`); those of other sets, of own pairs, of
            pairs out already and without a solution are skipped.
        set_name : str
            The set to update.
        """
        totals: dict[str, float] = {}
        solved: dict[str, set[str]] = {}
        longest: dict[str, float] = {}
        problems: dict[str, set[str]] = {}
        for one in rows:
            solver = one["solver"]
            if one["set"] != set_name or one["own"] or not self.running(set_name, solver):
                continue
            if one.get("over_cap"):  # (on a problem without a solution too: time is time)
                longest[solver] = max(longest.get(solver, 0.0), one["time_s"])
            if one["status"] in UNDECIDED:
                continue
            totals[solver] = totals.get(solver, 0.0) + one["time_s"]
            solved.setdefault(solver, set())
            if one["success"]:
                solved[solver].add(one["problem"])
            problems.setdefault(solver, set()).add(one["problem"])
        for solver, total in totals.items():
            # the pace: the fastest pair within the cap that solved every problem this one
            # solved, and at least one (a pair that fails fast sets no pace)
            paces = [other for other in totals if other != solver and other not in longest
                     and solved[other] and solved[other] >= solved[solver]]
            if not paces:
                continue
            fastest = min(paces, key=totals.__getitem__)
            if total > self.limit * totals[fastest] or solver in longest:
                left = {"problems": len(problems[solver]), "slower": total / totals[fastest],
                        "than": fastest}
                if solver in longest:
                    left.update(longest_s=longest[solver], cap_s=self.cap_s)
                self.out.setdefault(set_name, {})[solver] = left
                for larger in larger_buckets(set_name):
                    self.out.setdefault(larger, {}).setdefault(
                        solver, {**left, "measured_on": set_name})


def fastest_over_passes(frame: pd.DataFrame) -> pd.DataFrame:
    """Each (problem, pair)'s row with the smallest ``time_s`` over all passes.

    As each solve keeps the fastest of its repeats.

    Parameters
    ----------
    frame : pd.DataFrame
        Rows of :func:`measure_batch`.

    Returns
    -------
    pd.DataFrame
        One row per (problem, pair); ``frame`` itself when empty or without passes.
    """
    if "pass" not in frame or frame.empty:
        return frame
    fastest = frame.loc[frame.groupby(["problem", "solver"], sort=False)["time_s"].idxmin()]
    return fastest.reset_index(drop=True)


def summarize(rows: Sequence[dict[str, Any]],
              out: dict[str, dict[str, dict[str, Any]]] | None = None) -> list[dict[str, Any]]:
    """Per set: every pair's success and SGM, pi-robust's best pair, the fastest external one.

    On each problem's fastest row over the passes (module docstring): the speedup; with more
    than one pass, ``pass_speedups``: the same speedup from each pass's rows alone (NaN where a
    pass lacks one of the two kinds of pair, which then fails the target). The pairs that left a
    set (``out``: :attr:`Running.out`) are left out of its figures, since they were measured on
    part of it only, and listed as ``out_of_running``.

    Parameters
    ----------
    rows : sequence of dict
        Every row of every pass (:func:`measure_batch`).
    out : dict or None, optional
        :attr:`Running.out`; None (default) when no pair left.

    Returns
    -------
    list of dict
        One summary per set measured, in the order of SETS (sets not there after them, by
        name).
    """
    out = out or {}
    frame = pd.DataFrame([one for one in rows if one["solver"] not in out.get(one["set"], {})])
    frame = frame[~frame["status"].isin(UNDECIDED)]  # charged to no solver (see judge)
    passes = sorted(set(frame["pass"])) if "pass" in frame else []
    summary = []
    measured = set(frame["set"])
    for name in [*(one for one in SETS if one in measured), *sorted(measured - set(SETS))]:
        group = frame[frame["set"] == name]
        entry = _set_summary(name, fastest_over_passes(group))
        cold_cache = cold_cache_summary(name, group)
        if cold_cache:
            entry["cold_cache"] = cold_cache
        if "speedup" in entry and len(passes) > 1:
            entry["pass_speedups"] = [
                _set_summary(name, group[group["pass"] == number]).get("speedup", math.nan)
                for number in passes]
            entry["target_met"] = entry["target_met"] and all(
                speedup >= TARGET_SPEEDUP for speedup in entry["pass_speedups"])
        if name in out:
            entry["out_of_running"] = [{"solver": solver, **left}
                                       for solver, left in sorted(out[name].items())]
        summary.append(entry)
    return summary


def cold_cache_summary(name: str, group: pd.DataFrame) -> dict[str, Any]:
    """The set's figures from the cold variant in place of ``time_s``.

    ``time_cold_cache_s``: the caches flushed before each timed call. Gives pi-robust's best
    pair, the fastest external pair and the speedup.

    Parameters
    ----------
    name : str
        The set.
    group : pd.DataFrame
        The set's rows, every pass.

    Returns
    -------
    dict
        ``own``, ``external`` and ``speedup``; empty when the variant was not measured or
        one kind of pair is missing.
    """
    if "time_cold_cache_s" not in group or not group["time_cold_cache_s"].notna().any():
        return {}
    cold = _set_summary(name, fastest_over_passes(
        group.assign(time_s=group["time_cold_cache_s"]).dropna(subset=["time_s"])))
    if "speedup" not in cold:
        return {}
    return {"own": cold["own"], "external": cold["external"], "speedup": cold["speedup"]}


def _set_summary(name: str, group: pd.DataFrame) -> dict[str, Any]:
    """One set's figures from one row per (problem, pair): every pair's SGM of charged times
    and success rate, and when both kinds of pair are there, pi-robust's best pair, the fastest
    external pair, the speedup, the problems neither solves and whether the target holds."""
    group = group.copy()
    charge = float(group["time_s"].max())
    group["charged"] = group["time_s"].where(group["success"], charge)
    group["accuracy"] = ACCURACY
    shift = stats.time_scale_shift(group)
    pairs = []
    for key, mine in group.groupby("solver"):
        pairs.append({"solver": key, "own": bool(mine["own"].iloc[0]),
                      "sgm_s": stats.shifted_geometric_mean(mine["charged"], shift),
                      "median_s": float(mine["charged"].median()),
                      "success_rate": float(mine["success"].mean())})
    pairs.sort(key=lambda pair: pair["sgm_s"])
    own = [pair for pair in pairs if pair["own"]]
    external = [pair for pair in pairs if not pair["own"]]
    entry: dict[str, Any] = {"set": name, "problems": int(group["problem"].nunique()),
                             "contacts_min": int(group["contacts"].min()),
                             "contacts_max": int(group["contacts"].max()), "pairs": pairs}
    if own and external:
        entry["own"], entry["external"] = own[0], external[0]
        entry["speedup"] = external[0]["sgm_s"] / own[0]["sgm_s"]
        solved = {key: set(mine.loc[mine["success"], "problem"])
                  for key, mine in group.groupby("solver")}
        entry["unsolved_by_both"] = sorted(
            set(group["problem"]) - solved[own[0]["solver"]] - solved[external[0]["solver"]])
        both = solved[own[0]["solver"]] & solved[external[0]["solver"]]
        common = group[group["problem"].isin(both)]
        entry["common_speedup"] = _sgm(common, external[0]["solver"], shift) / _sgm(
            common, own[0]["solver"], shift) if both else math.nan
        holds = bool(entry["speedup"] >= TARGET_SPEEDUP and solved[
            external[0]["solver"]] <= solved[own[0]["solver"]])
        # the external pair's failures, each charged the set's largest time, may lift the SGM
        # over the target where pi-robust is not that fast on the problems both solve
        entry["met_by_failures"] = holds and not entry["common_speedup"] >= TARGET_SPEEDUP
        entry["target_met"] = holds and not entry["met_by_failures"]
        ratios = _problem_speedups(group, own[0]["solver"], external[0]["solver"])
        entry["median_problem_speedup"] = float(ratios.median()) if len(ratios) else math.nan
        entry["least_problem_speedup"] = float(ratios.min()) if len(ratios) else math.nan
    return entry


def _sgm(group: pd.DataFrame, solver: str, shift: float) -> float:
    """The shifted geometric mean of ``solver``'s charged times in ``group``."""
    return stats.shifted_geometric_mean(group.loc[group["solver"] == solver, "charged"], shift)


def _problem_speedups(group: pd.DataFrame, own: str, external: str) -> pd.Series:
    """``time(external) / time(own)`` on each problem both pairs solve (empty when there is
    none): the problems one by one, without the charges of failures."""
    times = group[group["success"]].pivot_table(index="problem", columns="solver",
                                                 values="time_s", aggfunc="min")
    if own not in times or external not in times:
        return pd.Series(dtype=float)
    return (times[external] / times[own]).dropna()


def markdown(summary: Sequence[dict[str, Any]], repeats: int, passes: int = 1,
             out_of_running: float = HEAD_TO_HEAD_OUT_OF_RUNNING,
             cold_repeats: int = 0, seeds: dict[str, list[int]] | None = None,
             few_contacts: dict[str, Any] | None = None,
             solve_cap_s: float = math.inf) -> str:
    """The head-to-head as a Markdown section: the protocol, a table per set, the pairs' figures.

    Parameters
    ----------
    summary : sequence of dict
        The per-set summaries of :func:`summarize`.
    repeats : int
        Timed repeats per solve.
    passes : int, optional
        Passes over every set; 1 by default.
    out_of_running : float, optional
        The limit of :class:`Running`; HEAD_TO_HEAD_OUT_OF_RUNNING by default.
    cold_repeats : int, optional
        Cache-flushed calls per solve; 0 (default) when not measured.
    seeds : dict of str to list of int or None, optional
        The generated problems' seeds per family (:func:`generated_seeds`), listed at the
        end; None (default) or empty for none.
    few_contacts : dict or None, optional
        The problems of a few contacts (``few_contacts.few_contacts_summary``), a paragraph
        after the targets; None (default) or empty for none.
    solve_cap_s : float, optional
        The cap of :class:`Running` and of the timing; infinite (default): none.

    Returns
    -------
    str
        The ``## Head to head`` section.
    """
    lines = [
        "## Head to head, no warm start: pi-robust against the fastest external pairs per "
        "set\n",
        f"Accuracy {ACCURACY:g}; `time_s` of the one stopwatch, the fastest of {repeats} "
        f"repeats (fewer once they took {REPEAT_BUDGET_S:g} s), never back to back: the "
        "solves of a few problems by every pair are timed together, one round of every "
        "(problem, pair) after another in a rotated order, after one untimed warm-up each "
        "(Siconos' pairs, in a server process, each solve on the CPU of the process that "
        "times the others)"
        + (f"; *caches flushed*: the same speedup from the fastest of {cold_repeats} calls "
           "each made after writing a buffer as large as the last-level cache (outside the "
           "stopwatch)" if cold_repeats > 0 else "")
        + (f", in each of {passes} passes over the whole set, one after another; each "
           "problem's fastest over the passes makes the table, and *per pass* is the range of "
           "the speedups that each pass alone gives (the machine's speed drifts between them)"
           if passes > 1 else "") + "; problems with no solution "
        f"left out; staggered pairs run up to {STAGGERED_MAX_OUTER} rounds (the accuracy "
        f"table's {accuracy_table.OPTIONS['staggered']['max_outer']} elsewhere), every pair alike; "
        "a failed solve is charged the set's largest time; SGM shifted on the set's "
        "own time scale. External pairs: the fastest of the main benchmark "
        "(`bench.parquet`) on the grid, dump and box families and per frictional law "
        "(Coulomb's, whichever the formulation, Siconos' `fc2d` included; `ccp`) with each "
        f"formulation's fastest, each family's {FAMILY_CANDIDATES} fastest, and on a hard "
        f"family's set that family's {FAMILY_CANDIDATES} fastest; one whose times on a set's "
        f"problems so far, summed, are more than {out_of_running:g} times those of the fastest "
        "external pair that solved every problem it solved (and one at least) is measured no "
        "further on that set, nor on the larger size buckets of its family (it cannot be the "
        "fastest; named below)"
        + (f"; so is one with a solve whose untimed warm-up took more than {solve_cap_s:g} s "
           "(the main table's time limit) once such a pair within the cap exists; such a "
           "solve is not timed again, nor run in a later pass: its warm-up's time stands"
           if math.isfinite(solve_cap_s) else "") + ". "
        "speedup = SGM of the fastest external pair / SGM of pi-robust's best "
        f"pair (target >= {TARGET_SPEEDUP:g}"
        + (" in the table and in every pass" if passes > 1 else "")
        + ", with pi-robust solving every problem the external pair solves, and as fast "
        "on the problems both solve, so that no target is met by the external pair's "
        "charged failures alone); per problem = "
        "the median over the problems both solve of the external pair's time over "
        "pi-robust's, and in brackets the least of them (the problem where pi-robust's lead "
        "is smallest).\n",
        "| set | problems | contacts | pi-robust pair | SGM [ms] | solved | fastest external "
        "pair | SGM [ms] | solved | speedup | per pass | per problem | caches flushed | "
        "target |",
        "|---|---:|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for entry in summary:
        own, external = entry.get("own"), entry.get("external")
        if own is None or external is None:
            absent = "pi-robust not measured" if own is None else "no external pair measured"
            lines.append(f"| {entry['set']} | {entry['problems']} | | ({absent}) "
                         "| | | | | | | | | | |")
            continue
        lines.append(
            f"| {entry['set']} | {entry['problems']} | {entry['contacts_min']}-"
            f"{entry['contacts_max']} | `{own['solver']}` | {1e3 * own['sgm_s']:.3f} | "
            f"{100 * own['success_rate']:.0f}% | `{external['solver']}` | "
            f"{1e3 * external['sgm_s']:.3f} | {100 * external['success_rate']:.0f}% | "
            f"{entry['speedup']:.2f}x | {pass_range(entry)} | "
            f"{entry['median_problem_speedup']:.2f}x ({entry['least_problem_speedup']:.2f}x) | "
            f"{flushed(entry)} | {'met' if entry['target_met'] else 'not met'}"
            f"{' (peer failures)' if entry.get('met_by_failures') else ''} |")
    held = [entry["set"] for entry in summary if entry.get("target_met")]
    missed = [entry["set"] for entry in summary if "target_met" in entry
              and not entry["target_met"]]
    undecided = [entry["set"] for entry in summary if "target_met" not in entry]
    lines.append("")
    lines.append(target_sentence(TARGET_SPEEDUP, held, missed, "set", undecided))
    lifted = [entry for entry in summary if entry.get("met_by_failures")]
    if lifted:
        lines.append("\nNot counted as met: " + "; ".join(
            f"on {entry['set']} the speedup passes {TARGET_SPEEDUP:g}x only because "
            f"`{entry['external']['solver']}` failed "
            f"{100 * (1 - entry['external']['success_rate']):.0f}% of the problems, each "
            "charged the set's largest time; "
            + both_solve_phrase(entry["common_speedup"], "problem")
            for entry in lifted) + ".")
    if missed:
        lines.append("\nWhere it does not, the section \"Where pi-robust's time goes\" breaks "
                     "a solve's time down, and docs/notes/pi-robust.md says what was tried, "
                     "with the scripts that measure it.")
    if few_contacts:
        lines.append("\n" + few_contacts_markdown(few_contacts))
    tuned = [f"- {entry['set']}: {TUNED_ON[entry['set']]}." for entry in summary
             if entry["set"] in TUNED_ON]
    if tuned:
        lines.append("\nOptions of pi-robust chosen while looking at a set's own problems "
                     "(its speedup there is measured on problems it was tuned on):\n")
        lines += tuned
    for entry in summary:
        if entry.get("unsolved_by_both"):
            lines.append(f"\n{entry['set']}: solved by neither `{entry['own']['solver']}` nor "
                         f"`{entry['external']['solver']}` (each charged the set's largest "
                         f"time): {', '.join(entry['unsolved_by_both'])}.")
    lines.append("\nEvery pair per set (SGM [ms], solved):\n")
    for entry in summary:
        lines.append(f"- {entry['set']}: " + ", ".join(
            f"`{pair['solver']}` {1e3 * pair['sgm_s']:.3f} ({100 * pair['success_rate']:.0f}%)"
            for pair in entry["pairs"]) + "".join(
            f"; {left_sentence(left)}" for left in entry.get("out_of_running", [])))
    if seeds:
        lines.append("\nSeeds of the generated problems (read from their files; `make bench` "
                     "draws them afresh each run, `qpbench build-set --seed-offset`): "
                     + "; ".join(f"{family} {seed_ranges(numbers)}"
                                 for family, numbers in sorted(seeds.items())) + ".")
    return "\n".join(lines) + "\n"


def left_sentence(left: dict[str, Any]) -> str:
    """Where and why an external pair was measured no further on a set, in Markdown.

    Parameters
    ----------
    left : dict
        An entry of a set's ``out_of_running``: ``solver``, ``problems``, ``slower``,
        ``than``, ``measured_on`` when it left a smaller size bucket, and ``longest_s`` and
        ``cap_s`` when a solve of it went over the cap.

    Returns
    -------
    str
        The clause.
    """
    where = f" of {left['measured_on']}" if "measured_on" in left else ""
    capped = (f"a solve took {left['longest_s']:.1f} s, past the cap of {left['cap_s']:g} s; "
              if "longest_s" in left else "")
    return (f"`{left['solver']}` measured no further after {left['problems']} "
            f"problem{'s' if left['problems'] > 1 else ''}{where} ({capped}"
            f"{left['slower']:.1f}x `{left['than']}`'s time there)")


def flushed(entry: dict[str, Any]) -> str:
    """The speedup of a set's cold variant (caches flushed before each timed call).

    Parameters
    ----------
    entry : dict
        A set's summary.

    Returns
    -------
    str
        ``S.SSx``, with the pairs it compares when they differ from the table's; empty when not
        measured.
    """
    cold = entry.get("cold_cache")
    if not cold:
        return ""
    pairs = (cold["own"]["solver"], cold["external"]["solver"])
    named = "" if pairs == (entry["own"]["solver"], entry["external"]["solver"]) else \
        f" (`{pairs[0]}` / `{pairs[1]}`)"
    return f"{cold['speedup']:.2f}x{named}"


def pass_range(entry: dict[str, Any]) -> str:
    """``lowest-highest x`` of the per-pass speedups (``pass_speedups``).

    Parameters
    ----------
    entry : dict
        A set's or a scene's summary.

    Returns
    -------
    str
        The range; empty with one pass.
    """
    speedups = entry.get("pass_speedups", [])
    return f"{min(speedups):.2f}-{max(speedups):.2f}x" if speedups else ""


def target_sentence(target: float, held: Sequence[str], missed: Sequence[str],
                    thing: str, undecided: Sequence[str] = ()) -> str:
    """Which of the ``thing``s (sets, scenes) meet the ``target`` x speedup, in one sentence.

    Parameters
    ----------
    target : float
        The speedup asked.
    held, missed : sequence of str
        The names where the target holds, and where it does not.
    thing : str
        What the names are, singular (``set``, ``scene``).
    undecided : sequence of str, optional
        The names without a verdict (one side not measured there); none by default.

    Returns
    -------
    str
        The sentence: "every" only where every name has a verdict and all hold, "no" where
        none holds, and never a verdict where there is none.
    """
    if not held and not missed:
        sentence = f"No {thing} has a verdict on the {target:g}x target"
    elif not missed:
        scope = f"every {thing} with a verdict" if undecided else f"every {thing}"
        sentence = f"The {target:g}x target holds on {scope}: {', '.join(held)}"
    elif not held:
        sentence = f"The {target:g}x target holds on no {thing}; it does not hold on: " \
                   f"{', '.join(missed)}"
    else:
        sentence = f"The {target:g}x target holds on: {', '.join(held)}; it does not hold " \
                   f"on: {', '.join(missed)}"
    if undecided:
        sentence += f"; no verdict (one side not measured) on: {', '.join(undecided)}"
    return sentence + "."


def both_solve_phrase(common_speedup: float, thing: str) -> str:
    """pi-robust's speedup on the ``thing``s that both pairs solve, as a phrase.

    Parameters
    ----------
    common_speedup : float
        The speedup over what both pairs solve; not finite when they solve nothing in common.
    thing : str
        What was solved, singular (``problem``, ``step``).

    Returns
    -------
    str
        ``on the {thing}s both pairs solve it is N.NNx``, or ``no {thing} did both solve``.
    """
    if math.isfinite(common_speedup):
        return f"on the {thing}s both pairs solve it is {common_speedup:.2f}x"
    return f"no {thing} did both solve"


def problem_batches(problems: Sequence[ImpactProblem | FrictionalProblem], size: int,
                    max_contacts: int = BATCH_CONTACTS
                    ) -> list[list[ImpactProblem | FrictionalProblem]]:
    """Consecutive problems in batches whose solves are timed together.

    Each batch is of one set, at most ``size`` problems, and no more than ``max_contacts``
    contacts in all unless it holds a single problem (a large problem's pairs are timed with
    each other only: its solves take milliseconds, and a pair far slower than the fastest
    leaves the set after each batch).

    Parameters
    ----------
    problems : sequence of ImpactProblem or FrictionalProblem
        The problems, in order.
    size : int
        Problems per batch at most.
    max_contacts : int, optional
        Contacts per batch at most; BATCH_CONTACTS by default.

    Returns
    -------
    list of list
        The batches, in order.
    """
    grouped: list[list[ImpactProblem | FrictionalProblem]] = []
    for problem in problems:
        last = grouped[-1] if grouped else []
        if (last and len(last) < size and set_of(last[0]) == set_of(problem)
                and sum(one.n_contacts for one in last) + problem.n_contacts <= max_contacts):
            last.append(problem)
        else:
            grouped.append([problem])
    return grouped


def head_to_head(folder: str | Path, bench: pd.DataFrame, repeats: int = HEAD_TO_HEAD_REPEATS,
                 candidates: int = HEAD_TO_HEAD_CANDIDATES,
                 progress: Callable[[str], None] | None = None,
                 passes: int = HEAD_TO_HEAD_PASSES,
                 out_of_running: float = HEAD_TO_HEAD_OUT_OF_RUNNING,
                 cold_repeats: int = HEAD_TO_HEAD_COLD_REPEATS,
                 batch_problems: int = HEAD_TO_HEAD_BATCH_PROBLEMS,
                 solve_cap_s: float = HEAD_TO_HEAD_SOLVE_CAP_S) -> dict[str, Any]:
    """The JSON object of ``qpbench head-to-head``: rows (each pass's), per-set summary, Markdown.

    The problems are taken in the order of their sets in SETS (:func:`set_rank`), within a set
    fewer contacts first, and timed in batches (:func:`problem_batches` of
    ``batch_problems``), every running pair on every problem of a batch in one interleaved
    schedule (:func:`measure_batch`, with ``cold_repeats`` cache-flushed calls beside);
    external pairs leave a set after a batch as :class:`Running` says, with
    ``limit = out_of_running`` (infinite: every pair runs on every problem) and
    ``cap_s = solve_cap_s``, the same cap under which a solve whose warm-up took longer is
    timed no further: in the later passes its pair is not run on that problem again, and its
    row stands for each pass (a pair without a pace keeps running on the set's other
    problems).

    Parameters
    ----------
    folder : str or Path
        The problem folder built from ``problems/head_to_head.toml``.
    bench : pd.DataFrame
        The main benchmark's rows, for :func:`fastest_external`.
    repeats : int, optional
        Timed repeats per solve; HEAD_TO_HEAD_REPEATS by default.
    candidates : int, optional
        Fastest external impact pairs compared; HEAD_TO_HEAD_CANDIDATES by default.
    progress : callable or None, optional
        Told a line before each batch; None (default) for none.
    passes : int, optional
        Whole passes, one after another; HEAD_TO_HEAD_PASSES by default.
    out_of_running : float, optional
        The limit of :class:`Running`; HEAD_TO_HEAD_OUT_OF_RUNNING by default.
    cold_repeats : int, optional
        Cache-flushed calls per solve; HEAD_TO_HEAD_COLD_REPEATS by default.
    batch_problems : int, optional
        Problems per batch at most; HEAD_TO_HEAD_BATCH_PROBLEMS by default.
    solve_cap_s : float, optional
        Seconds of a warm-up past which a solve is timed no further and its pair leaves the
        set (infinite: none); HEAD_TO_HEAD_SOLVE_CAP_S by default.

    Returns
    -------
    dict
        The settings, the pairs chosen (``candidates``), ``rows``, ``summary``,
        ``few_contacts`` (``few_contacts.few_contacts_summary``), ``markdown``,
        the problem count, the generated problems' seeds per family and the sets not measured.
    """
    chosen = fastest_external(bench, candidates, ACCURACY)
    # fewer contacts first within a set: a pair too slow leaves before the largest problems
    problems = sorted((problem for problem in files.load_all(files.find([str(folder)]))
                       if set_of(problem) is not None),
                      key=lambda problem: (set_rank(problem), problem.n_contacts))
    specs = {"impact": [get(key) for key in (*OWN_IMPACT, *chosen["impact"])],
             "frictional": [get(key, "frictional")
                            for key in (*OWN_FRICTIONAL, *chosen["frictional"])]}
    # a hard family's own fastest pair, on that family's set (named by the family) only
    own_set_specs = {family: [get(key) for key in keys]
                     for family, keys in chosen["families"].items()}
    rows: list[dict[str, Any]] = []
    running = Running(out_of_running, cap_s=solve_cap_s)
    batches = problem_batches(problems, batch_problems)
    # (pair, problem) -> the row of its solve over the cap, which later passes repeat
    over_cap: dict[tuple[str, str], dict[str, Any]] = {}
    with accuracy_table.overridden("staggered", max_outer=STAGGERED_MAX_OUTER):
        for pass_number in range(passes):
            done = 0
            for batch in batches:
                done += len(batch)
                if progress is not None:
                    progress(f"pass {pass_number + 1}/{passes} [{done}/{len(problems)}] "
                             f"{batch[-1].name}")
                pairs = [(spec, problem) for problem in batch for spec in (
                    specs["frictional"] if isinstance(problem, FrictionalProblem)
                    else specs["impact"] + own_set_specs.get(str(set_of(problem)), []))
                    if spec.solve is not None
                    and running.running(set_of(problem, spec.formulation), spec.key)]
                repeated = [over_cap[(spec.key, problem.name)] for spec, problem in pairs
                            if (spec.key, problem.name) in over_cap]
                timed = [(spec, problem) for spec, problem in pairs
                         if (spec.key, problem.name) not in over_cap]
                measured = measure_batch(timed, repeats, pass_number=pass_number,
                                         cold_repeats=cold_repeats,
                                         cap_s=solve_cap_s) if timed else []
                over_cap.update(((one["solver"], one["problem"]), one) for one in measured
                                if one.get("over_cap"))
                measured += [{**one, "pass": pass_number} for one in repeated]
                rows += measured
                for set_name in {one["set"] for one in measured}:
                    running.update(rows, set_name)
    summary = summarize(rows, running.out)
    few_contacts = few_contacts_summary(rows, UNDECIDED)
    seeds = generated_seeds(problems)
    return {"accuracy": ACCURACY, "repeats": repeats, "cold_repeats": cold_repeats,
            "batch_problems": batch_problems, "flush_bytes": flush_bytes() if cold_repeats
            else 0, "passes": passes, "candidates": chosen,
            "staggered_max_outer": STAGGERED_MAX_OUTER, "out_of_running": out_of_running,
            "solve_cap_s": solve_cap_s,
            "target_speedup": TARGET_SPEEDUP, "rows": rows, "summary": summary,
            "few_contacts": few_contacts,
            "markdown": markdown(summary, repeats, passes, out_of_running, cold_repeats,
                                 seeds, few_contacts, solve_cap_s) if rows else "",
            "problems": len(problems), "seeds": seeds,
            "unmeasured": [name for name in SETS if not any(r["set"] == name for r in rows)]}
