"""SCISim's coincident centres and kinematic bodies, simulated as SCISim does.

* two bodies with the same centre: SCISim normalises the zero vector to zero, so the pair's
  constraint has a zero normal and does nothing; qpbench leaves it out and says so once;
* a rigidbody2d ``fixed="1"`` body with a velocity is kinematic: it keeps moving at that
  velocity, takes no impulse, and enters its contacts through the relative velocity (``G^T v``
  with its own velocity, the n_rel of SCISim's kinematic constraints);
* a ball2d ``fixed="1"`` ball is an ordinary ball, as in SCISim, whose ball2d reads the flag
  and never scripts a ball; qpbench says so once.
"""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import parse_scene
from qpbench.simulation.stepper import Simulator

SOLVER = "clarabel/dual"


def simulate(text: str, steps: int, solver: str | None = SOLVER):
    simulator = Simulator(parse_scene(text, "test.xml"), choose_by_name(solver))
    result = simulator.run(max_steps=steps)
    assert result.failure is None, result.failure
    return result


def ball2d(balls: str, cor: float = 1.0, dt: str = "0.01", extra: str = "") -> str:
    return (f'<ball2d_scene><integrator type="verlet" dt="{dt}"/>'
            f'<impact_operator type="lcp" CoR="{cor}" v_tol="1e-9" cache_impulses="0">'
            f'<solver name="ipopt"/></impact_operator>{extra}{balls}</ball2d_scene>')


def rigid(bodies: str, geometry: str = '<geometry type="circle" r="0.5"/>', dt: str = "0.01",
          friction: str = "", extra: str = "") -> str:
    operator = friction or ('<impact_operator type="lcp" CoR="1" v_tol="1e-9" '
                            'cache_impulses="0"><solver name="ipopt"/></impact_operator>')
    return (f'<rigidbody2d_scene><integrator type="verlet" dt="{dt}"/>{operator}{extra}'
            f'{geometry}{bodies}</rigidbody2d_scene>')


# --- coincident centres ------------------------------------------------------------------
def test_two_balls_with_the_same_centre_pass_through_each_other_with_one_note() -> None:
    text = ball2d('<ball x="0" y="0" vx="0" vy="-1" m="1" r="1" fixed="0"/>'
                  '<ball x="0" y="0" vx="0" vy="0" m="1" r="1" fixed="0"/>', dt="0.1")
    result = simulate(text, 50)
    assert np.allclose(result.x_final, [[0.0, -5.0], [0.0, 0.0]])
    assert np.allclose(result.v_final, [[0.0, -1.0], [0.0, 0.0]])
    shared = [note for note in result.notes if "share a centre" in note]
    assert len(shared) == 1 and "#0 and #1" in shared[0] and "zero normal" in shared[0]


def test_the_coincident_pair_leaves_the_other_contacts_alone() -> None:
    # a third ball hits the pair's lower ball head-on: that contact is still resolved
    text = ball2d('<ball x="0" y="0" vx="0" vy="0" m="1" r="0.5" fixed="0"/>'
                  '<ball x="0" y="0" vx="0" vy="0" m="1" r="0.5" fixed="0"/>'
                  '<ball x="-1.5" y="0" vx="1" vy="0" m="1" r="0.5" fixed="0"/>')
    result = simulate(text, 100)
    assert result.impacts >= 1
    assert np.max(result.v_final[:2, 0]) > 0.1  # the pair was pushed
    assert abs(result.v_final[:, 0].sum() - 1.0) < 1e-8  # momentum kept


# --- kinematic bodies --------------------------------------------------------------------
def test_a_kinematic_circle_keeps_its_velocity_and_pushes_a_free_one() -> None:
    # elastic hit of an infinitely heavy circle moving at 1: the free one leaves at 2
    text = rigid('<rigid_body x="-1.2 0" theta="0" v="1 0" omega="0" rho="1" geo_idx="0" '
                 'fixed="1"/>'
                 '<rigid_body x="0 0" theta="0" v="0 0" omega="0" rho="1" geo_idx="0"/>')
    result = simulate(text, 50)
    assert np.allclose(result.v_final[0], [1.0, 0.0])
    assert np.allclose(result.x_final[0], [-1.2 + 0.5, 0.0])
    assert np.allclose(result.v_final[1], [2.0, 0.0], atol=1e-7)
    assert result.impacts == 1


