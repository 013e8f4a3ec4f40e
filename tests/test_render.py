"""Rendering a simulated scene to PNG and GIF: what the pictures show, read back as pixels."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from matplotlib.collections import PatchCollection
from PIL import Image

from qpbench.cli import main
from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import load_scene, parse_scene
from qpbench.simulation import render as render_module
from qpbench.simulation.render import render

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
CLARABEL = choose_by_name("clarabel/dual")
WHITE = np.array([1.0, 1.0, 1.0])


def inside_point(outline: np.ndarray) -> np.ndarray:
    """Half a radius above the centre of a circle drawn with outline vertices ``outline``."""
    lower, upper = outline.min(axis=0), outline.max(axis=0)
    centre = 0.5 * (lower + upper)
    return centre + np.array([0.0, 0.25 * (upper[1] - lower[1])])


class DrawnBalls:
    """Wraps render's ``_save``: before writing, records for every axes of the figure that
    draws balls its ball collections: a point inside every ball, as a pixel (row, column)
    of the saved image."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.axes: list[list[np.ndarray]] = []  # per axes, per collection: (balls, 2)
        self.height = 0
        real_save = render_module._save

        def save(figure, path, write) -> None:
            figure.canvas.draw()
            self.height = int(round(figure.get_figheight() * figure.dpi))
            for axes in figure.axes:
                collections = []
                for collection in axes.collections:
                    if isinstance(collection, PatchCollection):
                        # half a radius above each centre: inside the ball, off the
                        # contact normals drawn through centres of a row of balls
                        points = np.array([inside_point(path.vertices) for path in
                                           collection.get_paths()]).reshape(-1, 2)
                        pixels = axes.transData.transform(points)
                        collections.append(np.column_stack([self.height - pixels[:, 1],
                                                            pixels[:, 0]]))
                if collections:  # not the colour bar
                    self.axes.append(collections)
            real_save(figure, path, write)

        monkeypatch.setattr(render_module, "_save", save)


def colour_at(image: np.ndarray, pixel: np.ndarray) -> np.ndarray:
    """RGB of ``image`` (rows, columns, RGB[A] in 0..1) at a (row, column) pixel."""
    row, column = np.round(pixel).astype(int)
    return image[row, column, :3]


