"""``qpbench sim-precision``: whole simulations per inner solver and accuracy level.

The reference run reaches the analytic answers of two scenes (a Newton's cradle under the LCP
operator, a ball striking a rough floor obliquely, sliding or sticking); a looser level's
recorded ``state_error`` is the difference measured here from two independent runs; and on
scenes outside the defaults, osqp/dual and pi-robust run at 1e-2, 1e-4 and 1e-8, with osqp's
final state at 1e-8 never further from the reference than at 1e-2.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from bench_problems import write_tiny_problems

from qpbench.bench import sim_precision
from qpbench.bench.defaults import SIM_PRECISION_SCENES
from qpbench.bench.report import write_report
from qpbench.cli import main
from qpbench.cli.output import to_jsonable
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import load_scene
from qpbench.simulation.stepper import Simulator

ROOT = Path(__file__).resolve().parents[1]

# three unit-mass balls in a row, the last two touching, the first closing at speed 2:
# the simultaneous LCP with restitution 1 gives v+ = 2 (-1/3, 2/3, 2/3) (docs/design.md
# section 1, fact 5)
CRADLE = """<ball2d_scene>
  <integrator type="verlet" dt="0.001"/>
  <impact_operator type="lcp" CoR="1.0" v_tol="1.0e-9" cache_impulses="0">
    <solver name="ipopt" tol="1.0e-12"/>
  </impact_operator>
  <ball x="-1.005" y="0" vx="2" vy="0" m="1" r="0.500001" fixed="0"/>
  <ball x="0" y="0" vx="0" vy="0" m="1" r="0.500001" fixed="0"/>
  <ball x="1" y="0" vx="0" vy="0" m="1" r="0.500001" fixed="0"/>
</ball2d_scene>
"""

# a ball (ball2d: it does not spin) striking the floor y = 0 at (vx, -1), restitution 1/2,
# mu 0.3, no gravity
ROUGH_FLOOR = """<ball2d_scene>
  <integrator type="symplectic_euler" dt="0.001"/>
  <sobogus_friction_solver mu="0.3" CoR="0.5" max_iters="10000" eval_every="1" tol="1.0e-24"
                           staggering="geometric" cache_impulses="none"/>
  <static_plane x="0 0" n="0 1"/>
  <ball x="0" y="0.5015" vx="{vx}" vy="-1" m="2" r="0.5" fixed="0"/>