def test_a_kinematic_circle_moving_away_takes_no_impulse() -> None:
    text = rigid('<rigid_body x="-0.99 0" theta="0" v="-1 0" omega="0" rho="1" geo_idx="0" '
                 'fixed="1"/>'
                 '<rigid_body x="0 0" theta="0" v="0 0" omega="0" rho="1" geo_idx="0"/>')
    result = simulate(text, 10)
    assert np.allclose(result.v_final[1], 0.0) and result.impacts == 0


def test_a_fixed_ball_of_a_ball2d_scene_moves_like_any_other_as_in_scisim() -> None:
    # SCISim's ball2d never scripts a ball: fixed="1" is read and has no effect. An elastic
    # head-on hit of equal masses swaps the velocities, and gravity pulls the fixed ball too.
    text = ball2d('<ball x="-1.2" y="0" vx="1" vy="0" m="1" r="0.5" fixed="1"/>'
                  '<ball x="0" y="0" vx="0" vy="0" m="1" r="0.5" fixed="0"/>',
                  extra='<gravity fx="0" fy="-1"/>')
    scene = parse_scene(text, "fixed.xml")
    assert not scene.bodies.fixed.any() and scene.balls_alone
    assert [w for w in scene.warnings if '<ball> 0: fixed="1" has no effect' in w]
    result = simulate(text, 50)
    assert result.impacts == 1
    assert np.allclose(result.v_final[:, 0], [0.0, 1.0], atol=1e-7)
    assert np.allclose(result.v_final[:, 1], [-0.5, -0.5])  # 50 steps of 0.01 at g = 1


def test_a_kinematic_rigid_circle_moves_and_spins_as_declared() -> None:
    text = rigid('<rigid_body x="0 0" theta="0" v="0.5 -0.25" omega="3" rho="1" geo_idx="0" '
                 'fixed="1"/>')
    result = simulate(text, 20)
    assert np.allclose(result.x_final[0], [0.1, -0.05])
    assert np.allclose(result.theta_final, [0.6]) and np.allclose(result.omega_final, [3.0])


def test_a_spinning_kinematic_circle_drags_a_free_one_by_friction() -> None:
    # the kinematic wheel spins in place; a free circle resting against it under gravity
    # (pressed on by the wall-ball's side) is driven tangentially by the wheel's surface speed
    friction = ('<sobogus_friction_solver mu="1" CoR="0" max_iters="5000" eval_every="1" '
                'tol="1e-24" cache_impulses="none" staggering="geometric"/>')
    text = rigid('<rigid_body x="0 0" theta="0" v="0 0" omega="-4" rho="1" geo_idx="0" '
                 'fixed="1"/>'
                 '<rigid_body x="0 1" theta="0" v="0 0" omega="0" rho="1" geo_idx="0"/>',
                 friction=friction, extra='<near_earth_gravity f="0 -10"/>', dt="0.001")
    result = simulate(text, 5, solver=None)
    assert np.allclose(result.omega_final[0], -4.0) and np.allclose(result.v_final[0], 0.0)
    assert result.v_final[1, 0] > 0.0  # the top of a clockwise wheel moves to +x


@pytest.mark.parametrize("cor", [0.0, 1.0])
def test_a_kinematic_rigid_circle_hits_a_free_one_as_newton_says(cor: float) -> None:
    text = rigid('<rigid_body x="-1.2 0" theta="0" v="1 0" omega="0" rho="1" geo_idx="0" '
                 'fixed="1"/>'
                 '<rigid_body x="0 0" theta="0" v="0 0" omega="0" rho="1" geo_idx="0"/>')
    text = text.replace('CoR="1"', f'CoR="{cor}"')
    result = simulate(text, 30)
    assert np.allclose(result.v_final[1], [1.0 + cor, 0.0], atol=1e-7)


# --- boxes ---------------------------------------------------------------------------------
SOBOGUS = ('<sobogus_friction_solver mu="{mu}" CoR="0" max_iters="50000" eval_every="1" '
           'tol="1e-24" cache_impulses="none" staggering="geometric"/>')
BOX = '<geometry type="box" r="{hx} {hy}"/>'


