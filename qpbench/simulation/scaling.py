"""Cost per ball per step of the stepper on box scenes of growing size, and on dense piles.

``cost = wall time of the timed steps / (balls * steps)`` after one untimed
warm-up step, for every size; ``ratio = cost(largest) / cost(smallest)``. A
stepper linear in the number of balls keeps the ratio near 1 (target: <= 1.5).
The inner solver's own time is reported beside it, since it depends on the
solver and not on the stepper.

The sparse box scenes have few contacts. The dense piles (``circle_pile``, ``box_pile``)
keep most bodies in contact at every step; there the simulator's own cost per body per
step (contact detection, assembly, integration) is reported apart from the inner solves,
with its growth from the smallest to the largest size against the same target, and the
inner solves' growth per body per step against ``SOLVE_GROWTH_TARGET`` (<= 2x). Each kind
is warmed up once by one untimed step of a small pile, and every pile is timed from its
first step, so a large pile pays for no untimed step; a pile whose inner solves pass a time
budget stops after fewer steps (at least one), and its row says so. With ``passes`` > 1 every
pile of a kind is simulated once per pass, the sizes in turn (in reverse order every other
pass, so that a drift of the machine's speed falls on all sizes alike), and each size keeps
the pass whose inner solves took least: one genuine run of the pile, chosen as the least
disturbed (a failed one when any failed), with every pass's figure and the growth pass by
pass beside it.

The inner solves of a pile are also held against one sparse factorization of the final
active block: the caller hands in a :data:`FactorBlock` (this package knows no solver), told
the problem and impulses of the pile's last step done, after the timed steps; the inner-solve
time per step over the factorization's time is the row's ``solve_to_factorization``, against
``FACTORIZATION_TARGET`` (<= 3x).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np

from qpbench.problem.impact import ImpactProblem
from qpbench.scenes.builders import BOX_DT, BOX_RADIUS, box_scene
from qpbench.scenes.model import Bodies, ImpactOperator, Scene, SolverChoice
from qpbench.scenes.solver_names import SCISIM_TO_QPBENCH
from qpbench.simulation.operators import ChooseSolve, InnerSolveFailed
from qpbench.simulation.stepper import Simulator, StepEvent

TARGET_RATIO = 1.5
DEFAULT_SIZES = (1000, 10000)
DEFAULT_STEPS = 20
PILE_SPACING = 0.999  # centre distance / (2 r): neighbours overlap by 0.1 % of a diameter
PILE_SPEED = 0.01  # downward start velocity, so every step presses the pile together
PILE_GRAVITY = 9.81
DEFAULT_PILE_STEPS = 5
# the passes over every pile of a kind by default (``qpbench scaling --pile-passes``)
DEFAULT_PILE_PASSES = 3
PILE_WARMUP_BODIES = 100  # every kind's one untimed warm-up step is on a pile this small
# (or smaller: the smallest pile measured)
# a pile's timed steps stop early once its inner solves have taken this long (at least one
# step is always timed, and the steps done are reported)
DEFAULT_PILE_SOLVE_BUDGET_S = 60.0
# the inner solves per step of a pile against one sparse factorization of its final active block
FACTORIZATION_TARGET = 3.0
# the inner solves per body per step, largest pile against the smallest: near-linear at scale
SOLVE_GROWTH_TARGET = 2.0
# times one sparse factorization of the final active block: told the last step's problem and
# impulses, it gives the row's fields ``factorization_s`` (seconds, None when not measured),
# ``factorization_library`` and any more (qpbench.studies.factorization.active_block_factorization)
FactorBlock = Callable[[ImpactProblem, np.ndarray], dict[str, Any]]


def measure(balls: int, steps: int, choose_solve: ChooseSolve, seed: int = 0
            ) -> tuple[dict[str, Any], str | None]:
    """One size: wall time of ``steps`` steps of ``box_scene(balls)`` and what they did.

    One untimed warm-up step comes first.

    Parameters
    ----------
    balls : int
        The box scene's ball count.
    steps : int
        The timed steps.
    choose_solve : ChooseSolve
        The inner solve of the scene's operator.
    seed : int, optional
        The box scene's seed; 0 by default.

    Returns
    -------
    tuple of (dict, str or None)
        The row (wall and inner-solve seconds, cost per ball per step with and without the
        solves in microseconds, impacts, contacts, solve counts, success), and the names of
        the inner solvers.
    """
    simulator = Simulator(box_scene(balls, seed=seed), choose_solve)
    simulator.step()  # warm-up: first calls into numpy, scipy and the solver
    solve_before = simulator.log.solve_time_s
    solves_before, inaccurate_before = simulator.log.solves, simulator.log.inaccurate
    start = time.perf_counter()
    result = simulator.run(max_steps=steps)
    wall = time.perf_counter() - start
    solve = simulator.log.solve_time_s - solve_before
    row = {
        "balls": balls, "steps": steps, "wall_s": wall, "solve_s": solve,
        "cost_per_ball_step_us": 1e6 * wall / (balls * steps),
        "cost_without_solves_us": 1e6 * (wall - solve) / (balls * steps),
        "impacts": result.impacts, "max_contacts": result.max_contacts,
        "max_energy_gain": result.max_energy_gain, "success": result.failure is None,
        "inner_solves": simulator.log.solves - solves_before,
        "inaccurate_solves": simulator.log.inaccurate - inaccurate_before,
    }
    return row, simulator.solver_names


# a progress hook, told (measurements done, what was measured) after each measurement, never
# inside a timed window (the signature of qpbench.cli.progress.Progress.advance)
Advance = Callable[[int, str | None], None]


def _silent(count: int, note: str | None) -> None:
    """A progress hook that says nothing."""


def measurement_count(sizes: tuple[int, ...],
                      pile_sizes: dict[str, tuple[int, ...]] | None = None,
                      pile_passes: int = 1) -> int:
    """The measurements :func:`scaling` makes.

    One per box-scene size, and per kind of pile one warm-up and one per size and pass.

    Parameters
    ----------
    sizes : tuple of int
        The box scenes' ball counts.
    pile_sizes : dict of str to tuple of int, or None, optional
        Per kind of pile, its body counts; None (default) for no piles.
    pile_passes : int, optional
        The passes over every pile; 1 by default.

    Returns
    -------
    int
        The count, for a progress bar's total.
    """
    return len(sizes) + sum(1 + pile_passes * len(kind_sizes)
                            for kind_sizes in (pile_sizes or {}).values())


def scaling(choose_solve: ChooseSolve, sizes: tuple[int, ...] = DEFAULT_SIZES,
            steps: int = DEFAULT_STEPS, seed: int = 0,
            pile_sizes: dict[str, tuple[int, ...]] | None = None,
            pile_steps: int = DEFAULT_PILE_STEPS,
            pile_solve_budget_s: float = DEFAULT_PILE_SOLVE_BUDGET_S,
            progress: Advance | None = None,
            factor_block: FactorBlock | None = None,
            pile_passes: int = 1) -> dict[str, Any]:
    """Every size measured, the ratio of the largest to the smallest cost, and a Markdown table.

    With ``pile_sizes`` (kind -> sizes) also the dense piles, under ``"piles"``. ``progress``
    is told after each of the :func:`measurement_count` measurements (:data:`Advance`).

    Parameters
    ----------
    choose_solve : ChooseSolve
        The inner solve of every scene's operator.
    sizes : tuple of int, optional
        The box scenes' ball counts, smallest first; DEFAULT_SIZES by default.
    steps : int, optional
        Timed steps per box scene; DEFAULT_STEPS by default.
    seed : int, optional
        The box scenes' seed; 0 by default.
    pile_sizes : dict of str to tuple of int, or None, optional
        Per kind of pile (keys of PILES), its body counts; None (default) for no piles.
    pile_steps : int, optional
        Timed steps per pile at most; DEFAULT_PILE_STEPS by default.
    pile_solve_budget_s : float, optional
        Seconds of inner solves after which a pile stops timing steps;
        DEFAULT_PILE_SOLVE_BUDGET_S by default.
    progress : Advance or None, optional
        The progress hook; None (default) for none.
    factor_block : FactorBlock or None, optional
        Times one sparse factorization of each pile's final active block; None (default) for
        none.
    pile_passes : int, optional
        The passes over every pile (:func:`pile_scaling`); 1 by default.

    Returns
    -------
    dict
        The solver, steps, seed, the rows of :func:`measure`, ``ratio`` (with and without the
        solves), the target and whether it is met, ``piles`` when asked (:func:`pile_scaling`),
        and ``markdown``.
    """
    told = progress or _silent
    measured = []
    for balls in sizes:
        measured.append(measure(balls, steps, choose_solve, seed))
        told(1, f"box scene, {balls} balls")
    rows = [row for row, _ in measured]
    solver = measured[0][1]
    first, last = rows[0], rows[-1]
    ratio = last["cost_per_ball_step_us"] / first["cost_per_ball_step_us"]
    ratio_without = last["cost_without_solves_us"] / first["cost_without_solves_us"]
    report = {
        "solver": solver, "steps": steps, "seed": seed, "rows": rows,
        "ratio": ratio, "ratio_without_solves": ratio_without,
        "target_ratio": TARGET_RATIO, "meets_target": bool(ratio <= TARGET_RATIO),
    }
    if pile_sizes:
        report["piles"] = pile_scaling(choose_solve, pile_sizes, pile_steps,
                                       pile_solve_budget_s, told, factor_block, pile_passes)
    report["markdown"] = markdown(report)
    return report


def markdown(report: dict[str, Any]) -> str:
    """The measurements as a Markdown section.

    Parameters
    ----------
    report : dict
        The report of :func:`scaling`, without its ``markdown``.

    Returns
    -------
    str
        The ``## Simulation scaling`` section, with the piles' subsection when measured.
    """
    rows = report["rows"]
    lines = [
        "## Simulation scaling",
        "",
        f"Box scenes (`box_scene`, seed {report['seed']}): {report['steps']} timed steps after "
        f"one warm-up step; inner solver `{report['solver']}`.",
        "",
        "| balls | steps | wall (s) | inner solves (s) | impacts | max contacts "
        "| cost per ball per step (us) | without solves (us) | inaccurate solves |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {row['balls']} | {row['steps']} | {row['wall_s']:.3f} | {row['solve_s']:.3f} "
            f"| {row['impacts']} | {row['max_contacts']} | {row['cost_per_ball_step_us']:.2f} "
            f"| {row['cost_without_solves_us']:.2f} | {_inaccurate_cell(row)} |")
    verdict = "meets" if report["meets_target"] else "misses"
    lines += [
        "",
        f"Cost per ball per step, {rows[-1]['balls']} vs {rows[0]['balls']} balls: "
        f"**{report['ratio']:.2f}x** ({verdict} the target <= {report['target_ratio']}x); "
        f"without the inner solves {report['ratio_without_solves']:.2f}x.",
    ]
    text = "\n".join(lines) + "\n"
    if report.get("piles"):
        text += "\n" + pile_markdown(report["piles"], report["solver"])
    return text


# --- dense piles: most bodies in contact at every step ------------------------------------
PARTS = ("contacts_s", "assembly_s", "integration_s", "solve_s")


def _pile_scene(name: str, dialect: str, bodies: Bodies, width: float,
                solver_name: str = "policy_iteration") -> Scene:
    """A container (floor and two walls) under gravity, inelastic ``lcp`` impacts solved by
    the SCISim solver ``solver_name``."""
    solver = SolverChoice(solver_name, SCISIM_TO_QPBENCH[solver_name])
    return Scene(
        path=f"{name}.xml", dialect=dialect, bodies=bodies, integrator="symplectic_euler",
        dt=BOX_DT, gravity=np.array([0.0, -PILE_GRAVITY]),
        plane_points=np.array([[0.0, 0.0], [0.0, 0.0], [width, 0.0]]),
        plane_normals=np.array([[0.0, 1.0], [1.0, 0.0], [-1.0, 0.0]]),
        impact=ImpactOperator(type="lcp", restitution=0.0, v_tol=1e-9, solver=solver),
        end_time=Fraction(1),
    )


def circle_pile(n_bodies: int, solver_name: str = "policy_iteration") -> Scene:
    """A dense pile of balls in a container, every ball pressing on its neighbours.

    ``n_bodies`` balls of radius 1/2 in a hexagonal packing resting on the floor of a
    container about twice as wide as the pile is high; every ball presses on its neighbours
    (centre distance ``PILE_SPACING``), moving down at ``PILE_SPEED``; impacts solved by the
    SCISim solver ``solver_name``.

    Parameters
    ----------
    n_bodies : int
        The ball count, at least 1.
    solver_name : str, optional
        The SCISim name of the inner solver; ``policy_iteration`` by default.

    Returns
    -------
    Scene
        A ``ball2d`` scene named ``circle_pile_N``.

    Raises
    ------
    ValueError
        When ``n_bodies`` is below 1.
    """
    if n_bodies < 1:
        raise ValueError("a pile needs at least one body")
    columns = math.ceil(math.sqrt(2.0 * n_bodies))
    rows, column = np.divmod(np.arange(n_bodies), columns)
    spacing = PILE_SPACING
    x = BOX_RADIUS + spacing * (column + 0.5 * (rows % 2))
    y = BOX_RADIUS * spacing + rows * spacing * math.sqrt(3.0) / 2.0
    width = 2 * BOX_RADIUS + spacing * (columns - 0.5)
    bodies = Bodies(positions=np.stack([x, y], axis=1),
                    velocities=np.tile([0.0, -PILE_SPEED], (n_bodies, 1)),
                    masses=np.ones(n_bodies), radii=np.full(n_bodies, BOX_RADIUS),
                    fixed=np.zeros(n_bodies, dtype=bool))
    return _pile_scene(f"circle_pile_{n_bodies}", "ball2d", bodies, width, solver_name)


def box_pile(n_bodies: int) -> Scene:
    """A dense pile of unit boxes in a container, each pressing on its neighbours.

    ``n_bodies`` unit boxes (half-widths 1/2, mass 1, theta 0) in a square grid resting
    on the floor of a container, each pressing on its neighbours (pitch ``PILE_SPACING``),
    moving down at ``PILE_SPEED`` (rigidbody2d).

    Parameters
    ----------
    n_bodies : int
        The box count, at least 1.

    Returns
    -------
    Scene
        A ``rigidbody2d`` scene named ``box_pile_N``.

    Raises
    ------
    ValueError
        When ``n_bodies`` is below 1.
    """
    if n_bodies < 1:
        raise ValueError("a pile needs at least one body")
    columns = math.ceil(math.sqrt(2.0 * n_bodies))
    rows, column = np.divmod(np.arange(n_bodies), columns)
    half = BOX_RADIUS
    x = half + PILE_SPACING * column
    y = half * PILE_SPACING + PILE_SPACING * rows
    width = 2 * half + PILE_SPACING * (columns - 1)
    bodies = Bodies(positions=np.stack([x, y], axis=1).astype(float),
                    velocities=np.tile([0.0, -PILE_SPEED], (n_bodies, 1)),
                    masses=np.ones(n_bodies), radii=np.full(n_bodies, math.hypot(half, half)),
                    fixed=np.zeros(n_bodies, dtype=bool), theta=np.zeros(n_bodies),
                    omega=np.zeros(n_bodies), half_widths=np.full((n_bodies, 2), half))
    return _pile_scene(f"box_pile_{n_bodies}", "rigidbody2d", bodies, width)


PILES = {"circles": circle_pile, "boxes": box_pile}


class _Timed:
    """Wraps a bound method, adding its wall time to ``seconds``."""

    def __init__(self, method: Callable[..., Any]) -> None:
        self.method = method
        self.seconds = 0.0

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return self.method(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - start


def warm_up_pile(kind: str, bodies: int, choose_solve: ChooseSolve) -> None:
    """One untimed step of a pile of ``kind`` with ``bodies`` bodies.

    The first calls into numpy, scipy, the compiled box contacts and the solver happen here,
    not in a measured step (a separate small pile, so that a large pile need not pay for an
    untimed step).

    Parameters
    ----------
    kind : str
        A key of PILES: ``circles`` or ``boxes``.
    bodies : int
        The pile's body count.
    choose_solve : ChooseSolve
        The inner solve of the pile's operator.
    """
    Simulator(PILES[kind](bodies), choose_solve).step()


def measure_pile(kind: str, bodies: int, steps: int, choose_solve: ChooseSolve,
                 solve_budget_s: float = math.inf) -> tuple[dict[str, Any], StepEvent | None]:
    """One pile, warmed up beforehand (``warm_up_pile``), its time split into parts.

    Up to ``steps`` timed steps from its first, split into the simulator's own parts (contact
    detection, assembly of the impact problem, the rest of the step: integration and
    bookkeeping) and the inner solves (the whole call into the impact operator, the solver's
    own formulation included). The steps stop early, after at least one, once the inner solves
    have taken ``solve_budget_s``; the row says so. The last step done is returned beside the
    row, for one factorization of its final active block (:func:`final_block_fields`).

    Parameters
    ----------
    kind : str
        A key of PILES: ``circles`` or ``boxes``.
    bodies : int
        The pile's body count.
    steps : int
        The timed steps at most.
    choose_solve : ChooseSolve
        The inner solve of the pile's operator.
    solve_budget_s : float, optional
        Seconds of inner solves after which no further step is timed; no budget by default.

    Returns
    -------
    row : dict
        Steps done and asked, seconds per part, costs per body per step in microseconds,
        contacts per body, success or the failure, and the solves' accuracy.
    last : StepEvent or None
        The last step done; None when none was.
    """
    simulator = Simulator(PILES[kind](bodies), choose_solve)
    timers = {name: _Timed(getattr(simulator, name))
              for name in ("find_contacts", "impact_problem", "_solve")}
    for name, timer in timers.items():
        setattr(simulator, name, timer)
    contacts_found = 0
    done = 0
    failure = None
    last: StepEvent | None = None
    start = time.perf_counter()
    while done < steps and (done == 0 or timers["_solve"].seconds < solve_budget_s):
        try:
            last = simulator.step()
        except InnerSolveFailed as error:
            failure = error.detail
            break
        done += 1
        contacts_found += last.contacts.count
    wall = time.perf_counter() - start
    parts = {"contacts_s": timers["find_contacts"].seconds,
             "assembly_s": timers["impact_problem"].seconds,
             "solve_s": timers["_solve"].seconds}
    parts["integration_s"] = max(0.0, wall - sum(parts.values()))
    own = parts["contacts_s"] + parts["assembly_s"] + parts["integration_s"]
    scale = 1e6 / (bodies * max(1, done))
    row = {
        "kind": kind, "bodies": bodies, "steps": done, "steps_asked": steps,
        "stopped_by_solve_budget": failure is None and done < steps,
        "wall_s": wall, **parts,
        "own_s": own, "contacts_per_body": contacts_found / (bodies * max(1, done)),
        "own_per_body_step_us": own * scale,
        "solve_per_body_step_us": parts["solve_s"] * scale,
        "contacts_per_body_step_us": parts["contacts_s"] * scale,
        "assembly_per_body_step_us": parts["assembly_s"] * scale,
        "integration_per_body_step_us": parts["integration_s"] * scale,
        "success": failure is None, "failure": failure,
        **_accuracy_of(simulator),
    }
    return row, last


def final_block_fields(last: StepEvent | None, solve_per_step_s: float,
                       factor_block: FactorBlock) -> dict[str, Any]:
    """One sparse factorization of the final active block, against the inner solves per step.

    Parameters
    ----------
    last : StepEvent or None
        The pile's last step done; None when no step was done.
    solve_per_step_s : float
        The inner solves' seconds per step done.
    factor_block : FactorBlock
        Times the factorization of the step's problem and impulses.

    Returns
    -------
    dict
        The fields of ``factor_block`` (only ``factorization_s`` and ``factorization_library``,
        None, when the last step posed no impact problem), ``solve_per_step_s`` and
        ``solve_to_factorization`` (``solve_per_step_s / factorization_s``; None without a
        factorization time).
    """
    if last is not None and isinstance(last.problem, ImpactProblem):
        fields = factor_block(last.problem, last.impulses)
    else:
        fields = {"factorization_s": None, "factorization_library": None}
    factorization = fields.get("factorization_s")
    return {**fields, "solve_per_step_s": solve_per_step_s,
            "solve_to_factorization": (solve_per_step_s / factorization
                                       if factorization else None)}


def _accuracy_of(simulator: Simulator) -> dict[str, Any]:
    """How the inner solves of ``simulator``'s steps so far met the accuracy it asked of them,
    by qpbench's residual: solves (those with l = 0 exact aside), inaccurate ones (residual
    above the accuracy, yet usable: the step went on) and the largest residual."""
    return {"accuracy": simulator.accuracy, "inner_solves": simulator.log.solves,
            "inaccurate_solves": simulator.log.inaccurate,
            "max_residual": simulator.log.max_residual}


def pile_scaling(choose_solve: ChooseSolve, sizes: dict[str, tuple[int, ...]],
                 steps: int = DEFAULT_PILE_STEPS,
                 solve_budget_s: float = DEFAULT_PILE_SOLVE_BUDGET_S,
                 progress: Advance | None = None,
                 factor_block: FactorBlock | None = None,
                 passes: int = 1) -> dict[str, Any]:
    """Every pile at every size, and per kind the growth of its costs per body per step.

    Each kind is warmed up once on a small pile, then its piles are simulated ``passes``
    times, the sizes in turn (in reverse order every other pass), and each size keeps the
    pass whose inner solves per body per step took least, a failed one when any failed
    (:func:`_fastest_passes`). The
    growth of the simulator's own cost per body per step (largest size against the smallest,
    target <= 1.5x) and of the inner solves' (target <= SOLVE_GROWTH_TARGET) is given per
    kind, the latter also pass by pass. ``progress`` is told after each warm-up and each pile
    (:data:`Advance`).
    With ``factor_block``, each pile's inner solves per step are set against one sparse
    factorization of the final active block of its kept pass (:func:`final_block_fields`),
    and per kind the largest such ratio against FACTORIZATION_TARGET.

    Parameters
    ----------
    choose_solve : ChooseSolve
        The inner solve of every pile's operator.
    sizes : dict of str to tuple of int
        Per kind of pile (keys of PILES), its body counts, smallest first.
    steps : int, optional
        Timed steps per pile at most; DEFAULT_PILE_STEPS by default.
    solve_budget_s : float, optional
        Seconds of inner solves after which a pile stops timing steps;
        DEFAULT_PILE_SOLVE_BUDGET_S by default.
    progress : Advance or None, optional
        The progress hook; None (default) for none.
    factor_block : FactorBlock or None, optional
        Times one sparse factorization of each pile's final active block; None (default) for
        none.
    passes : int, optional
        The passes over every pile of a kind; 1 by default.

    Returns
    -------
    dict
        The steps, budget, passes, warm-up size and target, and under ``kinds`` per kind its
        sizes, rows (:func:`measure_pile`'s, with ``passes`` and every pass's
        ``solve_per_body_step_us_by_pass``), ``own_ratio``, ``solve_ratio``,
        ``solve_ratio_by_pass`` (the largest size's figure over the smallest's, pass by pass),
        ``meets_target`` and ``meets_solve_growth_target`` (``solve_growth_target`` beside
        ``target_ratio``); with ``factor_block`` also ``factorization_target`` and per kind
        ``max_solve_to_factorization`` (None when a row has no ratio) and
        ``meets_factorization_target``.
    """
    told = progress or _silent
    warmup = min([PILE_WARMUP_BODIES, *(min(kind_sizes) for kind_sizes in sizes.values())])
    report: dict[str, Any] = {"steps": steps, "solve_budget_s": solve_budget_s,
                              "passes": passes,
                              "warmup_bodies": warmup, "target_ratio": TARGET_RATIO,
                              "solve_growth_target": SOLVE_GROWTH_TARGET, "kinds": {}}
    if factor_block is not None:
        report["factorization_target"] = FACTORIZATION_TARGET
    for kind, kind_sizes in sizes.items():
        warm_up_pile(kind, warmup, choose_solve)
        told(1, f"{kind} pile warm-up, {warmup} bodies")
        rows = []
        for row, last_step in _fastest_passes(kind, kind_sizes, steps, choose_solve,
                                              solve_budget_s, passes, told):
            if factor_block is not None:
                row.update(final_block_fields(last_step, row["solve_s"] / max(1, row["steps"]),
                                              factor_block))
            rows.append(row)
        first, last = rows[0], rows[-1]
        own_ratio = last["own_per_body_step_us"] / max(first["own_per_body_step_us"], 1e-300)
        solve_ratio = (last["solve_per_body_step_us"]
                       / max(first["solve_per_body_step_us"], 1e-300))
        report["kinds"][kind] = {
            "sizes": list(kind_sizes), "rows": rows, "own_ratio": own_ratio,
            "solve_ratio": solve_ratio,
            "solve_ratio_by_pass": [
                large / max(small, 1e-300) for small, large in
                zip(first["solve_per_body_step_us_by_pass"],
                    last["solve_per_body_step_us_by_pass"], strict=True)],
            "meets_target": bool(own_ratio <= TARGET_RATIO),
            "meets_solve_growth_target": bool(solve_ratio <= SOLVE_GROWTH_TARGET),
        }
        if factor_block is not None:
            ratios = [row["solve_to_factorization"] for row in rows]
            largest = None if None in ratios else max(ratios)
            report["kinds"][kind].update({
                "max_solve_to_factorization": largest,
                "meets_factorization_target": bool(largest is not None
                                                   and largest <= FACTORIZATION_TARGET)})
    return report


def _fastest_passes(kind: str, kind_sizes: tuple[int, ...], steps: int,
                    choose_solve: ChooseSolve, solve_budget_s: float, passes: int,
                    told: Advance) -> list[tuple[dict[str, Any], StepEvent | None]]:
    """Per size of ``kind_sizes`` (in that order), the row and last step of the pass whose
    inner solves per body per step took least (of the passes whose solver failed, when any did:
    a failure is never hidden), the rows with ``passes`` and every pass's
    ``solve_per_body_step_us_by_pass``.

    Every pass simulates each size once (:func:`measure_pile`), in reverse order every other
    pass; ``told`` hears of each pile."""
    kept: dict[int, tuple[dict[str, Any], StepEvent | None]] = {}
    kept_rank: dict[int, tuple[bool, float]] = {}  # (success, time): a failure ranks first
    by_pass: dict[int, list[float]] = {bodies: [] for bodies in kind_sizes}
    for turn in range(passes):
        for bodies in kind_sizes if turn % 2 == 0 else kind_sizes[::-1]:
            row, last = measure_pile(kind, bodies, steps, choose_solve, solve_budget_s)
            by_pass[bodies].append(row["solve_per_body_step_us"])
            rank = (row["success"], row["solve_per_body_step_us"])
            if bodies not in kept or rank < kept_rank[bodies]:
                kept[bodies], kept_rank[bodies] = (row, last), rank
            told(1, f"{kind} pile, {bodies} bodies, pass {turn + 1} of {passes}")
    for bodies in kind_sizes:
        kept[bodies][0].update(passes=passes, solve_per_body_step_us_by_pass=by_pass[bodies])
    return [kept[bodies] for bodies in kind_sizes]


def _inaccurate_cell(row: dict[str, Any]) -> str:
    """``k of n`` inner solves whose residual missed the accuracy asked (``-``: a row
    measured before these counts were kept)."""
    if "inaccurate_solves" not in row:
        return "-"
    return f"{row['inaccurate_solves']} of {row['inner_solves']}"


def pile_markdown(report: dict[str, Any], solver: str | None) -> str:
    """The pile measurements as Markdown (a subsection of the scaling section).

    Parameters
    ----------
    report : dict
        The report of :func:`pile_scaling`.
    solver : str or None
        The inner solvers' names, for the text.

    Returns
    -------
    str
        The ``### Dense piles`` subsection: a table of every pile, the verdicts per kind (with
        the inner solves against one factorization of the final active block, when measured),
        and a line per pile the solve budget stopped.
    """
    budget = report.get("solve_budget_s", math.inf)
    budget_text = ("" if math.isinf(budget) else
                   f" (fewer when a pile's inner solves pass {budget:g} s; at least one)")
    levels = sorted({row["accuracy"] for entry in report["kinds"].values()
                     for row in entry["rows"] if "accuracy" in row})
    asked = f" ({', '.join(f'{level:g}' for level in levels)})" if levels else ""
    lines = [
        "### Dense piles",
        "",
        "Bodies settled in a container (floor and two walls) under gravity, each pressing on "
        "its neighbours and moving down slowly, so every step has contacts: circles in a "
        "hexagonal packing (`ball2d`), unit boxes in a grid (`rigidbody2d`); inelastic "
        f"`lcp` impacts, up to {report['steps']} timed steps per pile{budget_text}, from "
        "its first step, each kind warmed up once beforehand by one untimed step of a "
        f"{report.get('warmup_bodies', PILE_WARMUP_BODIES)}-body pile;{_passes_text(report)} "
        f"inner solver `{solver}`. The simulator's own cost (contact detection, assembly of "
        "the impact problem, integration and the rest of the step) is per body per step; the "
        "inner solves are beside it with their own growth. Every inner solve is judged by "
        f"qpbench's residual against the accuracy the simulator asks of it{asked}; an "
        "inaccurate one (above that accuracy, yet usable) is counted, and the step goes on with "
        "its answer."
        + _factorization_text(report),
        "",
        "| pile | bodies | steps | contacts per body | contacts (us) | assembly (us) "
        "| integration (us) | own cost per body per step (us) | inner solves (us) "
        "| inaccurate solves | largest residual | final active block (contacts) "
        "| one factorization (ms) | inner solves per step / factorization |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for kind, entry in report["kinds"].items():
        for row in entry["rows"]:
            failed = "" if row["success"] else " (solver failed)"
            largest = f"{row['max_residual']:.1e}" if "max_residual" in row else "-"
            lines.append(
                f"| {kind}{failed} | {row['bodies']} | {row['steps']} "
                f"| {row['contacts_per_body']:.2f} | {row['contacts_per_body_step_us']:.2f} "
                f"| {row['assembly_per_body_step_us']:.2f} "
                f"| {row['integration_per_body_step_us']:.2f} "
                f"| {row['own_per_body_step_us']:.2f} | {row['solve_per_body_step_us']:.2f} "
                f"| {_inaccurate_cell(row)} | {largest} | {_factorization_cells(row)} |")
    lines.append("")
    for kind, entry in report["kinds"].items():
        small, large = entry["sizes"][0], entry["sizes"][-1]
        verdict = "meets" if entry["meets_target"] else "misses"
        lines.append(
            f"- {kind}: own cost per body per step, {large} vs {small} bodies: "
            f"**{entry['own_ratio']:.2f}x** ({verdict} the target <= "
            f"{report['target_ratio']}x); inner solves **{entry['solve_ratio']:.2f}x**"
            + _solve_growth_verdict(entry, report) + _growth_by_pass(entry) + "."
            + _factorization_verdict(entry, report))
    for kind, entry in report["kinds"].items():
        for row in entry["rows"]:
            if row.get("stopped_by_solve_budget"):
                lines.append(
                    f"- {kind}, {row['bodies']} bodies: {row['steps']} of "
                    f"{row['steps_asked']} timed steps; the inner solves took "
                    f"{row['solve_s']:.0f} s, past the {budget:g} s budget of a pile "
                    "(`--pile-solve-budget`); the simulator's own cost is per step done.")
    return "\n".join(lines) + "\n"


def _passes_text(report: dict[str, Any]) -> str:
    """How the piles were passed over, when more than once (empty for one pass)."""
    passes = report.get("passes", 1)
    if passes <= 1:
        return ""
    return (f" every pile simulated in {passes} passes, the sizes in turn (in reverse order "
            "every other pass), each size keeping the pass whose inner solves took least;")


def _growth_by_pass(entry: dict[str, Any]) -> str:
    """``, pass by pass 2.10-2.60x``: the range of the inner solves' growth in each pass
    alone (empty for one pass)."""
    ratios = entry.get("solve_ratio_by_pass") or []
    if len(ratios) < 2:
        return ""
    return f", pass by pass {min(ratios):.2f}-{max(ratios):.2f}x"


def _solve_growth_verdict(entry: dict[str, Any], report: dict[str, Any]) -> str:
    """`` (meets the target <= 2x)`` or ``misses`` for one kind's inner solves, as measured
    against ``solve_growth_target`` (empty for a report measured before it was kept)."""
    if "solve_growth_target" not in report:
        return ""
    verdict = "meets" if entry["meets_solve_growth_target"] else "misses"
    return f" ({verdict} the target <= {report['solve_growth_target']:g}x)"


def _factorization_text(report: dict[str, Any]) -> str:
    """The sentence that says how the inner solves are set against one factorization (empty
    when not measured)."""
    if "factorization_target" not in report:
        return ""
    rows = [row for entry in report["kinds"].values() for row in entry["rows"]]
    shifts = sorted({row["factor_shift"] for row in rows if "factor_shift" in row})
    shift = f" = {', '.join(f'{value:g}' for value in shifts)} max diag Q" if shifts else ""
    libraries = dict.fromkeys(method.split("/")[0] for row in rows
                              for method in row.get("factorization_s_by_method", {}))
    words = {"CHOLMOD": "CHOLMOD (simplicial LDL^T, approximate minimum degree)",
             "SuperLU": "SuperLU (minimum degree on A^T + A, diagonal pivots)"}
    by = " and by ".join(words.get(name, name) for name in libraries) or "each library"
    return (" After its timed steps, each pile's final active block (the contacts F with l > 0 "
            f"in the answer of its last step), Q_FF + eps I (eps{shift}, since Q_FF may be "
            f"singular), is factored by {by}, each once untimed and then in alternating timed "
            "rounds, the minimum kept; one factorization is the faster (named per row), and "
            "the inner solves per step are set against it (target <= "
            f"{report['factorization_target']:g}x at every size).")


def _factorization_cells(row: dict[str, Any]) -> str:
    """The cells of the final active block: its contacts, one factorization's time (the faster
    library) and the inner solves per step against it; ``-`` where not measured."""
    contacts = str(row["active_contacts"]) if "active_contacts" in row else "-"
    if row.get("factorization_s") is None:
        return f"{contacts} | - | -"
    return (f"{contacts} | {1e3 * row['factorization_s']:.2f} ({row['factorization_library']}) "
            f"| {row['solve_to_factorization']:.2f}x")


def _factorization_verdict(entry: dict[str, Any], report: dict[str, Any]) -> str:
    """The sentence of one kind's inner solves per step against one factorization of the final
    active block, size by size, and whether each is within the target (empty when not
    measured)."""
    if "factorization_target" not in report:
        return ""
    target = report["factorization_target"]
    figures = ", ".join(
        f"{row['solve_to_factorization']:.2f}x at {row['bodies']}"
        if row.get("solve_to_factorization") is not None else f"none at {row['bodies']}"
        for row in entry["rows"])
    verdict = "meets" if entry["meets_factorization_target"] else "misses"
    return (f" Inner solves per step against one factorization of the final active block: "
            f"**{figures} bodies** ({verdict} the target <= {target:g}x)."
            + _factorization_growth(entry["rows"]))


def _factorization_growth(rows: list[dict[str, Any]]) -> str:
    """The sentence of how one factorization of the final active block grows per body from
    the smallest pile to the largest (the yardstick's own growth, beside the inner solves');
    empty unless both were factored."""
    first, last = rows[0], rows[-1]
    if first is last or not first.get("factorization_s") or not last.get("factorization_s"):
        return ""
    growth = ((last["factorization_s"] / last["bodies"])
              / (first["factorization_s"] / first["bodies"]))
    return (f" One factorization itself, per body, grows {growth:.2f}x from "
            f"{first['bodies']} to {last['bodies']} bodies.")
