"""docs/json-output.md documents every field of every JSON output: each command runs here on a
tiny input, and every key of what it prints or writes (and of the committed results/*.json)
must be a row of the command's table in the page, so that the page cannot drift from the
code. Each such command's ``--help`` names the page."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from qpbench.cli import main

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "json-output.md"
SCENES = ROOT / "problems" / "scenes"
HEADING = re.compile(r"^## `qpbench ([a-z-]+)")
ROW = re.compile(r"^\| `([^`]+)` \|")
# the commands whose --help names the page
WITH_EPILOG = ("solvers", "solve", "simulate", "scaling", "speed", "sequence", "breakdown",
               "head-to-head", "sim-precision")


def documented() -> dict[str, list[str]]:
    """command -> the field paths of its table in the page."""
    fields: dict[str, list[str]] = {}
    command = None
    for line in PAGE.read_text().splitlines():
        heading = HEADING.match(line)
        if heading:
            command = heading.group(1)
            fields[command] = []
        elif command is not None and (row := ROW.match(line)):
            fields[command].append(row.group(1))
    return fields


def key_paths(value: Any, prefix: str = "") -> Iterator[str]:
    """Every key of a JSON value as the page writes it: ``a.b`` for a field of an object,
    ``rows[].x`` for a field of the objects of a list."""
    if isinstance(value, dict):
        for key, item in value.items():
            path = f"{prefix}.{key}" if prefix else str(key)
            yield path
            yield from key_paths(item, path)
    elif isinstance(value, list):
        for item in value:
            yield from key_paths(item, f"{prefix}[]")


def field_pattern(field: str) -> re.Pattern[str]:
    """A row's field path as a pattern: ``<name>`` stands for any one key."""
    parts = re.split(r"(<[^>]+>)", field)
    return re.compile("".join(r"[^.\[\]]+" if part.startswith("<") else re.escape(part)
                              for part in parts))


def undocumented(command: str, output: dict[str, Any]) -> list[str]:
    """The key paths of ``output`` that no row of ``command``'s table matches."""
    patterns = [field_pattern(field) for field in documented()[command]]
    return sorted({path for path in key_paths(output)
                   if not any(pattern.fullmatch(path) for pattern in patterns)})


def printed(capsys: pytest.CaptureFixture[str], arguments: list[str], code: int = 0
            ) -> dict[str, Any]:
    assert main(arguments) == code
    return json.loads(capsys.readouterr().out)


def written(tmp_path: Path, arguments: list[str]) -> dict[str, Any]:
    output = tmp_path / f"{arguments[0]}.json"
    assert main([*arguments, "-o", str(output)]) == 0
    return json.loads(output.read_text())


def test_every_table_has_rows_and_every_command_with_json_a_table() -> None:
    fields = documented()
    assert set(fields) == {"solvers", "solve", "simulate", "scaling", "speed", "sequence",
                           "breakdown", "head-to-head", "sim-precision"}
    assert all(fields.values())
    assert "writes NaN, +infinity and -infinity as `null`" in PAGE.read_text()
    assert field_pattern("stopped.<pair>").fullmatch("stopped.osqp/dual")
    assert not field_pattern("stopped.<pair>").fullmatch("stopped.a.b")