def box_on_plane(angle_deg: float, mu: float, theta: float | None = None, y: float = 0.0,
                 omega: float = 0.0, hx: float = 1.0, hy: float = 1.0) -> str:
    """A box resting on a plane tilted by angle_deg (gravity -10 y), flush unless theta."""
    a = np.radians(angle_deg)
    n = [float(-np.sin(a)), float(np.cos(a))]
    theta = float(a if theta is None else theta)
    return rigid(f'<rigid_body x="0 {y}" theta="{theta!r}" v="0 0" omega="{omega}" rho="1" '
                 'geo_idx="0"/>', geometry=BOX.format(hx=hx, hy=hy), dt="0.001",
                 friction=SOBOGUS.format(mu=mu),
                 extra=f'<near_earth_gravity f="0 -10"/><static_plane x="{-hy * n[0]!r} '
                       f'{-hy * n[1]!r}" n="{n[0]!r} {n[1]!r}"/>')


def test_box_mass_and_inertia_are_scisims() -> None:
    scene = parse_scene(rigid('<rigid_body x="0 0" theta="0" v="0 0" omega="0" rho="2" '
                              'geo_idx="0"/>', geometry=BOX.format(hx=0.5, hy=1.5)))
    assert np.allclose(scene.bodies.masses, [2 * 4 * 0.5 * 1.5])
    assert np.allclose(scene.bodies.inertia, [6.0 * (0.25 + 2.25) / 3.0])


# SCISim's geometric map solves on the start-of-step velocity and then integrates gravity
# once more, so a resting body carries g dt downwards at the end of a step and sinks by at
# most g dt^2 per step: "stays put" holds to that lag
G_DT = 10 * 0.001


def test_a_box_resting_on_a_plane_stays_put() -> None:
    result = simulate(box_on_plane(0.0, 0.5), 200, solver=None)
    assert abs(result.x_final[0, 0]) < 1e-12 and -200 * G_DT * 0.001 <= result.x_final[0, 1] <= 0
    assert abs(result.v_final[0, 0]) < 1e-12 and abs(result.v_final[0, 1]) <= G_DT * 1.0001
    assert abs(result.theta_final[0]) < 1e-12 and abs(result.omega_final[0]) < 1e-12
    assert result.max_contacts == 2  # two corners, one constraint each


@pytest.mark.parametrize(("angle", "slides"), [(10.0, False), (25.0, True)])
def test_a_box_on_an_incline_sticks_below_atan_mu_and_slides_above(angle: float,
                                                                   slides: bool) -> None:
    # mu = 0.3: atan(0.3) = 16.7 degrees; a square box tips only above 45 degrees
    steps, mu = 300, 0.3
    result = simulate(box_on_plane(angle, mu), steps, solver=None)
    a = np.radians(angle)
    down = np.array([-np.cos(a), -np.sin(a)])  # along the slope, downhill (plane rises to +x)
    speed = float(result.v_final[0] @ down)
    t = steps * 0.001
    if slides:
        assert abs(speed - 10 * (np.sin(a) - mu * np.cos(a)) * t) <= G_DT and speed > 0.3
    else:
        assert abs(speed) <= G_DT  # the lag above, nothing more
    assert abs(result.omega_final[0]) < 1e-8  # neither tips


def test_a_box_dropped_on_a_corner_turns_the_way_the_torque_says() -> None:
    # tilted +0.3 rad (counter-clockwise), the lowest corner is at the right of the centre;
    # the plane pushes up there, a clockwise torque: omega becomes negative
    text = box_on_plane(0.0, 0.0, theta=0.3, y=0.3)  # the corner 0.05 above the plane
    result = simulate(text, 150, solver=None)
    assert result.impacts > 0 and result.omega_final[0] < -0.1
    mirrored = simulate(box_on_plane(0.0, 0.0, theta=-0.3, y=0.3), 150, solver=None)
    assert np.isclose(mirrored.omega_final[0], -result.omega_final[0], rtol=1e-6)


def test_a_frictionless_box_box_impact_conserves_momentum() -> None:
    text = rigid('<rigid_body x="-1.2 0.3" theta="0.2" v="2 0" omega="1" rho="1" geo_idx="0"/>'
                 '<rigid_body x="1 0" theta="0" v="-1 0" omega="0" rho="1" geo_idx="0"/>',
                 geometry=BOX.format(hx=0.5, hy=0.5))
    result = simulate(text, 60)
    assert result.impacts >= 1
    assert np.allclose(result.v_final.sum(axis=0), [1.0, 0.0], atol=1e-8)
    assert result.max_energy_gain is not None and result.max_energy_gain <= 1e-8
