"""Simulating friction: the physics it must get right, and mu = 0 left exactly as it was.

* a ball on an incline slides with ``a = g (sin t - mu cos t)`` above ``atan mu`` and stays
  put below it, in every staggering;
* a spinning disc dropped on a rough floor ends rolling (``v_x + omega r = 0``) when
  ``|v_x + omega r| <= 3 mu (1 + e) |v_y|`` and sliding otherwise, with the slip the impulse
  ``mu l_N`` leaves;
* with e = 0 no impact adds kinetic energy;
* with mu = 0 every shared scene ends bit for bit where the frictionless simulator ends, and
  never poses a frictional problem.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qpbench.cli import main
from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name
from qpbench.problem import files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes import load_scene, parse_scene
from qpbench.scenes.model import FrictionSolver
from qpbench.simulation.operators import ChosenSolve
from qpbench.simulation.stepper import Simulator, StepEvent

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "problems" / "scenes"
FIDELITY = ROOT / "problems" / "scisim_fidelity" / "scenes"
G = 9.81
DT = 0.001
MU = 0.5


def sobogus(mu: float, staggering: str, cor: float = 0.0, cache: str = "none") -> str:
    extra = (' stabilization="0" penetration_threshold="1e-5"'
             if staggering == "symplectic_euler" else "")
    return (f'<sobogus_friction_solver mu="{mu}" CoR="{cor}" max_iters="5000" eval_every="1" '
            f'tol="1e-24" cache_impulses="{cache}" staggering="{staggering}"{extra}/>')


def incline(degrees: float, staggering: str, mu: float = MU) -> str:
    """A ball at rest on a plane tilted by ``degrees`` (downhill towards -x), gravity -y."""
    angle = math.radians(degrees)
    normal = (-math.sin(angle), math.cos(angle))
    return f"""<ball2d_scene>
  <integrator type="symplectic_euler" dt="{DT}"/>
  {sobogus(mu, staggering)}
  <gravity fx="0" fy="{-G}"/>
  <static_plane x="0 0" n="{normal[0]!r} {normal[1]!r}"/>
  <ball x="{0.5 * normal[0]!r}" y="{0.5 * normal[1]!r}" vx="0" vy="0" m="2" r="0.5"
        fixed="0"/>