@pytest.mark.parametrize("command", WITH_EPILOG)
def test_the_help_names_the_page(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "docs/json-output.md" in capsys.readouterr().out


def test_solvers_and_solve_print_only_documented_fields(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert undocumented("solvers", printed(capsys, ["solvers", "--json"])) == []
    assert main(["generate", "k3", "--count", "1", "-o", str(tmp_path)]) == 0
    assert main(["generate", "incline", "--count", "1", "-o", str(tmp_path)]) == 0
    capsys.readouterr()
    impact = printed(capsys, ["solve", str(tmp_path / "k3-3-s0.npz"), "--solver", "pi-robust",
                              "--json"])
    assert "v_error" in impact and undocumented("solve", impact) == []
    for solver in ("pi-robust/staggered", "pi-robust/ccp"):
        frictional = printed(capsys, ["solve", str(tmp_path / "incline-2-s0.npz"), "--solver",
                                      solver, "--json"])
        assert "model_error" in frictional and undocumented("solve", frictional) == []


def test_simulate_prints_only_documented_fields(capsys: pytest.CaptureFixture[str]) -> None:
    for scene in ("ura/K3.xml", "scisim/horizontal_plane_collision.xml"):
        summary = printed(capsys, ["simulate", str(SCENES / scene), "--steps", "20", "--json"])
        assert undocumented("simulate", summary) == []


def test_the_measurement_commands_write_only_documented_fields(tmp_path: Path) -> None:
    scaling = written(tmp_path, ["scaling", "--sizes", "20,40", "--steps", "1",
                                 "--pile-steps", "1"])
    assert "piles" in scaling and undocumented("scaling", scaling) == []
    speed = written(tmp_path, ["speed", "--sizes", "16", "--repeats", "1"])
    assert undocumented("speed", speed) == []
    sequence = written(tmp_path, ["sequence", str(SCENES / "ura" / "K3.xml"), "--solvers",
                                  "pi-robust/lcp,osqp/dual", "--steps", "2", "--repeats", "1",
                                  "--passes", "2"])
    assert "pass_speedups" in sequence["comparison"]
    assert undocumented("sequence", sequence) == []
    breakdown = written(tmp_path, ["breakdown", "--repeats", "1"])
    assert undocumented("breakdown", breakdown) == []


def test_head_to_head_writes_only_documented_fields(tmp_path: Path) -> None:
    folder = tmp_path / "sets"
    assert main(["generate", "box", "--size", "16", "--count", "1", "-o", str(folder)]) == 0
    bench = tmp_path / "bench.parquet"  # a main table naming one external pair
    pd.DataFrame([{"problem": "box-16-s0", "family": "box", "kind": "impact",
                   "solver": "daqp", "formulation": "dual", "backend": "qpsolvers",
                   "accuracy": 1e-8, "mode": "cold", "success": True, "time_s": 1e-4,
                   "time_limit_s": 10.0}]).to_parquet(bench, index=False)
    report = written(tmp_path, ["head-to-head", str(folder), "--results", str(bench),
                                "--repeats", "1", "--passes", "2"])
    assert report["summary"][0]["external"]["solver"] == "daqp/dual"
    assert undocumented("head-to-head", report) == []


def test_sim_precision_writes_only_documented_fields(tmp_path: Path) -> None:
    friction = ROOT / "problems" / "scisim_fidelity" / "scenes" / "ball2d" / "tests_friction"
    scenes = [SCENES / "ura" / "K3.xml",  # frictionless
              friction / "ball_plane" / "mu_0p5" / "slope_test_posx"
              / "ball_slide_at_threshold.xml",  # frictional, SCISim's state after 50 steps
              friction.parent / "examples_gr" / "bernoullis_problem_gauss_seidel.xml"]  # none
    report = written(tmp_path, ["sim-precision", *map(str, scenes), "--solvers", "pi-robust,nsgs",
                                "--accuracy", "1e-4,1e-8", "--steps", "50", "--no-progress"])
    assert {row["status"] for row in report["rows"]} == {"ok", "skipped"}
    assert any(row["scisim_agrees"] is not None for row in report["rows"])
    assert undocumented("sim-precision", report) == []


@pytest.mark.parametrize("name, command", [("scaling", "scaling"), ("speed", "speed"),
                                           ("sequence", "sequence"), ("breakdown", "breakdown"),
                                           ("head_to_head", "head-to-head")])
def test_the_committed_results_hold_only_documented_fields(name: str, command: str) -> None:
    committed = json.loads((ROOT / "results" / f"{name}.json").read_text())
    assert undocumented(command, committed) == []
