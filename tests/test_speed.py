"""``qpbench speed``: pi-robust against one sparse factorization, on a tiny box packing
(structure and correctness only; no wall-clock assertion)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from qpbench.cli import main
from qpbench.studies.speed import TARGET_RATIO, speed


def test_speed_reports_figures_ratio_and_markdown_per_size() -> None:
    report = speed(sizes=(20, 40), seed=1, repeats=1)
    assert [row["balls"] for row in report["rows"]] == [40, 20]  # largest first
    for row in report["rows"]:
        assert row["factorization_s"] > 0 and row["solve_s"] > 0
        assert row["ratio"] == row["solve_s"] / row["factorization_s"]
        assert row["success"] and row["residual"] <= 1e-8 and row["v_error"] <= 1e-7
        assert row["target_met"] == (row["ratio"] <= TARGET_RATIO)
        assert row["problem"] in report["markdown"]
    assert report["target_met"] == all(row["target_met"] for row in report["rows"])


def test_speed_command_writes_the_json_with_a_markdown_key(tmp_path: Path) -> None:
    output = tmp_path / "speed.json"
    assert main(["speed", "--sizes", "16", "--repeats", "1", "-o", str(output)]) == 0
    report = json.loads(output.read_text())
    assert report["single_threaded_blas"] is True
    assert report["markdown"].startswith("## ") and len(report["rows"]) == 1


def test_speed_command_refuses_zero_repeats(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    output = tmp_path / "speed.json"
    assert main(["speed", "--sizes", "16", "--repeats", "0", "-o", str(output)]) == 2
    assert "--repeats" in capsys.readouterr().err and not output.exists()


def test_speed_command_refuses_a_folder_as_output(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["speed", "--sizes", "16", "--repeats", "1", "-o", str(tmp_path)]) == 2
    assert str(tmp_path) in capsys.readouterr().err
