"""Planar and Lees-Edwards portals (qpbench.simulation.portals): parsing, teleporting,
contacts across the boundary, momentum, and the shear a Lees-Edwards box imposes."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from qpbench.errors import InputError, UnsupportedError
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import parse_scene
from qpbench.simulation.stepper import Simulator

WALLS = ('<static_plane x="-2 0" n="1 0"/><static_plane x="2 0" n="-1 0"/>'
         '<static_plane x="0 -2" n="0 1"/><static_plane x="0 2" n="0 -1"/>')


def box(balls: str, portals: str, mu: float = 0.0) -> str:
    return (f'<ball2d_scene><integrator type="verlet" dt="0.01"/>'
            f'<sobogus_friction_solver mu="{mu}" CoR="1.0" max_iters="5000" eval_every="25" '
            f'tol="1.0e-12" staggering="geometric" cache_impulses="none"/>'
            f'{WALLS}{portals}{balls}</ball2d_scene>')


def run(text: str, steps: int):
    scene = parse_scene(text, "portal.xml")
    return scene, Simulator(scene, choose_by_name(None)).run(max_steps=steps)


@pytest.mark.parametrize("portal, attribute", [
    ('<planar_portal planeA="0" planeB="7"/>', "planeB"),
    ('<planar_portal planeA="1" planeB="1"/>', "planeB"),
    ('<lees_edwards_portal planeA="0" planeB="1" v="nan" bounds="1"/>', "v"),
    ('<lees_edwards_portal planeA="0" planeB="1" v="1" bounds="0"/>', "bounds"),
])
def test_a_bad_portal_is_refused_naming_file_element_and_attribute(portal: str,
                                                                   attribute: str) -> None:
    with pytest.raises(InputError) as raised:
        parse_scene(box("", portal), "bad.xml")
    message = str(raised.value)
    assert "bad.xml" in message and attribute in message and "portal" in message
    assert "\n" not in message


def test_portal_planes_are_no_longer_walls() -> None:
    scene = parse_scene(box("", '<planar_portal planeA="0" planeB="1"/>'), "p.xml")
    assert len(scene.portals) == 1 and scene.plane_points.shape == (2, 2)


def test_a_ball_leaving_through_one_plane_comes_back_through_the_other() -> None:
    _, result = run(box('<ball x="1.95" y="0.3" vx="1" vy="0" m="1" r="0.1" fixed="0"/>',
                        '<planar_portal planeA="0" planeB="1"/>'), 20)
    assert result.x_final[0, 0] == pytest.approx(-2.0 + 0.15, abs=1e-9)
    assert result.x_final[0, 1] == pytest.approx(0.3)
    assert result.v_final[0, 0] == pytest.approx(1.0)


def test_momentum_across_a_plain_portal_is_conserved() -> None:
    # the balls meet only across the portal: x = 1.85 and x = -1.85 are 0.3 apart through it
    balls = ('<ball x="1.85" y="0.0" vx="1" vy="0.2" m="1" r="0.2" fixed="0"/>'
             '<ball x="-1.85" y="0.05" vx="-1" vy="0" m="2" r="0.2" fixed="0"/>')
    scene, result = run(box(balls, '<planar_portal planeA="0" planeB="1"/>'), 30)
    assert result.impacts >= 1
    masses = scene.bodies.masses
    before = masses @ scene.bodies.velocities
    after = masses @ result.v_final
    assert np.allclose(before, after, atol=1e-9)
    assert result.v_final[0, 0] < 0  # they bounced off each other through the portal


def test_a_lees_edwards_box_builds_the_shear_profile_it_imposes() -> None:
    rng = np.random.default_rng(3)
    balls = []
    for i in range(6):
        for j in range(6):
            x, y = -1.65 + 0.66 * i, -1.65 + 0.66 * j
            vx, vy = rng.normal(0, 0.1, 2)
            balls.append(f'<ball x="{x}" y="{y}" vx="{vx}" vy="{vy}" m="1" r="0.3" fixed="0"/>')
    # planes y = -2 and y = 2 form the Lees-Edwards portal, x = -2 and 2 a plain one
    portals = ('<planar_portal planeA="0" planeB="1"/>'
               '<lees_edwards_portal planeA="2" planeB="3" v="2.0" bounds="2.0"/>')
    scene, result = run(box("".join(balls), portals, mu=0.5), 600)
    assert result.failure is None
    y, vx = result.x_final[:, 1], result.v_final[:, 0]
    lower, upper = vx[y < -0.7].mean(), vx[y > 0.7].mean()
    assert upper > lower + 0.2
    assert np.polyfit(y, vx, 1)[0] > 0.1


def test_portals_with_box_geometry_are_refused_in_one_line() -> None:
    scene = """<rigidbody2d_scene>
      <integrator type="symplectic_euler" dt="0.01"/>
      <geometry type="box" r="0.5 0.5"/>
      <rigid_body x="0 0" theta="0" v="1 0" omega="0" rho="1" geo_idx="0" fixed="0"/>
      <static_plane x="-2 0" n="1 0"/>
      <static_plane x="2 0" n="-1 0"/>
      <planar_portal planeA="0" planeB="1"/>
    </rigidbody2d_scene>"""
    with pytest.raises(UnsupportedError) as raised:
        parse_scene(scene, "boxes.xml")
    message = str(raised.value)
    assert message.startswith("boxes.xml: <planar_portal>") and "box geometry" in message
    assert "\n" not in message


def test_balls_whose_centres_meet_through_a_portal_make_no_contact_and_no_warning() -> None:
    """A ball at x = 1.9 and one at x = -2.1 (past the plane x = -2) share a centre through the
    portal, which maps x to x + 4: no normal exists there, so the pair is inert and left out,
    as ball_ball leaves out two balls with one centre, without a division by zero."""
    balls = ('<ball x="1.9" y="0.0" vx="0" vy="0" m="1" r="0.1" fixed="0"/>'
             '<ball x="-2.1" y="0.0" vx="0" vy="0" m="1" r="0.1" fixed="0"/>')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, result = run(box(balls, '<planar_portal planeA="0" planeB="1"/>'), 3)
    assert result.failure is None and result.impacts == 0
    assert np.all(np.isfinite(result.x_final))
