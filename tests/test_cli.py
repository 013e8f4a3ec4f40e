"""The command line as a user meets it: generate, import-dump, solve; one-line errors; the
measurement commands' defaults."""

from __future__ import annotations

import importlib
import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from qpbench.cli import build_parser
from qpbench.errors import MAX_LINE, one_line

DUMPS = Path(__file__).resolve().parents[1] / "problems" / "dumps"


def qpbench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "qpbench.cli", *args], capture_output=True,
                          text=True, timeout=300)


def test_import_dumps_then_clarabel_solves_grid5_to_1e_8(tmp_path: Path) -> None:
    imported = qpbench("import-dump", *map(str, sorted(DUMPS.glob("*"))), "-o", str(tmp_path))
    assert imported.returncode == 0, imported.stderr
    assert len(list(tmp_path.glob("*.npz"))) == 4
    solved = qpbench("solve", str(tmp_path / "grid5_itr_0.npz"), "--solver", "clarabel", "--json")
    result = json.loads(solved.stdout)
    assert result["residual"] <= 1e-8
    assert result["success"] is True
    assert result["v_error"] <= 1e-6
    assert len(result["lambda"]) == 46


def test_generate_writes_seeded_problems(tmp_path: Path) -> None:
    done = qpbench("generate", "k4", "--count", "2", "-o", str(tmp_path))
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k4-4-s0.npz", "k4-4-s1.npz"]


@pytest.mark.slow
def test_generate_box_scene_writes_a_scene_that_simulates(tmp_path: Path) -> None:
    done = qpbench("generate", "box", "--scene", "--size", "50", "-o", str(tmp_path))
    assert done.returncode == 0, done.stderr
    simulated = qpbench("simulate", str(tmp_path / "box-50-s0.xml"), "--steps", "5", "--json")
    assert simulated.returncode == 0, simulated.stderr
    assert len(json.loads(simulated.stdout)["x_final"]) == 50


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("solve", "missing.npz", "--solver", "osqp"), "missing.npz: no such problem file"),
        (("generate", "k9", "-o", "x"), "unknown family 'k9'"),
        (("import-dump", __file__, "-o", "x"), "test_cli.py: malformed dump"),
        # values outside their range are refused before any file is read or written
        (("solve", "missing.npz", "--solver", "osqp", "--accuracy", "nan"),
         "qpbench solve: --accuracy: accuracy levels must lie in (0, 1), got nan"),
        (("simulate", "missing.xml", "--accuracy", "-1"), "lie in (0, 1), got -1.0"),
        (("simulate", "missing.xml", "--end-time", "nan"),
         "--end-time must be at least 0, got nan"),
        (("render", "missing.xml", "--frames", "0", "-o", "x.gif"),
         "--frames must be at least 1, got 0"),
        (("generate", "k4", "--seed", "-1", "-o", "x"), "--seed must be at least 0, got -1"),
        (("run", "missing.npz", "--workers", "0", "-o", "x.parquet"),
         "--workers must be at least 1, got 0"),
        (("speed", "--seed", "-1", "-o", "x.json"), "--seed must be at least 0, got -1"),
        (("scaling", "--seed", "-1", "-o", "x.json"), "--seed must be at least 0, got -1"),
        # what argparse itself refuses: one line too, the usage left to -h
        (("solve",), "qpbench solve: the following arguments are required: problem, --solver "
                     "(usage: qpbench solve -h)"),
        (("run", "missing.npz", "--repeats", "two", "-o", "x.parquet"),
         "qpbench run: argument --repeats: invalid int value: 'two'"),
        (("solve", "missing.npz", "--solver", "osqp", "--bogus"),
         "qpbench: unrecognized arguments: --bogus"),
        (("nope",), "qpbench: argument COMMAND: invalid choice: 'nope'"),
    ],
)
def test_bad_input_is_one_line_and_nonzero(args: tuple[str, ...], message: str) -> None:
    done = qpbench(*args)
    assert done.returncode == 2
    assert message in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert "Traceback" not in done.stderr


def test_unknown_solver_is_one_line(tmp_path: Path) -> None:
    qpbench("generate", "k3", "-o", str(tmp_path))
    done = qpbench("solve", str(tmp_path / "k3-3-s0.npz"), "--solver", "nope")
    assert done.returncode == 2
    assert "unknown solver 'nope'" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_a_problem_file_with_a_row_index_outside_g_is_refused_before_any_solver_runs(
        tmp_path: Path) -> None:
    """pi-robust's compiled kernel reads G's row indices unchecked: loading must refuse them."""
    qpbench("generate", "k4", "-o", str(tmp_path))
    path = tmp_path / "k4-4-s0.npz"
    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays["G_indices"][-1] = 10**6
    with open(path, "wb") as stream:
        np.savez_compressed(stream, **arrays)
    done = qpbench("solve", str(path), "--solver", "pi-robust")
    assert done.returncode == 2
    assert done.stderr.startswith(f"qpbench solve: {path} attribute 'G': not a valid sparse "
                                  "matrix (")
    assert len(done.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("command", "required", "measurement", "options"),
    [
        ("head-to-head", ["folder", "--results", "bench.parquet"], "head_to_head",
         ("repeats", "passes", "candidates")),
        ("sequence", [], "sequence", ("steps", "accuracy", "repeats")),
        ("speed", [], "speed", ("sizes", "repeats")),
        ("breakdown", [], "breakdown", ("repeats",)),
    ],
)
def test_a_measurement_command_defaults_to_what_its_measurement_defaults_to(
        command: str, required: list[str], measurement: str, options: tuple[str, ...]) -> None:
    arguments = build_parser(only=command.replace("-", "_")).parse_args(
        [command, *required, "-o", "out.json"])
    module = importlib.import_module(f"qpbench.studies.{measurement}")
    defaults = inspect.signature(getattr(module, measurement)).parameters
    for option in options:
        assert getattr(arguments, option) == defaults[option].default, option


def test_an_error_line_escapes_line_breaks_and_is_cut_short() -> None:
    """An error may quote a damaged file's bytes (a zip member's name, a library's message):
    printed, it stays one printable line of bounded length."""
    assert one_line("bad.npz attribute 'm_i\nv': \x00 here") == \
        "bad.npz attribute 'm_i\\nv': \\x00 here"
    long = one_line("x" * 5000)
    assert long.endswith("... (5000 characters)") and len(long) < MAX_LINE + 30
    assert one_line("plain") == "plain"
