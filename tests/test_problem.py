"""ImpactProblem: Q, b and v+ from G, M^-1, v-, c; files that round-trip without pickle."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.errors import InputError
from qpbench.problem import files
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference


def head_on_pair(restitution: float = 1.0) -> ImpactProblem:
    """Two unit balls on the x axis, a at x = -1 moving right, b at x = 0 moving left."""
    n_ab = np.array([-1.0, 0.0])  # (x_a - x_b) / |x_a - x_b|
    G = np.concatenate([n_ab, -n_ab])[:, None]
    return ImpactProblem.build("pair", G, np.ones(4), [1.0, 0.0, -1.0, 0.0], restitution)


def test_q_and_b_follow_the_definitions() -> None:
    problem = head_on_pair(restitution=0.5)
    assert problem.Q.toarray() == pytest.approx(np.array([[2.0]]))
    # u- = G^T v- = -2 (approaching), b = (1 + c) u- = -3
    assert problem.b == pytest.approx([-3.0])
    assert problem.v_plus(np.array([1.0])) == pytest.approx([0.0, 0.0, 0.0, 0.0])


def test_three_collinear_balls_give_the_singular_q_of_the_design() -> None:
    k3 = generate("k3")[0]
    assert k3.Q.toarray() == pytest.approx(np.array([[2, 1, -1], [1, 2, 1], [-1, 1, 2]]))
    assert k3.rank_deficiency == 1


def test_save_and_load_round_trip_keeps_everything(tmp_path) -> None:
    problem = attach_reference(generate("grid", size=3, seed=4)[0])
    problem.data["warm_start"] = np.arange(problem.n_contacts, dtype=float)
    path = files.save(problem, tmp_path / problem.name)
    loaded = files.load(path)
    assert (loaded.G != problem.G).nnz == 0
    assert loaded.v_minus == pytest.approx(problem.v_minus)
    assert loaded.metadata == problem.metadata
    assert loaded.data["warm_start"] == pytest.approx(problem.data["warm_start"])
    assert loaded.reference.v_plus == pytest.approx(problem.reference.v_plus)
    assert loaded.reference.verified
    with np.load(path, allow_pickle=False) as archive:  # readable with pickle refused
        assert "header_json" in archive.files


def test_a_truncated_file_is_one_clear_error(tmp_path) -> None:
    path = files.save(head_on_pair(), tmp_path / "pair")
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(InputError, match="pair.npz"):
        files.load(path)


def rewrite_header(path: Path, change: Callable[[dict], None]) -> None:
    """Rewrites the JSON header of the problem file at ``path`` through ``change``."""
    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    header = json.loads(arrays["header_json"].tobytes().decode())
    change(header)
    arrays["header_json"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    with open(path, "wb") as stream:
        np.savez_compressed(stream, **arrays)


@pytest.mark.parametrize("version", [files.FORMAT_VERSION + 1, "2.0", None])
def test_a_file_of_another_format_version_is_one_line_naming_the_field(
        tmp_path: Path, version: object) -> None:
    path = files.save(head_on_pair(), tmp_path / "pair")
    rewrite_header(path, lambda header: header.update(format=version))
    with pytest.raises(InputError) as raised:
        files.load(path)
    message = str(raised.value)
    assert message.startswith(f"{path} attribute 'format': format version ")
    assert "reads versions 1 and 2" in message and "\n" not in message


def test_a_file_without_a_name_is_one_line_naming_the_field(tmp_path: Path) -> None:
    path = files.save(head_on_pair(), tmp_path / "pair")
    rewrite_header(path, lambda header: header.pop("name"))
    with pytest.raises(InputError) as raised:
        files.load(path)
    assert str(raised.value) == (f"{path} attribute 'name': missing: every problem file "
                                 "names its problem")


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("v_minus", [1.0, 0.0, np.nan, 0.0], "NaN"),
        ("v_minus", [1.0, 0.0], "shape"),
        ("m_inv", [1.0, -1.0, 1.0, 1.0], ">= 0"),
        ("restitution", 1.5, r"\[0, 1\]"),
    ],
)
def test_bad_data_names_the_field(field: str, value: object, message: str) -> None:
    arguments = {"m_inv": np.ones(4), "v_minus": [1.0, 0.0, -1.0, 0.0], "restitution": 1.0}
    arguments[field] = value
    G = sp.csc_matrix(np.array([[-1.0], [0.0], [1.0], [0.0]]))
    with pytest.raises(InputError, match=f"'{field}'.*{message}"):
        ImpactProblem.build("bad", G, **arguments)
