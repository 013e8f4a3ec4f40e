"""What accuracy costs in a whole simulation (``qpbench sim-precision``).

Every scene is simulated once per (pair, accuracy level), with the scene's own effects
(friction, boxes, portals) and the pair as the inner solver of every operator that needs one.
A solver name maps to the pair of the scene's kind as :mod:`qpbench.inner_solvers` maps
``--solver`` (:func:`pair_for`): ``NAME/FORMULATION`` where it takes that kind, else NAME's
default pair of the kind (``osqp/dual`` on a frictional scene: ``osqp/staggered``); a name
with no pair of the kind (``nsgs`` on a frictionless scene) is a skipped row with the reason.

Each run records the inner solves' summed time and the run's wall time, and its final state
against a *reference run*: the same scene at the tightest level by the first pair of
:data:`REFERENCE_PAIRS` that ends the run with every inner solve accurate. ``position_error``,
``velocity_error`` and ``state_error`` measure the final positions and velocities against the
reference's in the mass norm (:mod:`qpbench.bench.final_states` defines them). Where SCISim's
own final state at the same step count is known (committed or shared records, matched to a
scene file by its bytes), the same measure against it is ``scisim_error``, and
``scisim_agrees`` applies the fidelity rule (positions within 1e-6, velocities within 1e-6 x
max(1, largest SCISim speed)).

Along the run, at the start of every step with contacts: the largest penetration, of a
circle's contact (ball-ball, ball-plane, ball-drum) and of a box against the planes and the
bodies it touches (:mod:`qpbench.simulation.overlap`), and for a
frictional scene the Coulomb natural-map residual of the accepted impulses and the
maximum-dissipation gap ``max_k |u_T,k| d_k |l_T,k + mu_k l_N,k sign(u_T,k)| / scale^2``
(how far the tangential impulse is from the one that dissipates most at the resulting sliding
velocity, times that velocity: zero when sticking or sliding against the velocity at the cone's
edge; ``d_k = (W_NN)_kk``, ``scale`` the problem's). The hook that measures them is timed and its
time taken out of ``wall_s``. Before its first timed run, each pair runs its first scene once
untimed, so that what only a process's first calls pay (imports, compiled kernels, caches)
falls on no level.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from qpbench.atomic import atomic_path
from qpbench.bench.final_states import (
    ScisimState,
    agrees_with_scisim,
    final_state,
    scene_digest,
    scisim_states,
    state_errors,
)
from qpbench.bench.plots import DPI, style
from qpbench.errors import QpbenchError, UnsupportedError
from qpbench.inner_solvers import chosen
from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.scenes import load_scene
from qpbench.scenes.model import FrictionSolver, ImpactOperator, Scene
from qpbench.simulation import contacts, overlap
from qpbench.simulation.operators import ChooseSolve, ChosenSolve
from qpbench.simulation.stepper import SimulationResult, Simulator, StepEvent
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.registry import get

WITHIN = 1e-6  # the table: the loosest level whose final state stays this close
FRICTIONAL, FRICTIONLESS = "frictional", "frictionless"
# the registry's kind of problem each scene kind poses
REGISTRY_KIND = {FRICTIONAL: "frictional", FRICTIONLESS: "impact"}
# the reference's pair, the first that runs the scene with every inner solve accurate: exact
# methods first (policy iteration ends on an exact active set; Lemke pivots)
REFERENCE_PAIRS = {FRICTIONLESS: ("pi-robust/lcp", "lemke/lcp", "clarabel/primal"),
                   FRICTIONAL: ("nsgs/nsgs", "lemke/lcp", "pi-robust/staggered")}
CIRCLE_KINDS = (contacts.BALL, contacts.PLANE, contacts.DRUM)
ERROR_FLOOR = 1e-17  # the figure draws a zero error here

Advance = Callable[[int, str | None], None]


def _silent(count: int, note: str | None) -> None:
    """A progress hook that says nothing."""


# --- pairs ---------------------------------------------------------------------------------
def scene_kind(scene: Scene) -> str:
    """Give the kind of a scene: ``frictional`` when it declares friction with mu > 0.

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    str
        FRICTIONAL or FRICTIONLESS.
    """
    return FRICTIONAL if scene.frictional else FRICTIONLESS


def pair_for(name: str, kind: str) -> tuple[SolverSpec | None, str | None]:
    """Find the pair that runs scenes of ``kind`` for the solver name ``name``, or say why none.

    ``NAME/FORMULATION`` itself when it takes that kind; else NAME's default pair of the kind
    (:func:`qpbench.solvers.registry.get`).

    Parameters
    ----------
    name : str
        A solver name, ``NAME`` or ``NAME/FORMULATION``.
    kind : str
        FRICTIONAL or FRICTIONLESS.

    Returns
    -------
    tuple of (SolverSpec or None, str or None)
        The pair and None, or None and why the name has no pair of the kind.

    Raises
    ------
    QpbenchError
        For an unknown name (one line).
    """
    registry_kind = REGISTRY_KIND[kind]
    try:
        return get(name, registry_kind), None
    except QpbenchError as error:
        if "/" not in name:
            if "takes no" in str(error):
                return None, str(error)
            raise
    try:
        return get(name.split("/", 1)[0], registry_kind), None
    except QpbenchError as error:
        if "takes no" in str(error):
            return None, f"solver '{name}': {error}"
        raise


def choose_pair(spec: SolverSpec) -> ChooseSolve:
    """Make a ChooseSolve giving every operator (and a friction solver) the pair ``spec``.

    Parameters
    ----------
    spec : SolverSpec
        The inner solver's pair.

    Returns
    -------
    ChooseSolve
        The choice the simulator calls per operator.
    """

    def choose(operator: ImpactOperator | FrictionSolver) -> ChosenSolve:
        return chosen(spec)

    return choose


def check_names(names: Iterable[str]) -> None:
    """Check that every solver name is known and has a usable pair of some kind.

    Parameters
    ----------
    names : iterable of str
        The solver names, ``NAME`` or ``NAME/FORMULATION``.

    Raises
    ------
    QpbenchError
        One line when a name is unknown, or has no usable pair of either kind.
    """
    for name in names:
        found = [pair_for(name, kind)[0] for kind in (FRICTIONLESS, FRICTIONAL)]
        if not any(found):
            raise QpbenchError(f"solver '{name}' takes neither frictionless nor frictional "
                               "problems")


# --- one run -------------------------------------------------------------------------------
@dataclass
class RunTally:
    """What the per-step hook measures along one run, and its own time."""

    max_penetration: float = 0.0
    coulomb_residual: float | None = None
    mdp_gap: float | None = None
    hook_s: float = 0.0


def mdp_gap(problem: FrictionalProblem, impulses: np.ndarray) -> float:
    """Compute the maximum-dissipation gap of one frictional answer (module docstring).

    Parameters
    ----------
    problem : FrictionalProblem
        The step's problem.
    impulses : numpy.ndarray
        The accepted impulses, normal then tangential (2n).

    Returns
    -------
    float
        The largest gap over the contacts over ``scale^2``; 0 without contacts.
    """
    if problem.n_contacts == 0:
        return 0.0
    normal, tangential = problem.split(impulses)
    u_tangential = problem.split(problem.u(impulses))[1]
    best = -problem.mu * normal * np.sign(u_tangential)
    gap = np.abs(u_tangential) * problem.diag_N * np.abs(tangential - best)
    return float(np.max(gap)) / problem.scale / problem.scale


def penetration(scene: Scene, event: StepEvent) -> float:
    """Find the deepest overlap at the step's start.

    Of a circle's contact (its gap), and of every box against the planes and against the
    bodies it has a contact with (:mod:`qpbench.simulation.overlap`).

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    event : StepEvent
        The step's positions, orientations and contacts.

    Returns
    -------
    float
        The depth; 0 if nothing overlaps.
    """
    found = event.contacts
    deepest = 0.0
    if found.count:
        gaps = found.gaps(event.positions, scene.bodies.radii, scene.plane_points,
                          scene.plane_normals, scene.drum_centers, scene.drum_radii)
        circles = np.isin(found.kind, CIRCLE_KINDS)
        deepest = max(0.0, -float(np.min(gaps[circles], initial=0.0)))
    if event.orientations is None or not np.any(scene.bodies.is_box):
        return deepest
    return max(deepest, box_overlap(scene, event.positions, event.orientations, found))


def box_overlap(scene: Scene, positions: np.ndarray, angles: np.ndarray,
                found: contacts.Contacts) -> float:
    """Find the deepest overlap of a box: each against each plane, and each contact pair with one.

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    positions : numpy.ndarray
        The bodies' positions, shape (bodies, 2).
    angles : numpy.ndarray
        The bodies' orientations in radians.
    found : Contacts
        The step's contacts; only body-body pairs with a box in them are measured.

    Returns
    -------
    float
        The depth; 0 if no box overlaps.
    """
    bodies = scene.bodies
    is_box, half_widths, radii = bodies.is_box, bodies.half_widths, bodies.radii
    deepest = 0.0
    for k in np.flatnonzero(is_box):
        for point, normal in zip(scene.plane_points, scene.plane_normals, strict=True):
            deepest = max(deepest, overlap.box_plane_depth(positions[k], angles[k],
                                                           half_widths[k], point, normal))
    pairs = {(int(a), int(b)) for a, b, kind in zip(found.body_a, found.body_b, found.kind,
                                                    strict=True) if kind == contacts.BODY_BODY}
    for a, b in pairs:
        if is_box[a] and is_box[b]:
            depth = overlap.box_box_depth(positions[a], angles[a], half_widths[a],
                                          positions[b], angles[b], half_widths[b])
        else:
            circle, box = (a, b) if is_box[b] else (b, a)
            depth = overlap.circle_box_depth(positions[circle], radii[circle],
                                             positions[box], angles[box], half_widths[box])
        deepest = max(deepest, depth)
    return deepest


def tally_hook(scene: Scene, tally: RunTally) -> Callable[[StepEvent], None]:
    """Make the per-step hook that fills ``tally``.

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    tally : RunTally
        Where the hook records the largest penetration, Coulomb residual and maximum-dissipation
        gap, and its own time (``hook_s``).

    Returns
    -------
    callable
        The hook, called with each StepEvent.
    """

    def hook(event: StepEvent) -> None:
        start = time.perf_counter()
        tally.max_penetration = max(tally.max_penetration, penetration(scene, event))
        problem = event.problem
        if isinstance(problem, FrictionalProblem) and problem.n_contacts:
            residual = friction_metrics.residual(problem, event.impulses)
            gap = mdp_gap(problem, event.impulses)
            tally.coulomb_residual = max(tally.coulomb_residual or 0.0, residual)
            tally.mdp_gap = max(tally.mdp_gap or 0.0, gap)
        tally.hook_s += time.perf_counter() - start

    return hook


def simulate(scene: Scene, spec: SolverSpec, accuracy: float, steps: int
             ) -> tuple[SimulationResult, RunTally, str | None]:
    """Run ``scene`` with ``spec`` at ``accuracy`` for at most ``steps`` steps.

    Parameters
    ----------
    scene : Scene
        The scene.
    spec : SolverSpec
        The inner solver's pair.
    accuracy : float
        The inner solves' accuracy level.
    steps : int
        The step cap.

    Returns
    -------
    tuple of (SimulationResult, RunTally, str or None)
        The result, the tally, and the reason it stopped early (a failed inner solve, a state
        no longer finite), or None.
    """
    tally = RunTally()
    simulator = Simulator(scene, choose_pair(spec), accuracy=accuracy)
    try:
        result = simulator.run(max_steps=steps, on_step=tally_hook(scene, tally))
    except UnsupportedError as error:  # the state left floating-point range
        return SimulationResult(scene=scene.path, steps=simulator.step_index), tally, str(error)
    stopped = None
    if result.failure is not None:
        stopped = (f"inner solve failed at step {result.failure['step']}: "
                   f"{result.failure['reason']}")
    return result, tally, stopped


def _never_called(problem: Any, accuracy: float, warm_start: np.ndarray | None) -> Any:
    raise AssertionError("a probe's inner solve is never called")


def needs_inner_solver(scene: Scene) -> bool:
    """Tell whether the scene has an operator (or a friction solver) that calls an inner solve.

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    bool
        True when some operator needs an inner solver.
    """
    probe = Simulator(scene, lambda operator: ChosenSolve(name="probe", solve=_never_called))
    return bool(probe.inner)


ROW_FIELDS = ("scene", "kind", "solver", "pair", "accuracy", "steps", "status", "reason",
              "solve_time_s", "wall_s", "state_error", "position_error", "velocity_error",
              "scisim_error", "scisim_agrees", "impacts", "inner_solves", "inaccurate_solves",
              "failed_solves", "max_residual", "max_penetration", "energy_initial",
              "energy_final", "energy_drift", "max_energy_gain", "coulomb_residual", "mdp_gap")


def row(scene: Scene, kind: str, solver: str, pair: str | None, accuracy: float,
        **values: Any) -> dict[str, Any]:
    """Make one result row with every field of ROW_FIELDS (None where not given).

    Parameters
    ----------
    scene : Scene
        The scene.
    kind : str
        FRICTIONAL or FRICTIONLESS.
    solver : str
        The solver name as given.
    pair : str or None
        The pair's key; None when the name has no pair of the kind.
    accuracy : float
        The level.
    **values : Any
        The row's other fields.

    Returns
    -------
    dict of str to Any
        The row.
    """
    base = {name: None for name in ROW_FIELDS}
    base.update(scene=scene.path, kind=kind, solver=solver, pair=pair, accuracy=accuracy)
    base.update(values)
    return base


def measured_row(scene: Scene, kind: str, solver: str, spec: SolverSpec, accuracy: float,
                 run: tuple[SimulationResult, RunTally, str | None],
                 reference: tuple[np.ndarray, np.ndarray] | None,
                 scisim: ScisimState | None) -> dict[str, Any]:
    """Make the row of one run: times, errors against the reference and SCISim, the tally.

    Errors are measured only for a run that ended, against SCISim only at its step count.

    Parameters
    ----------
    scene : Scene
        The scene.
    kind : str
        FRICTIONAL or FRICTIONLESS.
    solver : str
        The solver name as given.
    spec : SolverSpec
        The pair that ran.
    accuracy : float
        The level.
    run : tuple of (SimulationResult, RunTally, str or None)
        What :func:`simulate` gave.
    reference : tuple of (numpy.ndarray, numpy.ndarray) or None
        The reference run's final (q, v); None without one.
    scisim : ScisimState or None
        SCISim's final state of the scene; None when unknown.

    Returns
    -------
    dict of str to Any
        The row (:func:`row`).
    """
    result, tally, stopped = run
    finished = stopped is None
    values: dict[str, Any] = {
        "steps": result.steps, "status": "ok" if finished else "failed", "reason": stopped,
        "solve_time_s": result.log.solve_time_s,
        "wall_s": max(0.0, result.wall_s - tally.hook_s),
        "impacts": result.impacts, "inner_solves": result.log.solves,
        "inaccurate_solves": result.log.inaccurate, "failed_solves": 0 if finished else 1,
        "max_residual": result.log.max_residual, "max_penetration": tally.max_penetration,
        "energy_initial": result.energy_initial, "energy_final": result.energy_final,
        "energy_drift": result.energy_final - result.energy_initial,
        "max_energy_gain": result.max_energy_gain,
        "coulomb_residual": tally.coulomb_residual, "mdp_gap": tally.mdp_gap,
    }
    if finished:
        q, v = final_state(scene, result)
        if reference is not None:
            values.update(state_errors(scene, q, v, *reference, result.time))
        if scisim is not None and scisim.steps == result.steps and scisim.q.shape == q.shape:
            values["scisim_error"] = state_errors(scene, q, v, scisim.q, scisim.v,
                                                  result.time)["state_error"]
            values["scisim_agrees"] = agrees_with_scisim(q, v, scisim.q, scisim.v)
    return row(scene, kind, solver, spec.key, accuracy, **values)


def reference_run(scene: Scene, accuracy: float, steps: int
                  ) -> tuple[dict[str, Any], tuple[np.ndarray, np.ndarray] | None]:
    """Run the reference of ``scene``: the first pair of REFERENCE_PAIRS[kind] that ends accurate.

    A pair qualifies when its run at ``accuracy`` ends with no failed or inaccurate inner solve.

    Parameters
    ----------
    scene : Scene
        The scene.
    accuracy : float
        The tightest level.
    steps : int
        The step cap.

    Returns
    -------
    tuple of (dict, tuple of (numpy.ndarray, numpy.ndarray) or None)
        Its summary (``pair`` None when none did, ``tried`` saying why each was passed over)
        and its final (q, v), or None.
    """
    kind = scene_kind(scene)
    tried: list[str] = []
    for name in REFERENCE_PAIRS[kind]:
        try:
            spec = get(name, REGISTRY_KIND[kind])
        except QpbenchError as error:
            tried.append(f"{name}: {error}")
            continue
        result, tally, stopped = simulate(scene, spec, accuracy, steps)
        if stopped is None and result.log.inaccurate == 0:
            q, v = final_state(scene, result)
            return ({"pair": spec.key, "accuracy": accuracy, "steps": result.steps,
                     "impacts": result.impacts, "inner_solves": result.log.solves,
                     "max_residual": result.log.max_residual,
                     "solve_time_s": result.log.solve_time_s,
                     "wall_s": max(0.0, result.wall_s - tally.hook_s),
                     "q_final": q, "v_final": v, "tried": tried}, (q, v))
        tried.append(f"{spec.key}: " + (stopped or f"{result.log.inaccurate} inaccurate "
                                                   "inner solves"))
    return {"pair": None, "accuracy": accuracy, "tried": tried}, None


# --- the measurement -----------------------------------------------------------------------
def run_count(scenes: int, names: int, levels: int) -> int:
    """Count the runs :func:`sim_precision` makes at most.

    Per scene: a reference and one per (name, level).

    Parameters
    ----------
    scenes, names, levels : int
        How many scenes, solver names and levels.

    Returns
    -------
    int
        The number of runs.
    """
    return scenes * (1 + names * levels)


def sim_precision(scene_paths: list[str], names: list[str], levels: tuple[float, ...],
                  steps: int, progress: Advance | None = None) -> dict[str, Any]:
    """Measure every scene x solver name x level (module docstring) into one report.

    Parameters
    ----------
    scene_paths : list of str
        The scene files.
    names : list of str
        The solver names, ``NAME`` or ``NAME/FORMULATION``.
    levels : tuple of float
        The accuracy levels; the tightest is the reference's.
    steps : int
        The step cap of every run.
    progress : callable, optional
        Told ``(runs done, note)`` after every run; None tells nothing.

    Returns
    -------
    dict of str to Any
        ``title``, ``steps``, ``levels``, ``solvers``, ``within``, ``reference_pairs``,
        ``scenes`` (each with its reference), ``rows``, ``loosest`` (:func:`loosest_within`)
        and ``markdown``.

    Raises
    ------
    QpbenchError
        On an unknown solver name, or a scene file that cannot be read.
    """
    told = progress or _silent
    check_names(names)
    scenes = [load_scene(path) for path in scene_paths]
    levels = tuple(sorted(set(levels), reverse=True))
    tightest = min(levels)
    scisim = scisim_states(steps)
    rows: list[dict[str, Any]] = []
    summaries: list[dict[str, Any]] = []
    warmed: set[str] = set()
    for scene in scenes:
        kind = scene_kind(scene)
        known = scisim.get(scene_digest(Path(scene.path)) or "")
        summary: dict[str, Any] = {
            "scene": scene.path, "kind": kind, "bodies": scene.bodies.count,
            "boxes": scene.bodies.has_boxes, "portals": bool(scene.portals),
            "staggering": scene.staggering,
            "scisim_source": None if known is None else known.source,
        }
        summaries.append(summary)
        if not needs_inner_solver(scene):
            summary["skipped"] = "the scene has no operator that calls an inner solver"
            told(run_count(1, len(names), len(levels)), scene.name)
            continue
        summary["reference"], reference = reference_run(scene, tightest, steps)
        told(1, f"{scene.name}: reference")
        for name in names:
            spec, why_not = pair_for(name, kind)
            if spec is not None and spec.key not in warmed:  # first calls, untimed
                simulate(scene, spec, tightest, steps)
                warmed.add(spec.key)
            for accuracy in levels:
                if spec is None:
                    rows.append(row(scene, kind, name, None, accuracy, steps=0,
                                    status="skipped", reason=why_not))
                else:
                    run = simulate(scene, spec, accuracy, steps)
                    rows.append(measured_row(scene, kind, name, spec, accuracy, run, reference,
                                             known))
                told(1, f"{scene.name}: {name} at {accuracy:g}")
    report: dict[str, Any] = {
        "title": "What accuracy costs in a whole simulation",
        "steps": steps, "levels": list(levels), "solvers": list(names), "within": WITHIN,
        "reference_pairs": {kind: list(pairs) for kind, pairs in REFERENCE_PAIRS.items()},
        "scenes": summaries, "rows": rows,
    }
    report["loosest"] = loosest_within(rows, WITHIN)
    report["markdown"] = markdown(report)
    return report


def loosest_within(rows: list[dict[str, Any]], within: float = WITHIN) -> list[dict[str, Any]]:
    """Find per scene and pair the loosest level whose runs stay within ``within``.

    The level is the loosest from which every run down to the tightest level ended with
    ``state_error <= within`` (None when the tightest did not); ``cost_ratio`` is its solve
    time over the tightest level's.

    Parameters
    ----------
    rows : list of dict
        The report's rows.
    within : float, optional
        The bound on ``state_error``; WITHIN by default.

    Returns
    -------
    list of dict
        Per (scene, solver): scene, kind, solver, pair, accuracy, state_error, cost_ratio.
    """
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for entry in rows:
        if entry["pair"] is not None:
            groups.setdefault((entry["scene"], entry["solver"]), []).append(entry)
    found = []
    for (scene, solver), group in groups.items():
        group = sorted(group, key=lambda entry: entry["accuracy"], reverse=True)
        tightest = group[-1]
        loosest = None
        for entry in reversed(group):  # from the tightest level up, while each stays within
            if not (entry["status"] == "ok" and entry["state_error"] is not None
                    and entry["state_error"] <= within):
                break
            loosest = entry
        ratio = None
        if (loosest is not None and tightest["status"] == "ok"
                and tightest["solve_time_s"] and tightest["solve_time_s"] > 0):
            ratio = loosest["solve_time_s"] / tightest["solve_time_s"]
        found.append({"scene": scene, "kind": group[0]["kind"], "solver": solver,
                      "pair": group[0]["pair"],
                      "accuracy": None if loosest is None else loosest["accuracy"],
                      "state_error": None if loosest is None else loosest["state_error"],
                      "cost_ratio": ratio})
    return found


# --- report --------------------------------------------------------------------------------
def _level(value: float | None) -> str:
    return "none" if value is None else f"{value:.0e}"


def _number(value: float | None, digits: int = 2) -> str:
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:.{digits}g}" if value != 0 else "0"


def _short(scene: str) -> str:
    """A scene's path without the folders every default scene shares."""
    for marker in ("scisim_fidelity/scenes/", "problems/scenes/"):
        if marker in scene:
            return scene.split(marker, 1)[1]
    return scene


