"""Cost per ball per step of the stepper on box scenes of growing size.

``cost = wall time of the timed steps / (balls * steps)`` after one untimed
warm-up step, for every size; ``ratio = cost(largest) / cost(smallest)``. A
stepper linear in the number of balls keeps the ratio near 1 (target: <= 1.5).
The inner solver's own time is reported beside it, since it depends on the
solver and not on the stepper.
"""

from __future__ import annotations

import time
from typing import Any

from qpbench.scenes.builders import box_scene
from qpbench.simulation.operators import ChooseSolve
from qpbench.simulation.stepper import Simulator

TARGET_RATIO = 1.5
DEFAULT_SIZES = (1000, 10000)
DEFAULT_STEPS = 20


def measure(balls: int, steps: int, choose_solve: ChooseSolve, seed: int = 0
            ) -> tuple[dict[str, Any], str | None]:
    """One size: wall time of ``steps`` steps of ``box_scene(balls)`` and what they did, and
    the names of the inner solvers."""
    simulator = Simulator(box_scene(balls, seed=seed), choose_solve)
    simulator.step()  # warm-up: first calls into numpy, scipy and the solver
    solve_before = simulator.log.solve_time_s
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
    }
    return row, simulator.solver_names


def scaling(choose_solve: ChooseSolve, sizes: tuple[int, ...] = DEFAULT_SIZES,
            steps: int = DEFAULT_STEPS, seed: int = 0) -> dict[str, Any]:
    """Every size measured, the ratio of the largest to the smallest cost, and a Markdown table."""
    measured = [measure(balls, steps, choose_solve, seed) for balls in sizes]
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
    report["markdown"] = markdown(report)
    return report


def markdown(report: dict[str, Any]) -> str:
    """The measurements as a Markdown section."""
    rows = report["rows"]
    lines = [
        "## Simulation scaling",
        "",
        f"Box scenes (`box_scene`, seed {report['seed']}): {report['steps']} timed steps after "
        f"one warm-up step; inner solver `{report['solver']}`.",
        "",
        "| balls | steps | wall (s) | inner solves (s) | impacts | max contacts "
        "| cost per ball per step (us) | without solves (us) |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        lines.append(
            f"| {row['balls']} | {row['steps']} | {row['wall_s']:.3f} | {row['solve_s']:.3f} "
            f"| {row['impacts']} | {row['max_contacts']} | {row['cost_per_ball_step_us']:.2f} "
            f"| {row['cost_without_solves_us']:.2f} |")
    verdict = "meets" if report["meets_target"] else "misses"
    lines += [
        "",
        f"Cost per ball per step, {rows[-1]['balls']} vs {rows[0]['balls']} balls: "
        f"**{report['ratio']:.2f}x** ({verdict} the target <= {report['target_ratio']}x); "
        f"without the inner solves {report['ratio_without_solves']:.2f}x.",
    ]
    return "\n".join(lines) + "\n"