</ball2d_scene>"""


def along_slope(velocity: np.ndarray, degrees: float) -> float:
    angle = math.radians(degrees)
    return float(velocity @ np.array([-math.cos(angle), -math.sin(angle)]))  # downhill


def run(text: str, steps: int, solver: str | None = None, **kwargs) -> tuple:
    scene = parse_scene(text, "friction.xml")
    events: list[StepEvent] = []
    result = Simulator(scene, choose_by_name(solver), **kwargs).run(
        max_steps=steps, on_step=events.append)
    assert result.failure is None, result.failure
    return scene, result, events


STAGGERINGS = ("geometric", "stabilized", "symplectic_euler")


@pytest.mark.parametrize("staggering", STAGGERINGS)
@pytest.mark.parametrize("degrees", [35.0, 50.0])
def test_a_ball_slides_down_a_steep_incline_at_g_sin_minus_mu_cos(staggering: str,
                                                                  degrees: float) -> None:
    text = incline(degrees, staggering)
    _, half, _ = run(text, 100)
    _, full, events = run(text, 200)
    angle = math.radians(degrees)
    expected = G * (math.sin(angle) - MU * math.cos(angle))
    measured = (along_slope(full.v_final[0], degrees)
                - along_slope(half.v_final[0], degrees)) / (100 * DT)
    assert measured == pytest.approx(expected, rel=1e-9)
    assert full.impacts > 150 and all(isinstance(e.problem, FrictionalProblem)
                                      for e in events if e.problem is not None)


@pytest.mark.parametrize("staggering", STAGGERINGS)
@pytest.mark.parametrize("degrees", [10.0, 25.0])
def test_a_ball_stays_put_on_a_gentle_incline(staggering: str, degrees: float) -> None:
    assert math.tan(math.radians(degrees)) < MU
    text = incline(degrees, staggering)
    _, half, _ = run(text, 100)
    scene, full, events = run(text, 200)
    # every impact sticks: the solve leaves no tangential velocity
    for event in events[1:]:
        problem = event.problem
        u_tangential = problem.split(problem.u(event.impulses))[1]
        assert abs(u_tangential[0]) < 1e-12
    speed = along_slope(full.v_final[0], degrees)
    assert speed == pytest.approx(along_slope(half.v_final[0], degrees), abs=1e-15)
    if staggering == "geometric":  # gravity acts after the impulse: v = g sin(t) dt
        assert speed == pytest.approx(G * math.sin(math.radians(degrees)) * DT, rel=1e-9)
    else:  # the solve sees the gravity of the step: the ball does not move at all
        assert speed == pytest.approx(0.0, abs=1e-15)
        moved = along_slope(full.x_final[0] - scene.bodies.positions[0], degrees)
        assert abs(moved) < 1e-15


def test_without_friction_the_same_ball_slides_at_g_sin() -> None:
    text = incline(25.0, "geometric", mu=0.0).replace(
        "<sobogus_friction_solver", '<impact_operator type="lcp" CoR="0"><solver name="ql"/>'
        '</impact_operator><!--').replace('staggering="geometric"/>', "-->")
    _, half, _ = run(text, 100, "pi-robust")
    _, full, _ = run(text, 200, "pi-robust")
    measured = (along_slope(full.v_final[0], 25.0) - along_slope(half.v_final[0], 25.0)) / (
        100 * DT)
    assert measured == pytest.approx(G * math.sin(math.radians(25.0)), rel=1e-9)


def disc(mu: float, spin: float, staggering: str = "geometric", cor: float = 0.0) -> str:
    """A disc of radius 0.5 touching the floor, falling at 1 m/s, spinning at ``spin``."""
    return f"""<rigidbody2d_scene>
  <integrator type="symplectic_euler" dt="{DT}"/>
  {sobogus(mu, staggering, cor)}
  <static_plane x="0 0" n="0 1"/>
  <geometry type="circle" r="0.5"/>
  <rigid_body x="0 0.5" theta="0" v="0 -1" omega="{spin}" rho="1" geo_idx="0"/>
