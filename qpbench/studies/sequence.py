"""Sequence mode: every solver replays a captured scene, warm-started from its own answers.

The ``warm`` mode of ``qpbench run`` starts from the impulses a simulator carried into a
captured step (only scenes that cache impulses have them), the same vector for every solver.
Here a scene is simulated with ``--capture`` semantics (one problem file per impact step,
named in order, each carrying ``data["contact_keys"]``: the identity of every contact, stable
across steps), and then each solver solves the problems in order twice (the pairs take turns
step by step: every pair solves a step before any pair solves the next one, so that a drift in
the machine's speed during a scene falls on all pairs alike):

* ``cold``: no warm start;
* ``sequence``: from the solver's OWN answer of the previous captured step, restricted to the
  contacts that persist (matched by their keys), zero on new contacts. The first step of a
  sequence, a step that shares no contact with the previous captured problem and a step after
  a non-finite answer start cold: there is nothing of the solver's own to carry. Consecutive
  captured problems are matched even when the simulator had steps without an impact between
  them (those solve l = 0 and change nothing the solver could carry).

Every solve goes through the one stopwatch (``qpbench.solvers.run.call_solver``: ``time_s``),
the fastest of ``repeats`` (fewer once they have taken ``REPEAT_BUDGET_S``) timed under the
timing protocol of docs/design.md section 7 (``qpbench.bench.repeats.time_interleaved``):
the cold and sequence solves of a step by every pair are timed together, after one untimed
warm-up per pair, in rounds whose order rotates, so that no repeat follows a repeat of the
same pair (with a single pair, its two solves alternate); it is judged by qpbench
(``judge``: residual at the requested accuracy). A solver that does not take warm starts
(``SolverSpec.warm_start`` false) gets the same vector and ignores it, so its sequence times
are cold times measured again.

The whole replay of every scene runs ``passes`` times, one pass after another (the captures
are made once), each pass from cold: a host's speed drifts over minutes, so each pass alone
gives a speedup and their range shows how far the drift moves it. The summaries keep each
step's fastest solve over the passes, in each mode (``fastest_over_passes``), as
head-to-head does; the target is met when the speedup of those, and of every pass alone, is
at least ``TARGET_SPEEDUP``.

Summaries charge a failed solve with the largest time of any solve of the measurement (the
report's rule: failing quickly never looks fast) and use the report's shifted geometric mean
(``qpbench.bench.stats``). A pair stops on a scene, and is left out of every summary (named in
the report, with where and why), so that all pairs compared solved the same steps, when its
solves there add up to more than ``SCENE_BUDGET_S``, or (an external pair) to more than
``out_of_running`` times those of the fastest warm-startable external pair that solved every
step so far, once ``PACE_STEPS`` steps are done: it cannot be the fastest, and replaying it
in every pass would take most of the sequence's time, so it leaves as the head-to-head's
pairs leave a set (``qpbench.studies.head_to_head.Running``).
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from qpbench.bench.defaults import (
    REPEATS,
    SEQUENCE_ACCURACY,
    SEQUENCE_OUT_OF_RUNNING,
    SEQUENCE_PASSES,
    SEQUENCE_STEPS,
    TARGET_SPEEDUP,
)
from qpbench.bench.repeats import REPEAT_BUDGET_S, Timing, fastest_output, time_interleaved
from qpbench.bench.stats import OWN_BACKEND, SHIFT_FACTOR, shifted_geometric_mean
from qpbench.errors import InputError
from qpbench.inner_solvers import choose_by_name
from qpbench.problem import files
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes import load_scene
from qpbench.simulation.operators import InnerSolveFailed
from qpbench.simulation.stepper import Simulator
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import all_solvers
from qpbench.solvers.run import BELOW_FLOOR, judge
from qpbench.studies.head_to_head import both_solve_phrase, pass_range, target_sentence

OWN = "pi-robust/lcp"
# the shared SCISim scenes with many consecutive impacts (box packings; the butterfly's
# three-ball chain), whose elastic impacts rarely repeat a contact, and a pile of 30 balls
# resting under gravity (``circle_pile(30, "ql")`` of qpbench.simulation.scaling), whose
# contacts persist from step to step as in most of a simulation's life
DEFAULT_SCENES = (
    "problems/scenes/ura/balls_in_box_100.xml",
    "problems/scenes/ura/10_balls_in_box.xml",
    "problems/scenes/scisim/butterfly.xml",
    "problems/scenes/piles/circle_pile_30.xml",
)
KEYS = "contact_keys"
# time steps simulated per requested impact step at most (scenes with quiet stretches)
STEP_BUDGET = 40
# a pair's time_s on one scene (cold and sequence solves) past which it stops there: far
# beyond the fastest pairs (well under a second), it keeps solvers that take seconds per
# solve on degenerate piles (cvxpy with IPOPT) from taking the benchmark's time
SCENE_BUDGET_S = 30.0
# steps of a scene every pair solves before one leaves for being far behind the fastest: one
# step's ratio says little (a dense method's lag grows and shrinks with a step's contacts)
PACE_STEPS = 5


# --- the sequence ---------------------------------------------------------------------------
def capture(scene_path: str | os.PathLike[str], folder: str | os.PathLike[str],
            steps: int) -> list[Path]:
    """Simulate ``scene_path`` with capture into ``folder`` until ``steps`` impacts are written.

    The simulation also stops after ``STEP_BUDGET * steps`` time steps, at the scene's end, or
    when an inner solve fails.

    Parameters
    ----------
    scene_path : str or os.PathLike
        The scene file, simulated with its own inner solver.
    folder : str or os.PathLike
        The folder the problem files are written to (made if missing).
    steps : int
        The impact problems wanted.

    Returns
    -------
    list of Path
        The problem files in ``folder``, in name (step) order.
    """
    scene = load_scene(scene_path)
    simulator = Simulator(scene, choose_by_name(None), capture=folder)
    Path(folder).mkdir(parents=True, exist_ok=True)
    limit = STEP_BUDGET * steps
    if scene.end_time is not None:
        limit = min(limit, simulator.step_count(None, None))
    while simulator.captured < steps and simulator.step_index < limit:
        try:
            simulator.step()
        except InnerSolveFailed:
            break
    return sorted(Path(folder).glob(f"*{files.SUFFIX}"))


def load_sequence(paths: Iterable[str | os.PathLike[str]]) -> list[ImpactProblem]:
    """The captured problems in file-name order (the capture names them by step).

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        The problem files.

    Returns
    -------
    list of ImpactProblem
        The problems, each with its contact keys.

    Raises
    ------
    InputError
        When a file is not a frictionless impact problem or carries no contact keys.
    """
    problems = []
    for path in sorted(Path(p) for p in paths):
        problem = files.load(path)
        if not isinstance(problem, ImpactProblem):
            raise InputError(str(path), "sequence mode takes frictionless impact problems")
        if KEYS not in problem.data:
            raise InputError(str(path), "captured without contact keys (capture it again)")
        problems.append(problem)
    return problems


def step_of(problem: ImpactProblem) -> int | None:
    """The simulation step a captured problem came from, as its metadata says.

    Parameters
    ----------
    problem : ImpactProblem
        A captured problem.

    Returns
    -------
    int or None
        The step; None when the metadata has no integer ``step``.
    """
    step = problem.metadata.get("step")
    return int(step) if isinstance(step, int | np.integer) else None


def carried(previous_keys: np.ndarray, previous_impulses: np.ndarray,
            keys: np.ndarray) -> tuple[np.ndarray, int]:
    """(warm start, persisting contacts): the previous answer on the contacts that persist.

    Contacts are matched by their keys; new contacts start at zero.

    Parameters
    ----------
    previous_keys : np.ndarray
        (m,) contact keys of the previous captured problem.
    previous_impulses : np.ndarray
        (m,) the solver's answer there.
    keys : np.ndarray
        (n,) contact keys of this problem.

    Returns
    -------
    tuple of (np.ndarray, int)
        The (n,) warm start, and how many of the contacts persist.
    """
    by_key = dict(zip(np.asarray(previous_keys).tolist(),
                      np.asarray(previous_impulses, dtype=float).tolist(), strict=True))
    warm = np.array([by_key.get(key, 0.0) for key in np.asarray(keys).tolist()], dtype=float)
    persisting = sum(1 for key in np.asarray(keys).tolist() if key in by_key)
    return warm, persisting


FIGURES = ("status", "success", "residual", "iterations", "time_s", "solver_status")


def _figures(row: dict[str, Any]) -> dict[str, Any]:
    """A judged row's figures that a step's row keeps, per mode."""
    return {name: row[name] for name in FIGURES}


def replay(spec: SolverSpec, problems: Sequence[ImpactProblem],
           accuracy: float = SEQUENCE_ACCURACY, scene: str = "", budget_s: float = math.inf,
           repeats: int = REPEATS) -> list[dict[str, Any]]:
    """One row per step: the cold solve and the sequence solve of ``spec`` (module docstring).

    Each is the fastest of ``repeats``; it stops early, with fewer rows than problems, once
    those ``time_s`` on this scene add up to more than ``budget_s``.

    Parameters
    ----------
    spec : SolverSpec
        The pair replayed.
    problems : sequence of ImpactProblem
        The captured problems, in order.
    accuracy : float, optional
        The level asked and judged; SEQUENCE_ACCURACY by default.
    scene : str, optional
        The scene's name, for the rows; empty by default.
    budget_s : float, optional
        Seconds of solves on this scene past which the pair stops; no budget by default.
    repeats : int, optional
        Timed calls per solve; REPEATS by default.

    Returns
    -------
    list of dict
        The rows of :func:`replayed_step`.
    """
    return replay_side_by_side([spec], problems, accuracy, scene, budget_s, repeats)


def replay_side_by_side(specs: Sequence[SolverSpec], problems: Sequence[ImpactProblem],
                        accuracy: float = SEQUENCE_ACCURACY, scene: str = "",
                        budget_s: float = math.inf, repeats: int = REPEATS,
                        progress: Callable[[str], None] | None = None,
                        out_of_running: float = math.inf, stopped: dict[str, str] | None = None
                        ) -> list[dict[str, Any]]:
    """:func:`replay` of every pair of ``specs`` at once, step by step.

    Each step is solved by every pair before the next step is, so that a change in the
    machine's speed during a scene falls on all pairs alike rather than on the pairs replayed at
    that moment, and the step's cold and sequence solves of every pair are timed together under
    the timing protocol (:func:`replayed_step`). Each pair keeps its own previous answer and its
    own budget; after each step the pairs of :func:`leavers` stop (past ``budget_s``, or, from
    the ``PACE_STEPS``-th step on, far behind the fastest warm-startable external pair).

    Parameters
    ----------
    specs : sequence of SolverSpec
        The pairs replayed.
    problems : sequence of ImpactProblem
        The captured problems, in order.
    accuracy : float, optional
        The level asked and judged; SEQUENCE_ACCURACY by default.
    scene : str, optional
        The scene's name, for the rows and the progress; empty by default.
    budget_s : float, optional
        Seconds of solves on this scene past which a pair stops; no budget by default.
    repeats : int, optional
        Timed calls per solve; REPEATS by default.
    progress : callable or None, optional
        Told a line before each step; None (default) for none.
    out_of_running : float, optional
        The ratio to the fastest warm-startable external pair's time past which an external
        pair stops; inf (default): never.
    stopped : dict of str to str or None, optional
        Filled with the pairs that stopped: where (scene, steps solved of all) and why; None
        (default): not told.

    Returns
    -------
    list of dict
        One row per (step, pair) solved, step by step.
    """
    rows = []
    previous: dict[str, tuple[ImpactProblem, np.ndarray | None]] = {}
    spent = dict.fromkeys((spec.key for spec in specs), 0.0)
    clean = dict.fromkeys((spec.key for spec in specs), True)
    running = list(specs)
    for index, problem in enumerate(problems):
        if not running:
            break
        if progress is not None:
            progress(f"{scene}: step {index + 1} of {len(problems)}")
        for spec, (row, answer, seconds) in zip(running, replayed_step(
                running, problem, index, previous, accuracy, scene, repeats), strict=True):
            rows.append(row)
            spent[spec.key] += seconds
            clean[spec.key] &= bool(row["cold_success"] and row["sequence_success"])
            previous[spec.key] = (problem, answer)
        leaving = leavers(running, spent, clean, budget_s,
                          out_of_running if index + 1 >= PACE_STEPS else math.inf)
        if stopped is not None:
            stopped.update((key, f"{scene}: {index + 1} of {len(problems)} steps, {why}")
                           for key, why in leaving.items())
        running = [spec for spec in running if spec.key not in leaving]
    return rows


def leavers(running: Sequence[SolverSpec], spent: dict[str, float], clean: dict[str, bool],
            budget_s: float, out_of_running: float) -> dict[str, str]:
    """The pairs that stop on a scene after a step, each with why.

    A pair stops past ``budget_s`` seconds of solves on the scene; an external pair also when
    its seconds there exceed ``out_of_running`` times those of the fastest warm-startable
    external pair that solved every step so far in both modes (the pace; so the fastest such
    pair never leaves, nor does a pair written here).

    Parameters
    ----------
    running : sequence of SolverSpec
        The pairs that solved the step.
    spent : dict of str to float
        Per pair key, the ``time_s`` of its cold and sequence solves on the scene, summed.
    clean : dict of str to bool
        Per pair key, whether every solve of it on the scene succeeded.
    budget_s : float
        Seconds of solves per scene past which a pair stops.
    out_of_running : float
        The ratio to the pace past which an external pair stops; inf: never.

    Returns
    -------
    dict of str to str
        Per pair key that stops, the reason.
    """
    paces = [spec.key for spec in running
             if spec.backend != OWN_BACKEND and spec.warm_start and clean[spec.key]]
    fastest = min(paces, key=lambda key: spent[key], default=None)
    leaving = {}
    for spec in running:
        seconds = spent[spec.key]
        if seconds > budget_s:
            leaving[spec.key] = f"past {budget_s:g} s of solves"
        elif (fastest is not None and spec.backend != OWN_BACKEND and spent[fastest] > 0
              and seconds > out_of_running * spent[fastest]):
            leaving[spec.key] = f"{seconds / spent[fastest]:.0f}x the time of `{fastest}` there"
    return leaving


def replayed_step(specs: Sequence[SolverSpec], problem: ImpactProblem, index: int,
                  previous: dict[str, tuple[ImpactProblem, np.ndarray | None]],
                  accuracy: float, scene: str, repeats: int
                  ) -> list[tuple[dict[str, Any], np.ndarray | None, float]]:
    """Per pair of ``specs``: (row, the answer to carry, time_s spent) of one step.

    Its cold solve and its sequence solve from its own ``previous`` (problem, finite answer or
    None), each the fastest of ``repeats``, all of the step's timed calls in one interleaved
    schedule (``qpbench.bench.repeats.time_interleaved``: one untimed warm-up per pair, then
    rounds in a rotated order; the two solves of a pair are one (problem, pair) unit).

    Parameters
    ----------
    specs : sequence of SolverSpec
        The pairs still running.
    problem : ImpactProblem
        The step's problem.
    index : int
        The step's position in the sequence.
    previous : dict of str to (ImpactProblem, np.ndarray or None)
        Per pair key, the previous problem it solved and its finite answer there (None: start
        cold).
    accuracy : float
        The level asked and judged.
    scene : str
        The scene's name, for the rows.
    repeats : int
        Timed calls per solve.

    Returns
    -------
    list of (dict, np.ndarray or None, float)
        Per pair, in the order of ``specs``: the row (cold and sequence figures), the sequence
        answer when finite, and the ``time_s`` of both solves.
    """
    starts: list[tuple[np.ndarray | None, int]] = []
    for spec in specs:
        warm, persisting = None, 0
        earlier = previous.get(spec.key)
        if earlier is not None and earlier[1] is not None:
            warm, persisting = carried(earlier[0].data[KEYS], earlier[1], problem.data[KEYS])
            if not persisting:
                warm = None
        starts.append((warm, persisting))
    timings = [Timing(spec, problem) for spec in specs] + [
        Timing(spec, problem, warm) for spec, (warm, _) in zip(specs, starts, strict=True)]
    outputs = time_interleaved(timings, repeats, accuracy)
    results = []
    for number, (spec, (warm, persisting)) in enumerate(zip(specs, starts, strict=True)):
        cold_output = fastest_output(outputs[number])
        output = fastest_output(outputs[len(specs) + number])
        cold = judge(spec, problem, cold_output, accuracy)
        sequence = judge(spec, problem, output, accuracy)
        answer = output.impulses
        finite = answer is not None and answer.shape == (problem.n_contacts,) \
            and bool(np.all(np.isfinite(answer)))
        row = {
            "scene": scene, "problem": problem.name, "index": index, "step": step_of(problem),
            "contacts": problem.n_contacts, "persisting": persisting,
            "solver": f"{spec.name}/{spec.formulation}", "warm_startable": spec.warm_start,
            "warm_start_given": warm is not None,
            **{f"cold_{name}": value for name, value in _figures(cold).items()},
            **{f"sequence_{name}": value for name, value in _figures(sequence).items()},
        }
        results.append((row, (answer.copy() if finite else None),
                        cold_output.time_s + output.time_s))
    return results


# --- summaries ------------------------------------------------------------------------------
def _shift(rows: Sequence[dict[str, Any]]) -> float:
    """10 x the median over (problem, mode) of the fastest successful time (stats' rule)."""
    fastest: dict[tuple[str, str, str], float] = {}
    for row in rows:
        for mode in ("cold", "sequence"):
            if row[f"{mode}_success"]:
                key = (row["scene"], row["problem"], mode)
                fastest[key] = min(fastest.get(key, math.inf), row[f"{mode}_time_s"])
    values = [value for value in fastest.values() if value > 0]
    return SHIFT_FACTOR * float(np.median(values)) if values else 1.0


def summarize(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per solver: median and SGM of the charged times, cold and in sequence, and success rates.

    A failure is charged the largest time of the measurement. A step below its problem's
    double-precision residual floor (verdict ``below-floor`` in either mode: no solver can be
    judged there) is left out, as the report leaves such cells out.

    Parameters
    ----------
    rows : sequence of dict
        Rows of :func:`replayed_step` (one per step and pair).

    Returns
    -------
    list of dict
        One entry per solver, in order of first appearance.
    """
    rows = [row for row in rows
            if BELOW_FLOOR not in (row["cold_status"], row["sequence_status"])]
    times = [row[f"{mode}_time_s"] for row in rows for mode in ("cold", "sequence")]
    finite = [t for t in times if isinstance(t, float) and math.isfinite(t)]
    charge = max(finite, default=1.0)
    shift = _shift(rows)
    summary = []
    for solver in dict.fromkeys(row["solver"] for row in rows):
        mine = [row for row in rows if row["solver"] == solver]
        entry: dict[str, Any] = {"solver": solver, "warm_startable": mine[0]["warm_startable"],
                                 "solves": len(mine),
                                 "warm_starts": sum(row["warm_start_given"] for row in mine)}
        for mode in ("cold", "sequence"):
            charged = [row[f"{mode}_time_s"] if row[f"{mode}_success"] else charge
                       for row in mine]
            entry[f"{mode}_median_s"] = float(np.median(charged))
            entry[f"{mode}_sgm_s"] = shifted_geometric_mean(charged, shift)
            entry[f"{mode}_success_rate"] = float(np.mean([row[f"{mode}_success"]
                                                           for row in mine]))
        summary.append(entry)
    return summary


def fastest_over_passes(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (scene, step, pair), each mode's figures from its fastest pass.

    In each mode (cold, sequence), the figures of the pass whose ``time_s`` was the smallest,
    as head-to-head keeps each problem's fastest row (rows without a ``pass`` are one pass
    already).

    Parameters
    ----------
    rows : sequence of dict
        Rows of every pass.

    Returns
    -------
    list of dict
        The kept rows, without ``pass``.
    """
    kept: dict[tuple[str, int, str], dict[str, Any]] = {}
    for row in rows:
        key = (row["scene"], row["index"], row["solver"])
        if key not in kept:
            kept[key] = {name: value for name, value in row.items() if name != "pass"}
            continue
        best = kept[key]
        for mode in ("cold", "sequence"):
            if row[f"{mode}_time_s"] < best[f"{mode}_time_s"]:
                for name in FIGURES:
                    best[f"{mode}_{name}"] = row[f"{mode}_{name}"]
    return list(kept.values())


def comparison(summary: Sequence[dict[str, Any]], own: str = OWN) -> dict[str, Any]:
    """pi-robust against the fastest warm-startable external pair (charged SGM), in each mode.

    ``ratio = external / own`` (above 1: pi-robust faster).

    Parameters
    ----------
    summary : sequence of dict
        The per-solver summary of :func:`summarize`.
    own : str, optional
        Our pair's key; OWN by default.

    Returns
    -------
    dict
        ``own``, ``target_speedup``, per mode (``cold``, ``sequence``) the fastest external pair,
        both SGMs and the speedup (None when a side is missing), and ``target_met``.
    """
    by_solver = {entry["solver"]: entry for entry in summary}
    mine = by_solver.get(own)
    external = [entry for entry in summary if entry["warm_startable"]
                and entry["solver"] != own and not _own_backend(entry["solver"], OWN_BACKEND)]
    result: dict[str, Any] = {"own": own, "target_speedup": TARGET_SPEEDUP}
    for mode in ("cold", "sequence"):
        if mine is None or not external:
            result[mode] = None
            continue
        best = min(external, key=lambda entry: entry[f"{mode}_sgm_s"])
        result[mode] = {"fastest_external": best["solver"],
                        "external_sgm_s": best[f"{mode}_sgm_s"],
                        "own_sgm_s": mine[f"{mode}_sgm_s"],
                        "speedup": best[f"{mode}_sgm_s"] / mine[f"{mode}_sgm_s"]}
    seq = result["sequence"]
    result["target_met"] = bool(seq is not None and seq["speedup"] >= TARGET_SPEEDUP
                                and mine is not None and mine["sequence_success_rate"] == 1.0)
    return result


def over_passes(rows: Sequence[dict[str, Any]]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(summary, comparison) of the rows' :func:`fastest_over_passes`.

    With more than one pass the comparison also holds ``pass_speedups``, the sequence speedup of
    each pass's rows alone (NaN where a pass lacks pi-robust or an external pair), and its
    target is met only when every one of them is at least ``TARGET_SPEEDUP`` too. The sequence
    speedup over the steps both pairs solve (``common_speedup``, no failure charged) must reach
    it as well; ``met_by_failures`` says when only the external pair's failures lifted it.

    Parameters
    ----------
    rows : sequence of dict
        Rows of every pass.

    Returns
    -------
    tuple of (list of dict, dict)
        The per-solver summary and the comparison.
    """
    fastest = fastest_over_passes(rows)
    summary = summarize(fastest)
    compared = comparison(summary)
    figures = compared["sequence"]
    compared["met_by_failures"] = False
    if figures is not None:  # the target met by the external pair's charged failures alone
        figures["common_speedup"] = _common_speedup(fastest, compared["own"],
                                                    figures["fastest_external"])
        compared["met_by_failures"] = compared["target_met"] and not \
            figures["common_speedup"] >= TARGET_SPEEDUP
        compared["target_met"] = compared["target_met"] and not compared["met_by_failures"]
    passes = sorted({row["pass"] for row in rows if "pass" in row})
    if len(passes) > 1:
        speedups = []
        for number in passes:
            alone = comparison(summarize([row for row in rows if row.get("pass") == number]))
            speedups.append(alone["sequence"]["speedup"] if alone["sequence"] else math.nan)
        compared["pass_speedups"] = speedups
        compared["target_met"] = compared["target_met"] and all(
            speedup >= TARGET_SPEEDUP for speedup in speedups)
    return summary, compared


def _common_speedup(rows: Sequence[dict[str, Any]], own: str, external: str) -> float:
    """SGM of ``external``'s sequence times over ``own``'s, on the steps both solve in sequence
    mode (NaN when there is none): the speedup without the charges of failures."""
    solved = {solver: {(row["scene"], row["problem"]): row["sequence_time_s"] for row in rows
                       if row["solver"] == solver and row["sequence_success"]}
              for solver in (own, external)}
    both = sorted(solved[own].keys() & solved[external].keys())
    if not both:
        return math.nan
    shift = _shift(rows)
    return shifted_geometric_mean([solved[external][key] for key in both], shift) / \
        shifted_geometric_mean([solved[own][key] for key in both], shift)


def by_scene(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per scene: the comparison of :func:`over_passes` on that scene's rows alone.

    Parameters
    ----------
    rows : sequence of dict
        Rows of every scene and pass.

    Returns
    -------
    list of dict
        One comparison per scene, with ``scene``, in order of first appearance.
    """
    return [{"scene": scene, **over_passes([row for row in rows if row["scene"] == scene])[1]}
            for scene in dict.fromkeys(row["scene"] for row in rows)]


def _per_pass(compared: dict[str, Any]) -> str:
    """`` (per pass: lowest-highest x)``, or nothing with one pass."""
    spread = pass_range(compared)
    return f" (per pass: {spread})" if spread else ""


def _own_backend(solver: str, own_backend: str) -> bool:
    return any(spec.key == solver and spec.backend == own_backend for spec in all_solvers())


def markdown(summary: Sequence[dict[str, Any]], compared: dict[str, Any],
             scenes: Sequence[dict[str, Any]], accuracy: float,
             per_scene: Sequence[dict[str, Any]] = (), stopped: dict[str, str] | None = None,
             budget_s: float = SCENE_BUDGET_S, repeats: int = REPEATS, passes: int = 1,
             out_of_running: float = math.inf) -> str:
    """The sequence study as a Markdown section: protocol, scenes, table, verdicts.

    Parameters
    ----------
    summary : sequence of dict
        The per-solver summary.
    compared : dict
        The comparison over all scenes (:func:`over_passes`).
    scenes : sequence of dict
        Per scene: its name, impact steps, contact range and share of persisting contacts.
    accuracy : float
        The level asked.
    per_scene : sequence of dict, optional
        The comparisons scene by scene (:func:`by_scene`); none by default.
    stopped : dict of str to str or None, optional
        The pairs that stopped, where and why; None (default) for none.
    budget_s : float, optional
        The budget per scene; SCENE_BUDGET_S by default.
    repeats : int, optional
        Timed calls per solve; REPEATS by default.
    passes : int, optional
        Replays of every scene; 1 by default.
    out_of_running : float, optional
        The ratio to the fastest warm-startable external pair past which an external pair
        stops; inf (default): none.

    Returns
    -------
    str
        The ``## Sequence mode`` section.
    """
    lines = [
        "## Sequence mode: warm starts from each solver's own previous answer\n",
        "Each captured scene is replayed in order, every pair solving a step before the next "
        "step (so that a drift in the machine's speed falls on all pairs alike); every solver "
        "solves each step cold and "
        "warm-started from its own answer of the previous step on the contacts that persist "
        f"(zero on new contacts), at accuracy {accuracy:g}, judged by qpbench's residual. "
        f"Times are `time_s` of the one stopwatch, the fastest of {repeats} repeats (fewer "
        f"once they took {REPEAT_BUDGET_S:g} s), never back to back: a step's cold and "
        "sequence solves by every pair are timed together, after one untimed warm-up per "
        "pair, in rounds of one call each whose order rotates"
        + (f", in each of {passes} replays of every scene, one after another; each step's "
           "fastest over the replays makes the table, in each mode, and *per pass* is the "
           "range of the speedups that each replay alone gives (the machine's speed drifts "
           "between them)" if passes > 1 else "")
        + "; a failed solve is charged the largest time of the measurement; SGM as in the "
        "report.\n",
        "Scenes: " + "; ".join(f"`{scene['scene']}` ({scene['steps']} impact steps, "
                               f"{scene['contacts_min']}-{scene['contacts_max']} contacts, "
                               f"{100 * scene.get('persisting_share', 0.0):.0f}% of a step's "
                               "contacts persist from the previous one)"
                               for scene in scenes) + ".\n",
        "| solver | warm start | cold median [ms] | cold SGM [ms] | cold success | "
        "sequence median [ms] | sequence SGM [ms] | sequence success | cold / sequence |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for entry in sorted(summary, key=lambda entry: entry["sequence_sgm_s"]):
        lines.append(
            f"| {entry['solver']} | {'yes' if entry['warm_startable'] else 'no'} | "
            f"{1e3 * entry['cold_median_s']:.3f} | {1e3 * entry['cold_sgm_s']:.3f} | "
            f"{100 * entry['cold_success_rate']:.0f}% | {1e3 * entry['sequence_median_s']:.3f} | "
            f"{1e3 * entry['sequence_sgm_s']:.3f} | {100 * entry['sequence_success_rate']:.0f}% | "
            f"{entry['cold_sgm_s'] / entry['sequence_sgm_s']:.2f}x |")
    lines.append("")
    if stopped:
        behind = (f", or once, from the scene's {PACE_STEPS}th step on, their solves there "
                  f"took more than {out_of_running:g} times those of the fastest warm-startable "
                  "external pair that solved every step so far: such a pair cannot be the "
                  "fastest" if math.isfinite(out_of_running) else "")
        lines.append(f"Pairs stopped on a scene (after {budget_s:g} s of solves there{behind}), "
                     "replayed no further and left out of the summaries: "
                     + "; ".join(f"`{key}` ({where})" for key, where in stopped.items())
                     + ".\n")
    for mode in ("cold", "sequence"):
        figures = compared.get(mode)
        if figures:
            lines.append(f"- {mode}: {compared['own']} SGM {1e3 * figures['own_sgm_s']:.3f} ms, "
                         f"fastest warm-startable external pair `{figures['fastest_external']}` "
                         f"{1e3 * figures['external_sgm_s']:.3f} ms: pi-robust is "
                         f"{figures['speedup']:.2f}x as fast"
                         + (f"{_per_pass(compared)}." if mode == "sequence" else "."))
    figures = compared.get("sequence")
    if figures is None:
        lines.append("\nThe target could not be judged (pi-robust or the external pairs were "
                     "not measured).")
    else:
        verdict = "holds" if compared["target_met"] else "does not hold"
        lines.append(f"\nThe target \"pi-robust at least {TARGET_SPEEDUP:g}x faster than the "
                     f"fastest warm-startable external pair in sequence mode\" {verdict} over "
                     f"all scenes together: measured {figures['speedup']:.2f}x against "
                     f"`{figures['fastest_external']}`{_per_pass(compared)}."
                     + (" The target asks it of every pass alone too." if passes > 1 else "")
                     + (f" It passes {TARGET_SPEEDUP:g}x only through that pair's failed "
                        "solves, each charged the largest time: "
                        + both_solve_phrase(figures["common_speedup"], "step") + "."
                        if compared.get("met_by_failures") else ""))
    if per_scene:
        lines += _per_scene_lines(per_scene, scenes)
    return "\n".join(lines) + "\n"


def _per_scene_lines(per_scene: Sequence[dict[str, Any]],
                     scenes: Sequence[dict[str, Any]]) -> list[str]:
    """The comparison scene by scene (each against its own fastest warm-startable pair)."""
    persisting = {scene["scene"]: scene.get("persisting_share", 0.0) for scene in scenes}
    lines = ["\nScene by scene (sequence mode, each against the fastest warm-startable external "
             "pair on that scene):\n",
             "| scene | contacts persisting | pi-robust SGM [ms] | fastest external pair | "
             "SGM [ms] | speedup | per pass | target |",
             "|---|---:|---:|---|---:|---:|---:|---|"]
    holds, fails = [], []
    for entry in per_scene:
        figures = entry.get("sequence")
        if figures is None:
            continue
        name = Path(entry["scene"]).stem
        (holds if entry["target_met"] else fails).append(name)
        lines.append(f"| `{name}` | {100 * persisting.get(entry['scene'], 0.0):.0f}% | "
                     f"{1e3 * figures['own_sgm_s']:.3f} | `{figures['fastest_external']}` | "
                     f"{1e3 * figures['external_sgm_s']:.3f} | {figures['speedup']:.2f}x | "
                     f"{pass_range(entry)} | {'met' if entry['target_met'] else 'not met'}"
                     f"{' (peer failures)' if entry.get('met_by_failures') else ''} |")
    lines.append(f"\n{target_sentence(TARGET_SPEEDUP, holds, fails, 'scene')} Where no contact "
                 "persists, a sequence solve is a cold solve.")
    return lines


def sequence(scenes: Sequence[str], specs: Sequence[SolverSpec], steps: int = SEQUENCE_STEPS,
             accuracy: float = SEQUENCE_ACCURACY,
             progress: Callable[[str], None] | None = None,
             budget_s: float = SCENE_BUDGET_S,
             repeats: int = REPEATS, passes: int = SEQUENCE_PASSES,
             out_of_running: float = SEQUENCE_OUT_OF_RUNNING) -> dict[str, Any]:
    """The JSON object of ``qpbench sequence``: rows, per-solver summary, comparison, Markdown.

    Per-step rows (each pass's, numbered in ``pass``), per-solver summary, the comparison with
    the target and a ``markdown`` section. A scene argument that is a folder is read as an
    existing capture; every scene is captured once and replayed ``passes`` times. A pair that
    stops on a scene in any pass (:func:`leavers`: past ``budget_s`` of solves there, or
    ``out_of_running`` times the fastest warm-startable external pair's time) is replayed no
    further and left out of every summary (``stopped``: where and why).

    Parameters
    ----------
    scenes : sequence of str
        Scene files to capture, or folders of an existing capture.
    specs : sequence of SolverSpec
        The pairs replayed.
    steps : int, optional
        Impact steps per scene; SEQUENCE_STEPS by default.
    accuracy : float, optional
        The level asked and judged; SEQUENCE_ACCURACY by default.
    progress : callable or None, optional
        Told a line before each step; None (default) for none.
    budget_s : float, optional
        Seconds of solves per scene past which a pair stops; SCENE_BUDGET_S by default.
    repeats : int, optional
        Timed calls per solve; REPEATS by default.
    passes : int, optional
        Replays of every scene; SEQUENCE_PASSES by default.
    out_of_running : float, optional
        The ratio past which an external pair stops; SEQUENCE_OUT_OF_RUNNING by default.

    Returns
    -------
    dict
        The settings, ``scenes``, ``summary``, ``comparison``, ``by_scene``, ``target_met``,
        ``rows``, ``stopped`` and ``markdown``.

    Raises
    ------
    InputError
        When a scene gives no impact, or a captured file is not a usable problem.
    """
    rows: list[dict[str, Any]] = []
    stopped: dict[str, str] = {}
    described = []
    captured: list[tuple[str, list[ImpactProblem]]] = []
    with tempfile.TemporaryDirectory(prefix="qpbench-sequence-") as scratch:
        for number, scene in enumerate(scenes):
            if Path(scene).is_dir():
                paths = sorted(Path(scene).glob(f"*{files.SUFFIX}"))[:steps]
            else:
                paths = capture(scene, Path(scratch) / str(number), steps)[:steps]
            problems = load_sequence(paths)
            if not problems:
                raise InputError(scene, "no impact was captured")
            counts = [problem.n_contacts for problem in problems]
            shared = [np.isin(now.data[KEYS], before.data[KEYS]).mean()
                      for before, now in zip(problems, problems[1:], strict=False)]
            described.append({"scene": str(scene), "steps": len(problems),
                              "contacts_min": min(counts), "contacts_max": max(counts),
                              "persisting_share": float(np.mean(shared)) if shared else 0.0})
            captured.append((str(scene), problems))
    for pass_number in range(passes):
        told = progress if progress is None or passes == 1 else (
            lambda text, number=pass_number: progress(f"pass {number + 1}/{passes} {text}"))
        for scene, problems in captured:
            running = [spec for spec in specs if spec.key not in stopped]
            replayed = replay_side_by_side(running, problems, accuracy, scene, budget_s,
                                           repeats, told, out_of_running, stopped)
            rows.extend({**row, "pass": pass_number} for row in replayed)
    rows = [row for row in rows if row["solver"] not in stopped]  # like with like
    summary, compared = over_passes(rows)
    per_scene = by_scene(rows)
    return {"title": "Sequence mode", "accuracy": accuracy, "steps": steps,
            "scenes": described, "summary": summary, "comparison": compared,
            "by_scene": per_scene, "target_met": compared["target_met"], "rows": rows,
            "stopped": stopped, "budget_s": budget_s, "out_of_running": out_of_running,
            "repeats": repeats, "passes": passes,
            "markdown": markdown(summary, compared, described, accuracy, per_scene, stopped,
                                 budget_s, repeats, passes, out_of_running)}
