"""The simulator: textbook impacts, the shared scenes, capture, failures and the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from other_cpu import printed_elsewhere

from qpbench import inner_solvers
from qpbench.cli import main
from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name, solve_with
from qpbench.problem import files
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes import load_scene, parse_scene
from qpbench.scenes.model import ImpactOperator
from qpbench.scenes.solver_names import FALLBACK
from qpbench.simulation import checks, stepper
from qpbench.simulation.broad_phase import candidate_pairs, swept_boxes
from qpbench.simulation.operators import ChosenSolve, SolvedImpulses, unit_scale
from qpbench.simulation.stepper import Simulator, StepEvent
from qpbench.solvers import registry
from qpbench.solvers.base import SolverSpec

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes"
SOLVER = "clarabel/dual"
TOLERANCE = 1e-6


def ball2d(balls: str, operator: str = "lcp", cor: float = 1.0, dt: str = "0.01",
           extra: str = "") -> str:
    """A ball2d scene text with the given <ball> lines and impact operator."""
    if operator == "grr":
        impact = (f'<impact_operator type="grr" CoR="{cor}" cache_impulses="0">'
                  '<elastic_operator type="gr" CoR="1" v_tol="1e-9"><solver name="ipopt"/>'
                  '</elastic_operator><inelastic_operator type="lcp" CoR="0">'
                  '<solver name="ipopt"/></inelastic_operator></impact_operator>')
    elif operator == "gauss_seidel":
        impact = f'<impact_operator type="gauss_seidel" CoR="{cor}" v_tol="1e-12"/>'
    else:
        impact = (f'<impact_operator type="{operator}" CoR="{cor}" v_tol="1e-9" '
                  'cache_impulses="0"><solver name="ipopt"/></impact_operator>')
    return (f'<ball2d_scene><integrator type="verlet" dt="{dt}"/>{impact}{extra}{balls}'
            "</ball2d_scene>")


def run(text: str, end_time: float | None = None, steps: int | None = None,
        solver: str = SOLVER) -> stepper.SimulationResult:
    result = Simulator(parse_scene(text, "test.xml"), choose_by_name(solver)).run(end_time,
                                                                                 steps)
    assert result.failure is None, result.failure
    return result


HEAD_ON = ('<ball x="-1" y="0" vx="1" vy="0" m="1" r="0.5" fixed="0"/>'
           '<ball x="1" y="0" vx="-0.5" vy="0" m="1" r="0.5" fixed="0"/>')


@pytest.mark.parametrize("operator", ["lcp", "gr", "grr", "gauss_seidel"])
def test_two_equal_balls_with_c_1_swap_velocities(operator: str) -> None:
    result = run(ball2d(HEAD_ON, operator), end_time=2.0)
    assert result.impacts == 1
    assert np.allclose(result.v_final, [[-0.5, 0.0], [1.0, 0.0]], atol=TOLERANCE)
    assert result.momentum_drift < 1e-12


def test_grr_with_c_half_halves_the_relative_velocity() -> None:
    result = run(ball2d(HEAD_ON, "grr", cor=0.5), end_time=2.0)
    relative_before, relative_after = -1.5, result.v_final[1, 0] - result.v_final[0, 0]
    assert relative_after == pytest.approx(-0.5 * relative_before, abs=TOLERANCE)
    assert result.v_final[:, 0].sum() == pytest.approx(0.5, abs=1e-12)


CRADLE = SCENES / "scisim" / "newtons_cradle.xml"


def test_newtons_cradle_with_gr_gives_the_last_ball_all_the_momentum() -> None:
    result = Simulator(load_scene(CRADLE), choose_by_name(SOLVER)).run(end_time=1.0)
    assert np.allclose(result.v_final, [[0, 0], [0, 0], [2, 0]], atol=TOLERANCE)
    assert result.momentum_drift < 1e-12
    assert result.energy_final == pytest.approx(result.energy_initial, rel=TOLERANCE)


def test_newtons_cradle_with_lcp_gives_minus_a_third_two_thirds_two_thirds() -> None:
    text = CRADLE.read_text().replace('type="gr"', 'type="lcp"')
    result = run(text, end_time=1.0)
    assert np.allclose(result.v_final[:, 0], [-2 / 3, 4 / 3, 4 / 3], atol=TOLERANCE)
    assert result.max_energy_gain <= TOLERANCE


def test_newtons_cradle_with_gauss_seidel_sweeps_like_gr() -> None:
    text = CRADLE.read_text().replace(
        '<impact_operator type="gr" CoR="1.0" v_tol="1.0e-9" cache_impulses="0">',
        '<impact_operator type="gauss_seidel" CoR="1.0" v_tol="1.0e-9">')
    result = run(text, end_time=1.0)
    assert np.allclose(result.v_final[:, 0], [0, 0, 2], atol=TOLERANCE)


@pytest.mark.parametrize("operator", ["lcp", "gr"])
def test_a_ball_hitting_a_plane_at_45_degrees_with_c_half(operator: str) -> None:
    text = ball2d('<ball x="0" y="0.6" vx="1" vy="-1" m="2" r="0.5" fixed="0"/>', operator,
                  cor=0.5, extra='<static_plane x="0 0" n="0 1"/>')
    result = run(text, steps=50)
    assert result.impacts == 1
    assert np.allclose(result.v_final, [[1.0, 0.5]], atol=TOLERANCE)


def test_a_rigid_circle_bounces_without_its_spin_changing() -> None:
    text = (SCENES / "scisim" / "horizontal_plane_collision.xml").read_text().replace(
        'omega="0.0"', 'omega="3.0"')
    scene = parse_scene(text, "spin.xml")
    simulator = Simulator(scene, choose_by_name(SOLVER))
    result = simulator.run(end_time=2.0)
    assert np.allclose(result.v_final, [[0.0, 2.0]], atol=TOLERANCE)
    assert simulator.omega[0] == 3.0
    assert simulator.theta[0] == pytest.approx(3.0 * 2.0)


def test_a_ball_inside_a_drum_reflects_and_stays_inside() -> None:
    text = ball2d('<ball x="0" y="0" vx="3" vy="1" m="1" r="0.5" fixed="0"/>', "gr",
                  extra='<static_drum x="0" y="0" r="2"/>')
    result = run(text, end_time=4.0)
    assert result.impacts >= 3
    assert np.hypot(*result.x_final[0]) <= 2 - 0.5 + 3 * 0.01 * np.hypot(3, 1)
    assert np.hypot(*result.v_final[0]) == pytest.approx(np.hypot(3, 1), rel=TOLERANCE)
    assert result.momentum_drift is None


def test_a_ball_hitting_a_fixed_ball_of_a_ball2d_scene_hands_on_its_velocity() -> None:
    # SCISim's ball2d never scripts a ball, so fixed="1" is an ordinary ball of mass 1 here
    # (kinematic bodies: tests/test_scisim_features.py)
    text = ball2d('<ball x="-1" y="0" vx="1" vy="0" m="1" r="0.5" fixed="0"/>'
                  '<ball x="0.5" y="0" vx="0" vy="0" m="1" r="0.5" fixed="1"/>', "lcp")
    result = run(text, end_time=1.0)
    assert np.allclose(result.v_final, [[0, 0], [1, 0]], atol=TOLERANCE)


def test_continuous_detection_catches_a_ball_that_would_pass_through() -> None:
    result = run((SCENES / "scisim" / "ball_ball_ccd_00.xml").read_text(), end_time=3.0)
    assert result.impacts == 1
    assert np.allclose(result.v_final, [[0, 0], [2.2, 0]], atol=TOLERANCE)


def test_without_an_impact_operator_balls_pass_through_each_other() -> None:
    text = ('<ball2d_scene><integrator type="verlet" dt="0.01"/>' + HEAD_ON + "</ball2d_scene>")
    result = run(text, end_time=2.0)
    assert result.impacts == 0 and result.max_contacts == 0
    assert np.allclose(result.v_final, [[1, 0], [-0.5, 0]])


def test_free_fall_under_verlet_is_exact() -> None:
    text = ball2d('<ball x="0" y="10" vx="1" vy="0" m="1" r="0.5" fixed="0"/>',
                  extra='<gravity fx="0" fy="-9.81"/>', dt="1/64")
    result = run(text, end_time=1.0)
    assert np.allclose(result.x_final, [[1.0, 10 - 9.81 / 2]], atol=1e-12)
    assert result.energy_final == pytest.approx(result.energy_initial, rel=1e-12)


def test_the_broad_phase_finds_every_overlapping_box() -> None:
    rng = np.random.default_rng(7)
    for count in (2, 30, 400):
        x0 = rng.uniform(0, 10, (count, 2))
        x1 = x0 + rng.normal(0, 0.2, (count, 2))
        radii = rng.uniform(0.05, 0.6, count)
        lower, upper = swept_boxes(x0, x1, radii)
        overlap = np.all((lower[:, None] <= upper[None]) & (lower[None] <= upper[:, None]), axis=2)
        expected = {(i, j) for i, j in zip(*np.nonzero(overlap), strict=True) if i < j}
        found = {tuple(pair) for pair in candidate_pairs(lower, upper).tolist()}
        assert found == expected


SCENE_STEP_CAPS = {"balls_in_box_1000": 15, "balls_in_box_100": 100, "newtons_cradle": 800,
                   "balls_bouncing_on_wedge_apgd": 400, "circle_pile_1000": 5,
                   "box_pile_1000": 2}


@pytest.mark.parametrize("path", sorted(SCENES.rglob("*.xml")), ids=lambda p: p.stem)
def test_every_shared_scene_simulates_without_energy_gain(path: Path) -> None:
    scene = load_scene(path)
    result = Simulator(scene, choose_by_name(SOLVER)).run(
        end_time=scene.end_time or 2.0, max_steps=SCENE_STEP_CAPS.get(scene.name, 300))
    assert result.failure is None, result.failure
    assert result.steps > 0
    assert result.max_energy_gain is None or result.max_energy_gain <= TOLERANCE
    assert result.energy_final <= result.energy_initial + TOLERANCE * abs(result.energy_initial)
    if scene.balls_alone:
        assert result.momentum_drift < 1e-9
    assert np.all(np.isfinite(result.x_final))


def test_captured_problems_carry_their_scene_step_and_time(tmp_path: Path) -> None:
    scene = load_scene(SCENES / "ura" / "K3.xml")
    result = Simulator(scene, choose_by_name(SOLVER), capture=tmp_path).run(max_steps=5)
    paths = sorted(tmp_path.glob("*.npz"))
    assert result.captured == len(paths) == 1
    problem = files.load(paths[0])
    step = problem.metadata["step"]
    assert paths[0].name == f"K3_step{step:06d}.npz" and problem.name == paths[0].stem
    assert step == 4 and problem.metadata["time"] == pytest.approx(0.4)  # dt = 0.1
    assert problem.family == "scene:K3" and problem.dofs_per_body == 3
    assert problem.metadata["scene"] == str(SCENES / "ura" / "K3.xml")
    assert problem.G.shape == (9, 3) and np.all(problem.m_inv[2::3] > 0)
    assert np.allclose(problem.G[2::3].toarray(), 0.0)  # rotation never touched
    # ball-ball columns: +n and -n, so impulses conserve momentum whatever they are
    assert np.allclose(problem.G[0::3].sum(axis=0), 0) and np.allclose(problem.G[1::3].sum(0), 0)
    assert np.allclose(problem.Q.toarray(), problem.Q.toarray().T)


def test_a_failed_inner_solve_stops_the_run_and_says_so() -> None:
    def no_answer(problem: ImpactProblem, accuracy: float,
                  warm_start: np.ndarray | None) -> SolvedImpulses:
        return SolvedImpulses(np.full(problem.n_contacts, np.nan), 0.0, "solved")

    def choose_solve(operator: ImpactOperator) -> ChosenSolve:
        return ChosenSolve("test-nan", no_answer)

    result = Simulator(load_scene(SCENES / "ura" / "K3.xml"), choose_solve).run(max_steps=10)
    assert result.failure is not None and result.failure["reason"] == "no finite answer"
    assert result.failure["solver"] == "test-nan" and result.failure["solver_status"] == "solved"
    assert result.failure["step"] == 4 and result.steps == 4  # the first impact, then stop
    assert result.as_dict()["success"] is False


def test_a_raising_backend_is_a_failed_inner_solve(monkeypatch: pytest.MonkeyPatch) -> None:
    def raises(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None):
        raise RuntimeError("backend broke")

    registry.all_solvers()
    spec = SolverSpec(name="test-raise", formulation="dual", backend="test", solve=raises)
    monkeypatch.setitem(registry._SOLVERS, spec.key, spec)
    result = Simulator(load_scene(SCENES / "ura" / "K3.xml"),
                       choose_by_name("test-raise")).run(max_steps=10)
    assert result.failure is not None and result.failure["solver"] == "test-raise/dual"
    assert "backend broke" in result.failure["solver_status"]


def test_an_operator_that_needs_a_solver_needs_a_choice() -> None:
    with pytest.raises(ValueError, match="needs an inner solver"):
        Simulator(load_scene(SCENES / "ura" / "K3.xml"))


def test_an_unusable_scene_solver_falls_back_and_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    real_get = inner_solvers.get

    def only_fallback(name: str) -> SolverSpec:
        if name != FALLBACK:
            raise QpbenchError(f"solver '{name}' is not usable here: test")
        return real_get(name)

    monkeypatch.setattr(inner_solvers, "get", only_fallback)
    simulator = Simulator(load_scene(SCENES / "scisim" / "two_balls.xml"), choose_by_name())
    assert [inner.chosen.name for inner in simulator.inner.values()] == [FALLBACK]
    assert len(simulator.notes) == 1 and "'ipopt'" in simulator.notes[0]


def test_simulate_json_has_the_design_keys(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = main(["simulate", str(SCENES / "scisim" / "two_balls.xml"), "--end-time", "2",
                 "--solver", SOLVER, "--capture", str(tmp_path), "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("steps", "impacts", "max_contacts", "energy_initial", "energy_final",
                "max_energy_gain", "momentum_drift", "wall_s", "captured", "x_final", "v_final"):
        assert key in out
    assert out["steps"] == 20 and out["impacts"] == 1 and out["captured"] == 1
    assert len(out["x_final"]) == 2 and len(out["v_final"][0]) == 2
    assert math.isclose(out["energy_final"], out["energy_initial"], rel_tol=TOLERANCE)


def test_simulate_without_end_time_caps_the_steps(capsys: pytest.CaptureFixture) -> None:
    assert main(["simulate", str(SCENES / "ura" / "K3.xml"), "--solver", SOLVER,
                 "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["steps"] == 1000
    assert "no <end_time>" in captured.err


def test_scaling_writes_ratio_and_markdown(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "scaling.json"
    assert main(["scaling", "--sizes", "50,200", "--steps", "2", "-o", str(output)]) == 0
    report = json.loads(output.read_text())
    assert [row["balls"] for row in report["rows"]] == [50, 200]
    assert report["ratio"] > 0 and "| 200 |" in report["markdown"]
    assert all(row["success"] for row in report["rows"])


def test_an_end_time_in_decimal_gives_the_exact_step_count() -> None:
    simulator = Simulator(load_scene(SCENES / "scisim" / "two_balls.xml"), choose_by_name(SOLVER))
    assert simulator.step_count(1.1, None) == 11  # 1.1 / 0.1, not 12 from 1.1's binary value
    assert simulator.step_count(None, 7) == 7 and simulator.step_count(1.1, 5) == 5


def test_cached_impulses_warm_start_and_give_the_same_answer() -> None:
    text = ball2d(HEAD_ON).replace('cache_impulses="0"', 'cache_impulses="1"')
    assert parse_scene(text, "cached.xml").impact.cache_impulses
    result = run(text, end_time=2.0)
    assert np.allclose(result.v_final, [[-0.5, 0.0], [1.0, 0.0]], atol=TOLERANCE)


def test_slow_contacts_are_solved_at_unit_velocity_scale() -> None:
    # touching balls closing at 1.5e-9: on the problem as it is, clarabel's absolute
    # tolerances gave an answer of qpbench's residual 9.6 and the run stopped at its first
    # impact; the inner solve sees the velocities scaled by a power of two instead
    slow = ('<ball x="-0.5" y="0" vx="1e-9" vy="0" m="1" r="0.5" fixed="0"/>'
            '<ball x="0.5" y="0" vx="-0.5e-9" vy="0" m="1" r="0.5" fixed="0"/>')
    result = run(ball2d(slow), steps=3)
    assert np.allclose(result.v_final, [[-0.5e-9, 0.0], [1e-9, 0.0]], rtol=0, atol=1e-15)


def test_the_unit_scale_is_a_power_of_two_that_brings_the_unit_into_a_half_to_one() -> None:
    for unit in (1.5e-9, 1.0, 3.0, 7e20):
        factor = unit_scale(unit, largest_velocity=unit)
        assert 0.5 <= factor * unit < 1.0 and math.frexp(factor)[0] == 0.5
    # a unit tiny beside the velocities (cancellation): scaling would overflow them, so none
    assert unit_scale(1e-300, largest_velocity=1e10) == 1.0


# balls 0 and 2 rest on the floor; ball 1 lands later, so its contact joins between theirs
RESTING_AND_LANDING = ('<ball x="-3" y="0.5" vx="0" vy="0" m="1" r="0.5" fixed="0"/>'
                       '<ball x="0" y="0.6" vx="0" vy="0" m="2" r="0.5" fixed="0"/>'
                       '<ball x="3" y="0.5" vx="0" vy="0" m="3" r="0.5" fixed="0"/>')


class RecordingSolve:
    """clarabel through the registry, recording the warm start of every call by step, and the
    problem as the solver sees it (at unit velocity scale)."""

    def __init__(self) -> None:
        self.solve = solve_with(registry.get(SOLVER))
        self.warm_starts: dict[int, np.ndarray | None] = {}
        self.problems: dict[int, ImpactProblem] = {}

    def __call__(self, problem: ImpactProblem, accuracy: float,
                 warm_start: np.ndarray | None) -> SolvedImpulses:
        self.warm_starts[problem.metadata["step"]] = warm_start
        self.problems[problem.metadata["step"]] = problem
        return self.solve(problem, accuracy, warm_start)


def test_the_warm_start_is_the_previous_steps_impulse_of_each_persisting_contact() -> None:
    text = ball2d(RESTING_AND_LANDING, "lcp", cor=0.0, extra='<gravity fx="0" fy="-9.81"/>'
                  '<static_plane x="0 0" n="0 1"/>').replace('cache_impulses="0"',
                                                             'cache_impulses="1"')
    recording = RecordingSolve()
    events: list[StepEvent] = []
    simulator = Simulator(parse_scene(text, "resting.xml"),
                          lambda operator: ChosenSolve(SOLVER, recording))
    result = simulator.run(max_steps=20, on_step=events.append)
    assert result.failure is None, result.failure
    assert len(recording.warm_starts) >= 10
    for step, warm in recording.warm_starts.items():
        assert step > 0  # the first step starts at rest: b = 0, l = 0 without a solve
        previous = events[step - 1]
        cached = dict(zip(previous.contacts.keys().tolist(), previous.impulses.tolist(),
                          strict=True))
        expected = [cached.get(key, 0.0) for key in events[step].contacts.keys().tolist()]
        # the solver works at unit velocity scale, so its warm start is scaled as b is
        original = events[step].problem
        assert isinstance(original, ImpactProblem)
        factor = np.max(np.abs(recording.problems[step].b)) / np.max(np.abs(original.b))
        assert warm is not None and (warm / factor).tolist() == expected, step
    warm_starts = [warm for warm in recording.warm_starts.values() if warm is not None]
    assert any(np.all(warm > 0) for warm in warm_starts)  # cached impulses reach the solver
    landing = [warm for warm in warm_starts if warm.shape == (3,) and np.any(warm == 0)]
    assert landing and all(warm[1] == 0 and warm[0] > 0 and warm[2] > 0 for warm in landing)


def test_without_the_cache_flag_no_warm_start_reaches_the_solver() -> None:
    text = ball2d(RESTING_AND_LANDING, "lcp", cor=0.0, extra='<gravity fx="0" fy="-9.81"/>'
                  '<static_plane x="0 0" n="0 1"/>')
    recording = RecordingSolve()
    Simulator(parse_scene(text, "resting.xml"),
              lambda operator: ChosenSolve(SOLVER, recording)).run(max_steps=5)
    assert recording.warm_starts and all(w is None for w in recording.warm_starts.values())


def checked_figures() -> list[str]:
    """The energy, momentum and momentum drift of 1,000 bodies drawn from a fixed seed (a
    tenth of them kinematic), in hexadecimal."""
    rng = np.random.default_rng(3)
    bodies = 1000
    masses, inertia = rng.uniform(0.1, 10.0, bodies), rng.uniform(0.01, 1.0, bodies)
    free = rng.random(bodies) > 0.1
    positions, v_start, v_end = (rng.normal(0.0, 5.0, (bodies, 2)) for _ in range(3))
    omega, gravity = rng.normal(0.0, 3.0, bodies), np.array([0.3, -9.81])
    energy = checks.energy(masses, inertia, free, positions, v_start, omega, gravity)
    momentum = checks.momentum(masses, free, v_end)
    drift = checks.momentum_drift(masses, free, v_start, v_end, gravity, 0.25)
    return [float(value).hex() for value in (energy, *momentum, drift)]


def test_the_simulation_checks_do_not_depend_on_blas_kernels_or_simd() -> None:
    """A simulation reports the same energy and momentum on every CPU: the figures of a
    process that rounds as an old CPU does (tests/other_cpu.py) equal this one's."""
    assert printed_elsewhere(__file__) == checked_figures()


if __name__ == "__main__":
    print("\n".join(checked_figures()))
