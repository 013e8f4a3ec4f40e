"""Reading SCISim scenes: every shared scene loads; bad input gets one clear line."""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from qpbench.cli import main
from qpbench.errors import InputError, QpbenchError, UnsupportedError
from qpbench.scenes import load_scene, parse_scene
from qpbench.scenes.builders import box_scene, scene_xml, write_scene

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes"
SHARED = sorted(SCENES.rglob("*.xml"))

TWO_BALLS = """<ball2d_scene>
  <integrator type="verlet" dt="0.01"/>
  <impact_operator type="lcp" CoR="1.0" v_tol="1.0e-9" cache_impulses="0">
    <solver name="policy_iteration" max_iters="100" tol="1e-8"/>
  </impact_operator>
  <ball x="-1" y="0" vx="1" vy="0" m="1" r="0.5" fixed="0"/>
  <ball x="1" y="0" vx="-1" vy="0" m="1" r="0.5" fixed="0"/>
</ball2d_scene>"""

ONE_CIRCLE = """<rigidbody2d_scene>
  <integrator type="symplectic_euler" dt="1/10080"/>
  <geometry type="circle" r="0.5"/>
  <rigid_body x="0 0" theta="0" v="1 0" omega="2" rho="2" geo_idx="0"/>
</rigidbody2d_scene>"""


def test_the_shared_scenes_are_there() -> None:
    assert len(SHARED) >= 14


@pytest.mark.parametrize("path", SHARED, ids=lambda p: p.stem)
def test_every_shared_scene_loads(path: Path) -> None:
    scene = load_scene(path)
    assert scene.bodies.count > 0
    assert scene.dt > 0
    assert scene.impact is not None
    assert np.all(scene.bodies.masses > 0) and np.all(scene.bodies.radii > 0)
    assert np.allclose(np.linalg.norm(scene.plane_normals, axis=1), 1.0)


def test_a_ball2d_scene_reads_as_written() -> None:
    scene = load_scene(SCENES / "scisim" / "balls_bouncing_on_wedge_apgd.xml")
    assert scene.dialect == "ball2d" and scene.dofs_per_body == 2
    assert scene.integrator == "verlet" and scene.dt == Fraction(1, 10000)
    assert np.allclose(scene.gravity, [0.0, -10.0])
    assert np.allclose(scene.plane_normals[0], [math.sqrt(0.5), math.sqrt(0.5)])
    assert scene.bodies.masses[0] == 8.0 and scene.bodies.radii[1] == 0.45
    operator = scene.impact
    assert operator.type == "grr" and operator.restitution == 1.0
    assert operator.elastic.type == "gr" and operator.elastic.solver.qpbench_name == "apgd"
    assert operator.inelastic.type == "lcp" and operator.inelastic.restitution == 0.0


def test_a_rigidbody2d_circle_has_mass_rho_pi_r2_and_a_fractional_dt() -> None:
    scene = parse_scene(ONE_CIRCLE, "circle.xml")
    assert scene.dialect == "rigidbody2d" and scene.dofs_per_body == 3
    assert scene.dt == Fraction(1, 10080)
    assert scene.bodies.masses[0] == pytest.approx(2 * math.pi * 0.25)
    assert scene.bodies.inertia[0] == pytest.approx(0.5 * scene.bodies.masses[0] * 0.25)
    assert scene.bodies.omega[0] == 2.0 and not scene.bodies.fixed[0]
    assert scene.gravity is None and scene.impact is None


def test_a_drum_scene_and_the_scene_solver_mapping() -> None:
    scene = load_scene(SCENES / "scisim" / "butterfly.xml")
    assert np.allclose(scene.drum_radii, [4.0])
    assert scene.impact.solver.scisim_name == "ipopt"
    k3 = load_scene(SCENES / "ura" / "K3.xml")
    assert k3.impact.solver.qpbench_name == "pi-robust"


def test_sobogus_with_mu_zero_is_a_frictionless_lcp_with_its_cor() -> None:
    scene = load_scene(SCENES / "scisim" / "ball_ball_ccd_00.xml")
    assert scene.impact.type == "lcp" and scene.impact.restitution == 1.0
    assert scene.impact.declared_by == "sobogus_friction_solver"


