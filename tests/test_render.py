"""Rendering a simulated scene to PNG and GIF."""

from __future__ import annotations

from pathlib import Path

import pytest

from qpbench.cli import main
from qpbench.errors import QpbenchError
from qpbench.scenes import load_scene
from qpbench.simulation.render import render

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_a_png_shows_a_run_with_its_strongest_impact(tmp_path: Path) -> None:
    output = tmp_path / "cradle.png"
    result = render(load_scene(SCENES / "scisim" / "newtons_cradle.xml"), output,
                    end_time=0.7, solver="clarabel/dual")
    assert result.impacts >= 1
    data = output.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 10_000
    assert not list(tmp_path.glob(".tmp-*"))


def test_a_gif_of_a_scene_with_planes(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "box.gif"
    code = main(["render", str(SCENES / "ura" / "10_balls_in_box.xml"), "-o", str(output),
                 "--steps", "30", "--frames", "6", "--solver", "clarabel/dual"])
    assert code == 0
    assert output.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert f"wrote {output}" in capsys.readouterr().out


def test_a_drum_scene_renders(tmp_path: Path) -> None:
    output = tmp_path / "butterfly.png"
    render(load_scene(SCENES / "scisim" / "butterfly.xml"), output, steps=60,
           solver="clarabel/dual")
    assert output.read_bytes().startswith(PNG_MAGIC)


def test_an_unknown_picture_format_is_refused(tmp_path: Path) -> None:
    with pytest.raises(QpbenchError, match=r"\.png or \.gif"):
        render(load_scene(SCENES / "ura" / "K3.xml"), tmp_path / "k3.jpg", steps=1)
    assert not list(tmp_path.iterdir())