def test_a_png_shows_every_ball_where_it_ended_and_the_strongest_impact(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    drawn = DrawnBalls(monkeypatch)
    output = tmp_path / "cradle.png"
    scene = load_scene(SCENES / "scisim" / "newtons_cradle.xml")
    result = render(scene, output, end_time=0.7, choose_solve=CLARABEL)
    assert result.impacts >= 1
    assert output.read_bytes().startswith(PNG_MAGIC)
    assert not list(tmp_path.glob(".tmp-*"))
    image = matplotlib.image.imread(output)
    assert image.shape[0] == drawn.height and image.shape[1] == 2 * drawn.height  # two panels
    impact_axes, run_axes = drawn.axes
    assert [centres.shape[0] for centres in impact_axes] == [scene.bodies.count]
    start, end = run_axes  # dashed outlines at the start, filled balls at the end
    assert start.shape[0] == end.shape[0] == scene.bodies.count == 3
    for point in [*end, *impact_axes[0]]:
        colour = colour_at(image, point)
        assert not np.allclose(colour, WHITE, atol=0.02), point
        assert colour[2] > colour[0]  # blue: tab:blue over white
    corner = colour_at(image, np.array([drawn.height * 0.92, drawn.height * 1.9]))
    assert np.allclose(corner, WHITE, atol=0.02)  # background where nothing is drawn


def test_a_gif_of_a_scene_with_planes_has_one_frame_per_stride_and_the_last(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "box.gif"
    code = main(["render", str(SCENES / "ura" / "10_balls_in_box.xml"), "-o", str(output),
                 "--steps", "30", "--frames", "6", "--solver", "clarabel/dual"])
    assert code == 0
    assert output.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert f"wrote {output}" in capsys.readouterr().out
    with Image.open(output) as gif:
        assert gif.n_frames == 7  # steps 0, 5, ..., 25 (stride 30 // 6) and the end
        frames = []
        for index in range(gif.n_frames):
            gif.seek(index)
            frames.append(np.asarray(gif.convert("RGB"), dtype=float))
    assert all(not np.array_equal(a, b) for a, b in zip(frames, frames[1:], strict=False))
    first = frames[0] / 255.0
    blue = (first[..., 2] > first[..., 0] + 0.2) & (first[..., 2] > 0.5)
    assert blue.sum() > 100  # the balls


def test_a_drum_scene_draws_its_balls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    drawn = DrawnBalls(monkeypatch)
    output = tmp_path / "butterfly.png"
    scene = load_scene(SCENES / "scisim" / "butterfly.xml")
    render(scene, output, steps=60, choose_solve=CLARABEL)
    image = matplotlib.image.imread(output)
    end = drawn.axes[-1][-1]
    assert end.shape[0] == scene.bodies.count
    inside = [point for point in end
              if 0 <= point[0] < image.shape[0] and 0 <= point[1] < image.shape[1]]
    assert len(inside) == scene.bodies.count
    assert all(not np.allclose(colour_at(image, point), WHITE, atol=0.02) for point in inside)


def test_an_unknown_picture_format_is_refused(tmp_path: Path) -> None:
    with pytest.raises(QpbenchError, match=r"\.png or \.gif"):
        render(load_scene(SCENES / "ura" / "K3.xml"), tmp_path / "k3.jpg", steps=1,
               choose_solve=CLARABEL)
    assert not list(tmp_path.iterdir())


# a box (half-widths 2 x 0.5) turned by 0.5 rad and a circle turned by 0, both at rest
BOX_AND_CIRCLE = """<rigidbody2d_scene>
  <integrator type="verlet" dt="0.01"/>
  <geometry type="box" r="2.0 0.5"/>
  <geometry type="circle" r="0.5"/>
  <rigid_body x="0 0" theta="0.5" v="0 0" omega="0" rho="1" geo_idx="0"/>
  <rigid_body x="4 0" theta="0" v="0 0" omega="0" rho="1" geo_idx="1"/>
</rigidbody2d_scene>
"""


def render_one_step(scene: str, output: Path, monkeypatch: pytest.MonkeyPatch) -> list:
    """Renders ``scene`` (XML text) after one step to ``output`` with ``qpbench render`` and
    returns the (axes, figure) pairs drawn, for mapping world points to pixels."""
    scene_path = output.with_suffix(".xml")
    scene_path.write_text(scene)
    axes_seen: list = []
    real_save = render_module._save

    def save(figure, path, write) -> None:
        figure.canvas.draw()
        axes_seen.extend((axes, figure) for axes in figure.axes)
        real_save(figure, path, write)

    monkeypatch.setattr(render_module, "_save", save)
    assert main(["render", str(scene_path), "-o", str(output), "--steps", "1"]) == 0
    return axes_seen


def test_a_box_is_drawn_as_its_rotated_rectangle_and_a_circle_with_its_radius_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    output = tmp_path / "box.png"
    axes_seen = render_one_step(BOX_AND_CIRCLE, output, monkeypatch)
    image = matplotlib.image.imread(output)
    (axes, figure), = axes_seen  # no impact: one panel
    height = int(round(figure.get_figheight() * figure.dpi))

    def colour(world: np.ndarray) -> np.ndarray:
        x, y = axes.transData.transform(world)
        return colour_at(image, np.array([height - y, x]))

    c, s = np.cos(0.5), np.sin(0.5)
    rotation = np.array([[c, -s], [s, c]])
    near_corner = rotation @ np.array([1.8, 0.4])  # inside the rotated box, by a corner
    outside = rotation @ np.array([0.0, 1.0])  # off the box, inside its circumcircle (2.06)
    unrotated = np.array([1.8, 0.0])  # inside the box were theta ignored, outside at 0.5 rad
    assert np.hypot(*outside) < np.hypot(2.0, 0.5)
    drawn = colour(near_corner)
    assert not np.allclose(drawn, WHITE, atol=0.02) and drawn[2] > drawn[0]
    assert np.allclose(colour(outside), WHITE, atol=0.02)
    assert np.allclose(colour(unrotated), WHITE, atol=0.02)
    # the circle: a radius line along theta = 0, darker than the disc's fill beside it
    line, fill = colour(np.array([4.3, 0.0])), colour(np.array([4.0, 0.3]))
    assert not np.allclose(fill, WHITE, atol=0.02)
    assert line[0] < fill[0] - 0.15 and line[2] > line[0]


def test_the_recorded_angles_follow_a_spinning_circle() -> None:
    text = BOX_AND_CIRCLE.replace('theta="0" v="0 0" omega="0"', 'theta="0" v="0 0" omega="50"')
    spinning = parse_scene(text, "spin.xml")
    _, recording = render_module.simulate_and_record(spinning, None, 3, None, 10)
    assert recording.frame_thetas[0] is not None
    assert np.allclose(recording.frame_thetas[0], [0.5, 0.0])
    assert np.allclose(recording.frame_thetas[-1], [0.5, 3 * 0.01 * 50])


PORTAL_SCENE = """<ball2d_scene>
  <integrator type="symplectic_euler" dt="0.01"/>
  <ball x="0" y="0" vx="0.5" vy="0" m="1" r="0.5" fixed="0"/>
  <static_plane x="-3 0" n="1 0"/>
  <static_plane x="3 0" n="-1 0"/>
  <planar_portal planeA="0" planeB="1"/>
</ball2d_scene>
"""


def test_a_portal_is_drawn_as_its_two_planes_dashed_in_one_colour(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (axes, _figure), = render_one_step(PORTAL_SCENE, tmp_path / "portal.png", monkeypatch)
    portal_lines = [line for line in axes.get_lines() if line.get_label() == "portal"]
    assert len(portal_lines) == 2  # plane A and plane B
    assert {line.get_linestyle() for line in portal_lines} == {"--"}
    assert len({line.get_color() for line in portal_lines}) == 1
    xs = sorted(float(np.mean(line.get_xdata())) for line in portal_lines)
    assert xs == pytest.approx([-3.0, 3.0])
