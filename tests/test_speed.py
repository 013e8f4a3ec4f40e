"""``qpbench speed``: pi-robust against one sparse factorization, on a tiny box packing
(structure and correctness only; no wall-clock assertion)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.cli import main
from qpbench.problem.generate import generate
from qpbench.solvers import sparse_cholesky
from qpbench.studies.factorization import (
    FACTOR_SHIFT,
    METHODS,
    fastest,
    shifted_block,
    time_factorizations,
    time_once,
)
from qpbench.studies.speed import FACTORIZATIONS, TARGET_RATIO, speed


def test_speed_reports_figures_ratio_and_markdown_per_size() -> None:
    report = speed(sizes=(20, 40), seed=1, repeats=1)
    assert [row["balls"] for row in report["rows"]] == [40, 20]  # largest first
    for row in report["rows"]:
        assert row["factorization_s"] > 0 and row["solve_s"] > 0
        assert row["ratio"] == row["solve_s"] / row["factorization_s"]
        assert row["success"] and row["residual"] <= 1e-8 and row["v_error"] <= 1e-7
        assert row["target_met"] == (row["ratio"] <= TARGET_RATIO)
        assert row["problem"] in report["markdown"]
        # one sparse factorization: the fastest of CHOLMOD and SuperLU's two orderings
        by_method = row["factorization_s_by_method"]
        assert list(by_method) == list(FACTORIZATIONS)
        assert row["factorization_s"] == min(by_method.values())
        assert by_method[row["factorization_method"]] == row["factorization_s"]
        assert row["factorization_library"] == row["factorization_method"].split("/")[0]
        assert (f"{1e3 * row['factorization_s']:.2f} ({row['factorization_method']})"
                in report["markdown"])
    assert report["target_met"] == all(row["target_met"] for row in report["rows"])
    assert ("CHOLMOD/AMD" in FACTORIZATIONS) == (sparse_cholesky.LIBRARY == "CHOLMOD")
    assert {"SuperLU/MMD_AT_PLUS_A", "SuperLU/COLAMD"} <= set(FACTORIZATIONS)
    assert all(f"{method} [ms]" in report["markdown"] for method in FACTORIZATIONS)


def test_the_shifted_block_is_q_over_the_chosen_contacts_plus_a_tiny_diagonal() -> None:
    problem = generate("box", 20, seed=1)[0]
    dense = problem.Q.toarray()
    shift = FACTOR_SHIFT * np.max(np.abs(problem.diag_Q))
    chosen = np.array([0, 2, 5])
    block = shifted_block(problem, chosen)
    assert block.shape == (3, 3) and sp.isspmatrix_csc(block)
    np.testing.assert_allclose(block.toarray(),
                               dense[np.ix_(chosen, chosen)] + shift * np.eye(3), rtol=1e-15)
    np.testing.assert_allclose(shifted_block(problem).toarray(),
                               dense + shift * np.eye(problem.n_contacts), rtol=1e-15)


def test_the_fastest_factorization_skips_failed_calls_and_names_its_library() -> None:
    picked = fastest({"CHOLMOD/AMD": [3.0, math.nan, 2.0], "SuperLU/COLAMD": [2.5],
                      "SuperLU/MMD_AT_PLUS_A": [math.nan]})
    assert picked == {"factorization_s": 2.0, "factorization_method": "CHOLMOD/AMD",
                      "factorization_library": "CHOLMOD",
                      "factorization_s_by_method": {"CHOLMOD/AMD": 2.0, "SuperLU/COLAMD": 2.5,
                                                    "SuperLU/MMD_AT_PLUS_A": None}}
    nothing = fastest({"SuperLU/COLAMD": [math.nan]})
    assert nothing["factorization_s"] is None and nothing["factorization_library"] is None
    singular = sp.csc_matrix(np.array([[1.0, 0.0], [0.0, 0.0]]))
    assert math.isnan(time_once(singular, sparse_cholesky.symmetric_splu))
    timed = time_factorizations(sp.csc_matrix(np.array([[2.0, 1.0], [1.0, 2.0]])), repeats=2)
    assert timed["factorization_s"] > 0 and set(timed["factorization_s_by_method"]) == set(METHODS)
    assert timed["factorization_library"] in ("CHOLMOD", "SuperLU")


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