def pair_summary(rows: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    """Summarise each (solver, level) over the scenes of ``kind``.

    The summed inner-solve and wall times of the runs that ended, the largest and median
    ``state_error``, runs that failed, and the scenes whose final state stayed within WITHIN.

    Parameters
    ----------
    rows : list of dict
        The report's rows.
    kind : str
        FRICTIONAL or FRICTIONLESS.

    Returns
    -------
    list of dict
        One entry per (solver, level), by solver then loosest level first.
    """
    groups: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for entry in rows:
        if entry["kind"] == kind and entry["status"] != "skipped":
            groups.setdefault((entry["solver"], entry["accuracy"]), []).append(entry)
    summary = []
    for (solver, accuracy), group in groups.items():
        ended = [entry for entry in group if entry["status"] == "ok"]
        errors = [entry["state_error"] for entry in ended if entry["state_error"] is not None]
        summary.append({
            "solver": solver, "pairs": sorted({entry["pair"] for entry in group}),
            "accuracy": accuracy, "runs": len(group), "failed": len(group) - len(ended),
            "solve_time_s": sum(entry["solve_time_s"] for entry in ended),
            "wall_s": sum(entry["wall_s"] for entry in ended),
            "max_state_error": max(errors) if errors else None,
            "median_state_error": float(np.median(errors)) if errors else None,
            "within": sum(error <= WITHIN for error in errors),
            "inaccurate_solves": sum(entry["inaccurate_solves"] for entry in ended),
        })
    return sorted(summary, key=lambda item: (item["solver"], -item["accuracy"]))


LOOSEST_CAPTION = ("Loosest level from which every tighter level's final state stays within "
                   "{within:.0e} of the reference, and its inner-solve time over that at "
                   "{tightest:.0e} (one timing per run)")


def loosest_grid(report: dict[str, Any], kind: str
                 ) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """Lay out ``report["loosest"]`` as a per-scene table for the scenes of ``kind``.

    Each cell holds the loosest level within WITHIN and its cost ratio, ``none`` or
    ``skipped``.

    Parameters
    ----------
    report : dict of str to Any
        The report of :func:`sim_precision`.
    kind : str
        FRICTIONAL or FRICTIONLESS.

    Returns
    -------
    tuple of (list of str, list of tuple of (str, list of str))
        The solver names that have a row, and per scene its short name and its cells.
    """
    loosest = report["loosest"]
    solvers = [name for name in report["solvers"]
               if any(entry["kind"] == kind and entry["solver"] == name for entry in loosest)]
    cells = {(entry["scene"], entry["solver"]): entry for entry in loosest}
    grid = []
    for scene in report["scenes"]:
        if scene["kind"] != kind:
            continue
        row = []
        for name in solvers:
            entry = cells.get((scene["scene"], name))
            if entry is None:
                row.append("skipped")
            elif entry["accuracy"] is None:
                row.append("none")
            else:
                ratio = entry["cost_ratio"]
                row.append(_level(entry["accuracy"])
                           + ("" if ratio is None else f" ({ratio:.2f}x)"))
        grid.append((_short(scene["scene"]), row))
    return solvers, grid


def markdown(report: dict[str, Any]) -> str:
    """Write the measurement as a Markdown section.

    Per kind of scene, a table per pair and level (summed times, largest error, failures) and
    the per-scene table of the loosest level within WITHIN of the reference with its cost
    against the tightest level.

    Parameters
    ----------
    report : dict of str to Any
        The report of :func:`sim_precision`.

    Returns
    -------
    str
        The Markdown text.
    """
    rows = report["rows"]
    tightest = min(report["levels"])
    lines = [f"# {report['title']}", "",
             f"Each scene simulated for {report['steps']} steps with each pair as its inner "
             f"solver at each level; `state_error` is the final state's relative distance "
             f"(positions and velocities, mass norm) from a reference run at {tightest:.0e}. "
             "Frictional scenes run frictional pairs (a QP backend inside `staggered`, "
             "`nsgs`, Lemke on the `lcp` form); frictionless ones impact pairs.", ""]
    for kind in (FRICTIONLESS, FRICTIONAL):
        scenes = [scene for scene in report["scenes"] if scene["kind"] == kind]
        if not scenes:
            continue
        lines += [f"## {kind.capitalize()} scenes ({len(scenes)})", "",
                  "| solver | pairs | level | solve time | wall time | largest error | "
                  f"median error | within {WITHIN:.0e} | failed runs | inaccurate solves |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for item in pair_summary(rows, kind):
            lines.append(
                f"| {item['solver']} | {', '.join(item['pairs'])} | {_level(item['accuracy'])} "
                f"| {_number(item['solve_time_s'], 3)} s | {_number(item['wall_s'], 3)} s "
                f"| {_number(item['max_state_error'])} | {_number(item['median_state_error'])} "
                f"| {item['within']}/{item['runs']} | {item['failed']} "
                f"| {item['inaccurate_solves']} |")
        solvers, grid = loosest_grid(report, kind)
        if solvers:
            lines += ["", f"{LOOSEST_CAPTION.format(within=WITHIN, tightest=tightest)}:", "",
                      "| scene | " + " | ".join(solvers) + " |",
                      "|---|" + "---|" * len(solvers)]
            lines += [f"| {scene} | " + " | ".join(cells) + " |" for scene, cells in grid]
        lines.append("")
    unreferenced = [scene["scene"] for scene in report["scenes"]
                    if "reference" in scene and scene["reference"]["pair"] is None]
    if unreferenced:
        lines += ["No reference run succeeded (no `state_error`): "
                  + ", ".join(_short(scene) for scene in unreferenced), ""]
    skipped = [_short(scene["scene"]) for scene in report["scenes"] if "skipped" in scene]
    if skipped:
        lines += ["Not measured (no inner solver): " + ", ".join(skipped), ""]
    compared = [entry for entry in rows if entry["scisim_agrees"] is not None]
    if compared:
        agree = sum(bool(entry["scisim_agrees"]) for entry in compared)
        lines += [f"Against SCISim's own final states: {agree} of {len(compared)} runs agree "
                  "within the fidelity rule (positions 1e-6, velocities 1e-6 x max(1, speed)).",
                  ""]
    return "\n".join(lines)


def figure(report: dict[str, Any], path: str | Path) -> Path | None:
    """Draw the scene-level work-precision figure as a PNG at ``path``.

    A panel per kind of scene, a curve per solver, each point one level at (inner-solve time
    summed over the kind's scenes, largest ``state_error`` over them), drawn only where every
    run of that level ended.

    Parameters
    ----------
    report : dict of str to Any
        The report of :func:`sim_precision`.
    path : str or pathlib.Path
        The PNG file to write (atomically).

    Returns
    -------
    pathlib.Path or None
        ``path``; None when nothing can be drawn (nothing written).
    """
    kinds = [kind for kind in (FRICTIONLESS, FRICTIONAL)
             if any(entry["kind"] == kind for entry in report["rows"])]
    if not kinds:
        return None
    panels, grid = plt.subplots(1, len(kinds), figsize=(6.4 * len(kinds), 4.8), squeeze=False)
    names = {name: index for index, name in enumerate(report["solvers"])}
    for axes, kind in zip(grid.flat, kinds, strict=True):
        by_solver: dict[str, list[dict[str, Any]]] = {}
        for item in pair_summary(report["rows"], kind):
            if item["failed"] == 0 and item["max_state_error"] is not None:
                by_solver.setdefault(item["solver"], []).append(item)
        xs: list[float] = []
        ys: list[float] = [WITHIN]
        for solver, points in by_solver.items():
            points = sorted(points, key=lambda item: -item["accuracy"])
            x = [max(item["solve_time_s"], ERROR_FLOOR) for item in points]
            y = [max(item["max_state_error"], ERROR_FLOOR) for item in points]
            axes.plot(x, y, marker="o", markersize=4, label=solver,
                      **style(names.get(solver, len(names))))
            xs += x
            ys += y
        axes.set_xscale("log")
        axes.set_yscale("log")
        # explicit limits: equal values (every error zero, say) leave log axes degenerate
        if xs:
            axes.set_xlim(min(xs) / 2, max(xs) * 2)
        axes.set_ylim(min(ys) / 10, max(ys) * 10)
        axes.axhline(WITHIN, color="grey", linewidth=0.8, linestyle=":")
        axes.set_xlabel(f"inner-solve time summed over the {kind} scenes [s]")
        axes.set_ylabel("largest final-state error over the scenes")
        axes.set_title(f"{kind.capitalize()} scenes ({report['steps']} steps; points: levels)\n"
                       f"(the reference pair's run at the tightest level is the reference; "
                       f"0 drawn at {ERROR_FLOOR:.0e})", fontsize=9)
        axes.grid(True, which="both", alpha=0.3)
        if by_solver:
            axes.legend(fontsize=7, loc="best")
    try:
        with atomic_path(path) as temporary:
            panels.savefig(temporary, dpi=DPI, bbox_inches="tight", format="png")
    finally:
        plt.close(panels)
    return Path(path)