def test_unknown_elements_and_attributes_are_accepted_with_one_warning() -> None:
    text = TWO_BALLS.replace("<ball ", '<ball colour="red" ', 1).replace(
        "</ball2d_scene>", '<sound a="0"/><sound a="1"/></ball2d_scene>')
    scene = parse_scene(text, "extra.xml")
    assert len(scene.warnings) == 1
    assert "<sound>" in scene.warnings[0] and "<ball> 'colour'" in scene.warnings[0]


def test_a_scripting_callback_is_never_run(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    script = tmp_path / "callback.py"
    script.write_text(f"open({str(marker)!r}, 'w').write('ran')\n")
    text = TWO_BALLS.replace("</ball2d_scene>", '<scripting callback="callback"/></ball2d_scene>')
    path = tmp_path / "scripted.xml"
    path.write_text(text)
    scene = load_scene(path)
    assert any("never runs code" in warning for warning in scene.warnings)
    assert main(["simulate", str(path), "--steps", "3", "--solver", "clarabel/dual",
                 "--json"]) == 0
    assert not marker.exists()


BAD_SCENES = [
    ("<ball2d_scene><integrator", InputError, "malformed XML"),
    ("<scene/>", InputError, "not a SCISim 2D scene"),
    ("<rigidbody3d_scene/>", UnsupportedError, "not supported"),
    (TWO_BALLS.replace('r="0.5" fixed="0"/>\n  <ball x="1"', 'fixed="0"/>\n  <ball x="1"'),
     InputError, "<ball> attribute 'r': missing"),
    (TWO_BALLS.replace('vx="1"', 'vx="fast"'), InputError, "<ball> attribute 'vx': not a number"),
    (TWO_BALLS.replace('vx="1"', 'vx="nan"'), InputError, "attribute 'vx': must be finite"),
    (TWO_BALLS.replace('r="0.5"', 'r="-0.5"', 1), InputError, "attribute 'r': must be positive"),
    (TWO_BALLS.replace('m="1"', 'm="0"', 1), InputError, "attribute 'm': must be positive"),
    (TWO_BALLS.replace('dt="0.01"', 'dt="0"'), InputError, "<integrator> attribute 'dt'"),
    (TWO_BALLS.replace('dt="0.01"', 'dt="1/0"'), InputError, "<integrator> attribute 'dt'"),
    (TWO_BALLS.replace('type="verlet"', 'type="rk4"'), InputError, "<integrator> attribute 'type'"),
    (TWO_BALLS.replace('CoR="1.0"', 'CoR="1.5"'), InputError, "attribute 'CoR': must lie in"),
    (TWO_BALLS.replace('fixed="0"', 'fixed="yes"', 1), InputError, "attribute 'fixed'"),
    (TWO_BALLS.replace('name="policy_iteration"', 'name="magic"'), InputError,
     "<solver> attribute 'name': unknown SCISim solver"),
    (TWO_BALLS.replace('<integrator type="verlet" dt="0.01"/>', ""), InputError,
     "<integrator>: missing"),
    (ONE_CIRCLE.replace('geo_idx="0"', 'geo_idx="1"'), InputError,
     "<rigid_body> attribute 'geo_idx': out of range"),
    (ONE_CIRCLE.replace('type="circle" r="0.5"', 'type="box" r="1 0"'), InputError,
     "<geometry> attribute 'r': must be positive"),
    (ONE_CIRCLE.replace('type="circle" r="0.5"', 'type="box" r="1 nan"'), InputError,
     "<geometry> attribute 'r': must be finite"),
    (ONE_CIRCLE.replace('v="1 0"', 'v="1"'), InputError, "expected two numbers"),
    # magnitudes whose products (energies, squared distances) would overflow, or whose
    # inverses would
    (TWO_BALLS.replace('vx="1"', 'vx="1e300"'), InputError,
     "<ball> attribute 'vx': out of range: '1e300' (qpbench reads magnitudes up to 1e+40)"),
    (TWO_BALLS.replace('r="0.5"', 'r="1e-300"', 1), InputError,
     "<ball> attribute 'r': out of range: '1e-300' (qpbench reads magnitudes up to 1e+40, "
     "positive values from 1e-40)"),
    (ONE_CIRCLE.replace('v="1 0"', 'v="1 -1e50"'), InputError,
     "<rigid_body> attribute 'v': out of range"),
    (ONE_CIRCLE.replace('type="circle" r="0.5"', 'type="box" r="1 1e-50"'), InputError,
     "<geometry> attribute 'r': out of range"),
    (TWO_BALLS.replace('dt="0.01"', 'dt="1e400"'), InputError,
     "<integrator> attribute 'dt': out of range"),
    (TWO_BALLS.replace('dt="0.01"', f'dt="{10 ** 400}/1"'), InputError,
     "<integrator> attribute 'dt': out of range"),
    # refused before Fraction would build 10^999999999 exactly (for minutes)
    (TWO_BALLS.replace('dt="0.01"', 'dt="1e-999999999"'), InputError,
     "<integrator> attribute 'dt': out of range: an exponent of more than four digits"),
    (TWO_BALLS.replace('dt="0.01"', 'dt="0.01x"'), InputError,
     "<integrator> attribute 'dt': not a decimal or a fraction"),
    (TWO_BALLS.replace("</ball2d_scene>", '<static_plane x="0 -5" n="0 1"/><static_plane '
                       'x="0 5" n="0 -1"/><planar_portal planeA="0" planeB="0"/></ball2d_scene>'),
     InputError, "<planar_portal> attribute 'planeB': plane 0 is already a portal plane"),
]

SOBOGUS = ('<sobogus_friction_solver mu="0.5" CoR="0" max_iters="50" eval_every="1" tol="1e-12" '
           'cache_impulses="none" staggering="geometric"/>')


def with_friction(element: str, scene: str = TWO_BALLS) -> str:
    """``scene`` with its impact operator replaced by a friction solver element."""
    start, end = scene.index("  <impact_operator"), scene.index("</impact_operator>")
    return scene[:start] + "  " + element + scene[end + len("</impact_operator>"):]


FRICTION_CIRCLE = ONE_CIRCLE.replace("</rigidbody2d_scene>", SOBOGUS + "</rigidbody2d_scene>")
BAD_SCENES += [
    (with_friction(SOBOGUS.replace('mu="0.5"', 'mu="-0.1"')), InputError,
     "<sobogus_friction_solver> attribute 'mu': must be >= 0"),
    (with_friction(SOBOGUS.replace('mu="0.5"', 'mu="nan"')), InputError,
     "<sobogus_friction_solver> attribute 'mu': must be finite"),
    (with_friction(SOBOGUS.replace(' tol="1e-12"', '')), InputError,
     "<sobogus_friction_solver> attribute 'tol': missing"),
    (with_friction(SOBOGUS.replace(' cache_impulses="none"', '')), InputError,
     "<sobogus_friction_solver> attribute 'cache_impulses': missing"),
    (with_friction(SOBOGUS.replace('CoR="0"', 'CoR="1.2"')), InputError,
     "<sobogus_friction_solver> attribute 'CoR': must lie in [0, 1]"),
    (with_friction(SOBOGUS.replace('max_iters="50"', 'max_iters="0"')), InputError,
     "<sobogus_friction_solver> attribute 'max_iters': must be a positive integer"),
    (with_friction(SOBOGUS.replace('eval_every="1"', 'eval_every="51"')), InputError,
     "<sobogus_friction_solver> attribute 'eval_every': must be <= max_iters"),
    (with_friction(SOBOGUS.replace('tol="1e-12"', 'tol="-1"')), InputError,
     "<sobogus_friction_solver> attribute 'tol': must be >= 0"),
    (with_friction(SOBOGUS.replace('"none"', '"all"')), InputError,
     "<sobogus_friction_solver> attribute 'cache_impulses': must be one of"),
    (with_friction(SOBOGUS.replace('"geometric"', '"leapfrog"')), InputError,
     "<sobogus_friction_solver> attribute 'staggering': must be one of"),
    (with_friction(SOBOGUS.replace('"geometric"', '"symplectic_euler" stabilization="0" '
                                   'penetration_threshold="1e-5"').replace('CoR="0"',
                                                                           'CoR="0.5"')),
     InputError, "<sobogus_friction_solver> attribute 'CoR': must be 0 for the "
                 "symplectic_euler staggering"),
    (with_friction(SOBOGUS.replace('"geometric"', '"symplectic_euler" stabilization="0"')),
     InputError, "<sobogus_friction_solver> attribute 'penetration_threshold': missing"),
    (with_friction(SOBOGUS.replace('"geometric"', '"stabilized"').replace(
        '"none"', '"normal"')), InputError,
     "<sobogus_friction_solver> attribute 'cache_impulses': must be none for the stabilized"),
    (FRICTION_CIRCLE.replace('"geometric"', '"symplectic_euler" stabilization="0" '
                             'penetration_threshold="1e-5"'), InputError,
     "<sobogus_friction_solver> attribute 'staggering': must be one of geometric, stabilized"),
    (with_friction('<staggered_projections_friction_solver mu="0.5" CoR="0" tol="1e-8" '
                   'max_iters="20" staggering="geometric"><lcp_impact_solver name="ipopt"/>'
                   '</staggered_projections_friction_solver>'), InputError,
     "<mdp_friction_solver>: missing"),
    (FRICTION_CIRCLE.replace('type="circle" r="0.5"', 'type="box" r="-1 1"'), InputError,
     "<geometry> attribute 'r': must be positive"),
    (with_friction(SOBOGUS).replace("</ball2d_scene>", '<static_plane x="0 -5" n="0 1"/>'
                                    '<static_plane x="0 5" n="0 -1"/><planar_portal planeA="0"'
                                    ' planeB="2"/></ball2d_scene>'),
     InputError, "<planar_portal> attribute 'planeB': names plane 2"),
]

BAD_SCENES += [
    # a chain of grr operators is refused at its second link, not followed until Python's
    # recursion limit
    (TWO_BALLS.replace('<impact_operator type="lcp" CoR="1.0" v_tol="1.0e-9" cache_impulses="0">'
                       '\n    <solver name="policy_iteration" max_iters="100" tol="1e-8"/>',
                       '<impact_operator type="grr" CoR="0.5">'
                       + '<elastic_operator type="grr">' * 5000
                       + '</elastic_operator>' * 5000), InputError,
     "<elastic_operator> attribute 'type': a grr cannot nest another grr"),
    ('<?xml version="1.0" encoding="no-such-encoding"?>' + TWO_BALLS, InputError,
     "malformed XML: unknown encoding"),
    # a value of any length is quoted in at most a few dozen characters
    (TWO_BALLS.replace('r="0.5"', 'r="' + "1" * 100_000 + '"', 1), InputError,
     "<ball> attribute 'r': must be finite, got '1111111111111111111111111111111111111111'... "
     "(100000 characters)"),
    (with_friction(SOBOGUS.replace('max_iters="50"', 'max_iters="' + "9" * 4000 + '"')),
     InputError, "<sobogus_friction_solver> attribute 'max_iters': out of range"),
]


def test_a_sobogus_solver_with_friction_reads_every_attribute() -> None:
    scene = parse_scene(with_friction(SOBOGUS.replace('"geometric"', '"symplectic_euler" '
                                                      'stabilization="1" '
                                                      'penetration_threshold="1e-5"')),
                        "rough.xml")
    friction = scene.friction
    assert scene.impact is None and scene.frictional and scene.staggering == "symplectic_euler"
    assert (friction.kind, friction.mu, friction.restitution) == ("sobogus", 0.5, 0.0)
    assert (friction.max_iters, friction.eval_every, friction.tol) == (50, 1, 1e-12)
    assert friction.cache_impulses == "none" and friction.stabilization
    assert friction.penetration_threshold == 1e-5
    assert friction.residual_asked == pytest.approx(1e-6)


def test_mu_zero_keeps_the_frictionless_lcp_and_records_the_staggering() -> None:
    scene = parse_scene(with_friction(SOBOGUS.replace('mu="0.5"', 'mu="0"').replace(
        '"geometric"', '"stabilized"')), "smooth.xml")
    assert scene.impact.type == "lcp" and not scene.frictional
    assert scene.staggering == "stabilized" and scene.friction.mu == 0.0


def test_staggered_projections_name_their_inner_solvers() -> None:
    scene = parse_scene(with_friction(
        '<staggered_projections_friction_solver mu="0.3" CoR="0.5" tol="1e-8" max_iters="20" '
        'staggering="geometric" internal_warm_start_alpha="1" internal_warm_start_beta="1">'
        '<lcp_impact_solver name="ql" tol="1e-12"/><mdp_friction_solver name="ql" tol="1e-12"/>'
        '</staggered_projections_friction_solver>'), "sp.xml")
    friction = scene.friction
    assert friction.kind == "staggered_projections" and friction.mu == 0.3
    assert friction.impact_solver.qpbench_name == "pi-robust"
    assert friction.friction_solver_name == "ql" and friction.residual_asked == 1e-8


def test_a_frictional_scene_written_back_reads_the_same(tmp_path: Path) -> None:
    scene = parse_scene(with_friction(SOBOGUS), "rough.xml")
    again = load_scene(write_scene(scene, tmp_path / "rough.xml"))
    assert again.friction == scene.friction


@pytest.mark.parametrize(("text", "error", "message"), BAD_SCENES,
                         ids=[f"{e.__name__}-{m[:30]}" for _, e, m in BAD_SCENES])
def test_bad_scenes_get_one_clear_line(text: str, error: type, message: str) -> None:
    with pytest.raises(error) as raised:
        parse_scene(text, "bad.xml")
    line = str(raised.value)
    assert line.startswith("bad.xml") and message in line and "\n" not in line


BOMB = """<?xml version="1.0"?>
<!DOCTYPE lolz [
  <!ENTITY lol "lol">
  <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
  <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<ball2d_scene><camera name="&lol4;"/></ball2d_scene>"""


def test_an_entity_expansion_bomb_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture
                                             ) -> None:
    with pytest.raises(InputError, match="refused"):
        parse_scene(BOMB, "bomb.xml")
    path = tmp_path / "bomb.xml"
    path.write_text(BOMB)
    assert main(["simulate", str(path), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and "refused" in captured.err


def test_an_external_entity_is_refused() -> None:
    text = ('<?xml version="1.0"?><!DOCTYPE s [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
            "<ball2d_scene>&x;</ball2d_scene>")
    with pytest.raises(InputError, match="refused"):
        parse_scene(text, "external.xml")


def test_a_warning_names_at_most_ten_unknown_attributes() -> None:
    attributes = " ".join(f'extra{index}="1"' for index in range(500))
    scene = parse_scene(TWO_BALLS.replace("<ball ", f"<ball {attributes} ", 1), "many.xml")
    assert len(scene.warnings) == 1 and scene.warnings[0].endswith("and 490 more")
    assert len(scene.warnings[0]) < 400


def test_a_missing_file_is_one_line(capsys: pytest.CaptureFixture) -> None:
    assert main(["simulate", "no/such/scene.xml"]) == 2
    err = capsys.readouterr().err
    assert "no such scene file" in err and err.count("\n") == 1


def test_written_scenes_read_back_the_same(tmp_path: Path) -> None:
    for scene in (box_scene(30, seed=3), load_scene(SCENES / "ura" / "K3.xml"),
                  load_scene(SCENES / "scisim" / "balls_bouncing_on_wedge_apgd.xml"),
                  load_scene(SCENES / "scisim" / "butterfly.xml")):
        again = load_scene(write_scene(scene, tmp_path / f"{scene.name}.xml"))
        assert again.dialect == scene.dialect and again.dt == scene.dt
        assert np.array_equal(again.bodies.positions, scene.bodies.positions)
        assert np.array_equal(again.bodies.velocities, scene.bodies.velocities)
        assert np.allclose(again.bodies.masses, scene.bodies.masses, rtol=1e-14)
        assert np.allclose(again.plane_normals, scene.plane_normals, rtol=0, atol=1e-15)
        assert np.array_equal(again.drum_radii, scene.drum_radii)
        assert again.impact.type == scene.impact.type
        assert again.warnings == []
    assert "<ball2d_scene>" in scene_xml(box_scene(2))


def test_a_box_scene_starts_without_overlap_inside_its_walls() -> None:
    scene = box_scene(200, seed=1)
    x, r = scene.bodies.positions, scene.bodies.radii
    gaps = np.linalg.norm(x[:, None] - x[None, :], axis=2) + np.eye(len(x)) * 1e9
    assert np.min(gaps) > 2 * r[0]
    for point, normal in zip(scene.plane_points, scene.plane_normals, strict=True):
        assert np.all((x - point) @ normal > r)
    with pytest.raises(ValueError):
        box_scene(0)


def test_every_error_is_a_qpbench_error() -> None:
    assert issubclass(InputError, QpbenchError) and issubclass(UnsupportedError, QpbenchError)