</ball2d_scene>
"""


def write(folder: Path, name: str, text: str) -> str:
    path = folder / name
    path.write_text(text)
    return str(path)


def test_the_reference_run_reaches_the_cradle_of_the_simultaneous_lcp(tmp_path: Path) -> None:
    scene = load_scene(write(tmp_path, "cradle.xml", CRADLE))
    summary, final = sim_precision.reference_run(scene, 1e-10, 20)
    assert summary["pair"] == sim_precision.REFERENCE_PAIRS["frictionless"][0]
    assert summary["impacts"] >= 1 and final is not None
    velocities = np.asarray(summary["v_final"]).reshape(-1, 2)
    np.testing.assert_allclose(velocities[:, 0], [-2 / 3, 4 / 3, 4 / 3], atol=1e-10)
    np.testing.assert_allclose(velocities[:, 1], 0.0, atol=1e-12)


@pytest.mark.parametrize("vx", [1.0, 0.2], ids=["slides", "sticks"])
def test_the_reference_run_reaches_the_oblique_frictional_impact(tmp_path: Path,
                                                                 vx: float) -> None:
    scene = load_scene(write(tmp_path, "rough_floor.xml", ROUGH_FLOOR.format(vx=vx)))
    summary, _ = sim_precision.reference_run(scene, 1e-10, 10)
    assert summary["pair"] is not None and summary["impacts"] == 1
    # the normal impulse is m (1 + e) |vy|; sticking needs |m vx| <= mu times it, else the
    # tangential velocity drops by mu (1 + e) |vy|
    mu, restitution, vy = 0.3, 0.5, 1.0
    kick = mu * (1 + restitution) * vy
    expected_vx = 0.0 if vx <= kick else vx - kick
    np.testing.assert_allclose(summary["v_final"], [expected_vx, restitution * vy], atol=1e-9)


def measured_error(scene_path: str, pair: str, accuracy: float, reference_pair: str,
                   reference_accuracy: float, steps: int) -> float:
    """max(position, velocity) relative error in the mass norm, from two runs made here."""
    scene = load_scene(scene_path)
    runs = [Simulator(scene, choose_by_name(name), accuracy=level).run(max_steps=steps)
            for name, level in ((pair, accuracy), (reference_pair, reference_accuracy))]
    (x, v), (x_ref, v_ref) = [(run.x_final.ravel(), run.v_final.ravel()) for run in runs]
    mass = np.repeat(scene.bodies.masses, 2)
    reach = np.repeat(scene.bodies.radii, 2)

    def norm(values: np.ndarray) -> float:
        return math.sqrt(float(np.sum(mass * values**2)))

    position = norm(x - x_ref) / max(norm(x_ref), norm(reach))
    falling = 0.0 if scene.gravity is None else (
        float(np.linalg.norm(scene.gravity)) * runs[1].time * math.sqrt(scene.bodies.masses.sum()))
    velocity = norm(v - v_ref) / max(norm(v_ref), norm(scene.bodies.velocities.ravel()), falling)
    return max(position, velocity)


def test_a_looser_levels_recorded_error_is_the_difference_measured(tmp_path: Path) -> None:
    scene = str(ROOT / "problems" / "scenes" / "ura" / "K4.xml")
    report = sim_precision.sim_precision([scene], ["osqp/dual"], (1e-2, 1e-8), steps=30)
    reference = report["scenes"][0]["reference"]
    loose = next(row for row in report["rows"] if row["accuracy"] == 1e-2)
    assert loose["pair"] == "osqp/dual" and loose["status"] == "ok"
    expected = measured_error(scene, "osqp/dual", 1e-2, reference["pair"], 1e-8, 30)
    assert expected > 0
    assert loose["state_error"] == pytest.approx(expected, rel=1e-9)


def test_unseen_scenes_run_and_osqp_is_no_worse_at_1e_8_than_at_1e_2(tmp_path: Path) -> None:
    scenes = [ROOT / "problems" / "scenes" / "ura" / "grid3_itr_0.xml",
              ROOT / "problems" / "scenes" / "scisim" / "ball_ball_ccd_00.xml",
              ROOT / "problems" / "scisim_fidelity" / "scenes" / "ball2d" / "tests_st"
              / "ball_plane" / "mu_0p5" / "slope_test_posx" / "ball_slide_at_threshold.xml"]
    defaults = {str((ROOT / scene).resolve()) for scene in SIM_PRECISION_SCENES}
    assert not defaults & {str(scene.resolve()) for scene in scenes}
    output = tmp_path / "sim_precision.json"
    assert main(["sim-precision", *map(str, scenes), "--solvers", "osqp/dual,pi-robust",
                 "--accuracy", "1e-2,1e-4,1e-8", "--steps", "12", "--no-progress",
                 "-o", str(output)]) == 0
    report = json.loads(output.read_text())
    rows = report["rows"]
    assert len(rows) == 3 * 2 * 3
    assert {row["accuracy"] for row in rows} == {1e-2, 1e-4, 1e-8}
    assert all(row["status"] != "skipped" for row in rows)
    assert {row["pair"] for row in rows if row["kind"] == "frictional"} == {
        "osqp/staggered", "pi-robust/staggered"}

    def error(row: dict) -> float:
        return math.inf if row["state_error"] is None else row["state_error"]

    for scene in report["scenes"]:
        osqp = {row["accuracy"]: row for row in rows
                if row["scene"] == scene["scene"] and row["solver"] == "osqp/dual"}
        assert osqp[1e-8]["status"] == "ok"
        assert error(osqp[1e-8]) <= error(osqp[1e-2])
    assert "Frictional scenes" in report["markdown"]
    figure = sim_precision.figure(report, tmp_path / "sim_precision.png")
    assert figure is not None and figure.read_bytes().startswith(b"\x89PNG")


def test_a_name_without_a_pair_of_the_scenes_kind_is_a_skipped_row(tmp_path: Path) -> None:
    scene = str(ROOT / "problems" / "scenes" / "scisim" / "two_balls.xml")
    report = sim_precision.sim_precision([scene], ["nsgs"], (1e-4,), steps=3)
    (row,) = report["rows"]
    assert row["status"] == "skipped" and row["pair"] is None
    assert "takes no impact problems" in row["reason"]


def test_the_report_draws_the_figure_and_the_page_shows_the_loosest_levels(
        tmp_path: Path) -> None:
    """A sim_precision.json beside a results table: REPORT.md links the work-precision figure
    it drew, and index.html has the per-scene table of loosest levels."""
    scene = str(ROOT / "problems" / "scenes" / "ura" / "K4.xml")
    report = sim_precision.sim_precision([scene], ["osqp/dual"], (1e-2, 1e-8), steps=30)
    (tmp_path / "sim_precision.json").write_text(json.dumps(to_jsonable(report)))
    report = json.loads((tmp_path / "sim_precision.json").read_text())
    write_tiny_problems(tmp_path / "problems", count=1)
    assert main(["run", str(tmp_path / "problems"), "--solvers", "clarabel/dual",
                 "--accuracy", "1e-4", "--no-progress", "-o",
                 str(tmp_path / "bench.parquet")]) == 0
    text = write_report(tmp_path / "bench.parquet").read_text()
    assert "](figures/sim_precision.png)" in text
    assert (tmp_path / "figures" / "sim_precision.png").stat().st_size > 0
    page = (tmp_path / "index.html").read_text()
    section = page.split("<section id='simulations'>", 1)[1].split("</section>", 1)[0]
    solvers, grid = sim_precision.loosest_grid(report, sim_precision.FRICTIONLESS)
    assert solvers == ["osqp/dual"] and grid
    for scene_name, cells in grid:
        assert scene_name in section and all(cell in section for cell in cells)