</rigidbody2d_scene>"""


@pytest.mark.parametrize("staggering", ["geometric", "stabilized"])
def test_a_spinning_disc_on_a_rough_floor_ends_rolling(staggering: str) -> None:
    # slip speed |v_x + omega r| = 1 <= 3 mu |v_y| = 1.5: the impact leaves it rolling
    _, result, _ = run(disc(0.5, 2.0, staggering), 20)
    v_x, v_y = result.v_final[0]
    omega = result.omega_final[0]
    assert v_x + 0.5 * omega == pytest.approx(0.0, abs=1e-10)
    assert v_y == pytest.approx(0.0, abs=1e-12)
    # the angular momentum about the contact point, I omega0 = (I + m r^2) omega, is kept
    assert omega == pytest.approx(2.0 / 3.0, rel=1e-9) and v_x == pytest.approx(-1.0 / 3.0)
    assert result.theta_final[0] != 0.0


def test_a_fast_spinning_disc_on_a_slippery_floor_keeps_sliding() -> None:
    # slip 1 > 3 mu |v_y| = 0.3: it slides, l_T = mu l_N takes mu |v_y| off v_x and
    # 2 mu |v_y| / r off omega, leaving a slip of 1 - 3 mu
    _, result, _ = run(disc(0.1, 2.0), 20)
    v_x, v_y = result.v_final[0]
    omega = result.omega_final[0]
    assert v_x == pytest.approx(-0.1, rel=1e-9) and omega == pytest.approx(1.6, rel=1e-9)
    assert v_x + 0.5 * omega == pytest.approx(0.7, rel=1e-9)
    assert v_y == pytest.approx(0.0, abs=1e-12)


def dissipative(path: Path) -> bool:
    """A frictional scene with e = 0 and no gap stabilization (which may push bodies apart)."""
    friction = load_scene(path).friction
    return bool(friction is not None and friction.frictional and friction.restitution == 0.0
                and not friction.stabilization)


@pytest.mark.parametrize("path", [p for p in sorted(FIDELITY.rglob("*.xml")) if dissipative(p)],
                         ids=lambda p: str(p.relative_to(FIDELITY)))
def test_with_e_zero_no_impact_adds_kinetic_energy(path: Path) -> None:
    result = Simulator(load_scene(path), choose_by_name(None)).run(max_steps=50)
    assert result.failure is None
    assert result.max_energy_gain is None or result.max_energy_gain <= 1e-9


def test_with_e_zero_no_impact_adds_kinetic_energy_to_the_test_scenes() -> None:
    for text in (incline(35.0, "geometric"), incline(35.0, "symplectic_euler"),
                 disc(0.5, 2.0), disc(0.1, 40.0, "stabilized")):
        _, result, _ = run(text, 50)
        assert result.impacts > 0 and result.max_energy_gain <= 1e-12


SHARED = sorted(SCENES.rglob("*.xml"))
STEP_CAPS = {"balls_in_box_1000": 10, "balls_in_box_100": 60, "circle_pile_1000": 5,
             "box_pile_1000": 5}


@pytest.mark.parametrize("path", SHARED, ids=lambda p: p.stem)
def test_mu_zero_is_the_frictionless_simulation_bit_for_bit(path: Path) -> None:
    plain = load_scene(path)
    smooth = load_scene(path)
    smooth.friction = FrictionSolver(kind="sobogus", mu=0.0, restitution=0.0,
                                     staggering="geometric", tol=1e-12, max_iters=100,
                                     eval_every=1)
    steps = STEP_CAPS.get(plain.name, 150)
    kinds: set[type] = set()
    results = []
    for scene in (plain, smooth):
        results.append(Simulator(scene, choose_by_name("pi-robust")).run(
            max_steps=steps, on_step=lambda e: kinds.add(type(e.problem))))
    assert kinds <= {ImpactProblem, type(None)}
    assert np.array_equal(results[0].x_final, results[1].x_final)
    assert np.array_equal(results[0].v_final, results[1].v_final)


@pytest.mark.parametrize("name", ["tests_ccd/ball_ball_ccd_01.xml",
                                  "tests_ccd/ball_ball_ccd_03.xml"])
def test_a_sobogus_solver_with_mu_zero_is_the_lcp_bit_for_bit(name: str) -> None:
    text = (FIDELITY / "ball2d" / name).read_text()
    start = text.index("<sobogus_friction_solver")
    end = text.index("/>", start) + 2
    element = text[start:end]
    cor = element.split('CoR="')[1].split('"')[0]
    lcp = (text[:start] + f'<impact_operator type="lcp" CoR="{cor}" v_tol="0">'
           '<solver name="ql"/></impact_operator>' + text[end:])
    ends = []
    for variant in (text, lcp):
        _, result, _ = run(variant, 50, "pi-robust")
        ends.append((result.x_final, result.v_final))
    assert np.array_equal(ends[0][0], ends[1][0]) and np.array_equal(ends[0][1], ends[1][1])


def test_the_frictionless_symplectic_euler_scene_runs() -> None:
    path = FIDELITY / "ball2d" / "tests_st" / "three_ball_collision_cor_0_0.xml"
    scene = load_scene(path)
    assert scene.staggering == "symplectic_euler" and not scene.frictional
    result = Simulator(scene, choose_by_name(None)).run(max_steps=200)
    assert result.failure is None and result.impacts == 1
    assert result.max_energy_gain < 0


def test_captured_frictional_problems_are_frictional_problem_files(tmp_path: Path) -> None:
    _, result, _ = run(disc(0.5, 2.0), 3, capture=tmp_path)
    paths = sorted(tmp_path.glob("*.npz"))
    assert result.captured == len(paths) == 1
    problem = files.load(paths[0])
    assert isinstance(problem, FrictionalProblem)
    assert problem.mu.tolist() == [0.5] and problem.metadata["staggering"] == "geometric"
    # T carries the arm: the contact point is r below the centre, (0, -r) x (-1, 0) = -r
    assert problem.T.toarray()[:, 0].tolist() == [-1.0, 0.0, -0.5]


def recording(solver: str, seen: list) -> object:
    """choose_by_name(solver), with every call's problem (as the solver sees it, at unit
    velocity scale) and warm start recorded."""
    base = choose_by_name(solver)

    def choose(operator):
        chosen = base(operator)

        def solve(problem, accuracy, warm_start):
            seen.append((problem, warm_start))
            return chosen.solve(problem, accuracy, warm_start)

        return ChosenSolve(name=chosen.name, solve=solve, note=chosen.note)

    return choose


@pytest.mark.parametrize("cache", ["none", "normal", "normal_and_friction"])
def test_cache_impulses_warm_starts_from_the_previous_step(cache: str) -> None:
    text = incline(35.0, "geometric").replace('cache_impulses="none"',
                                              f'cache_impulses="{cache}"')
    scene = parse_scene(text, "cached.xml")
    seen: list = []
    events: list[StepEvent] = []
    Simulator(scene, recording(None, seen)).run(max_steps=20, on_step=events.append)
    assert len(seen) > 10
    by_step = {event.step: event for event in events}
    for (problem, _), (next_problem, warm) in zip(seen, seen[1:], strict=False):
        previous = by_step[problem.normal.metadata["step"]].impulses  # r as the step used it
        # the solver works at unit velocity scale, so its warm start is scaled as q is
        factor = next_problem.scale / by_step[next_problem.normal.metadata["step"]].problem.scale
        if cache == "none":
            assert warm is None
        elif cache == "normal":
            assert (warm / factor).tolist() == [previous[0], 0.0]
        else:
            assert (warm / factor).tolist() == previous.tolist()


def test_a_frictional_scene_refuses_a_frictionless_solver() -> None:
    scene = parse_scene(incline(35.0, "geometric"), "rough.xml")
    with pytest.raises(QpbenchError, match="takes no frictional problems"):
        Simulator(scene, choose_by_name("clarabel/dual"))
    # a frictionless solver's name alone means its frictional twin (staggered projections)
    assert Simulator(scene, choose_by_name("clarabel")).solver_names == "clarabel/staggered"


def test_the_scene_tolerance_sets_the_inner_accuracy() -> None:
    loose = parse_scene(incline(35.0, "geometric").replace('tol="1e-24"', 'tol="1e-12"'), "a")
    tight = parse_scene(incline(35.0, "geometric"), "b")
    assert Simulator(loose, choose_by_name(None)).accuracy == 1e-8  # sqrt(1e-12) is looser
    assert Simulator(tight, choose_by_name(None)).accuracy == pytest.approx(1e-12)
    assert Simulator(tight, choose_by_name(None), accuracy=1e-4).accuracy == 1e-4
    smooth = replace(tight.friction, mu=0.0)
    assert not smooth.frictional


def test_simulate_json_reports_theta_and_omega_of_rigid_bodies(tmp_path: Path,
                                                               capsys) -> None:
    path = tmp_path / "disc.xml"
    path.write_text(disc(0.5, 2.0))
    assert main(["simulate", str(path), "--steps", "5", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["omega_final"][0] == pytest.approx(2.0 / 3.0)
    assert summary["theta_final"][0] > 0 and len(summary["x_final"][0]) == 2
    ball = tmp_path / "ball.xml"
    ball.write_text(incline(35.0, "geometric"))
    assert main(["simulate", str(ball), "--steps", "5", "--json"]) == 0
    assert "omega_final" not in json.loads(capsys.readouterr().out)
