"""ImpactProblem: Q, b and v+ from G, M^-1, v-, c; files that round-trip without pickle."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from friction_cases import ball_on_floor

from qpbench.errors import InputError
from qpbench.problem import files
from qpbench.problem.friction import FrictionalReference
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


def rewrite(path: Path, change: Callable[[dict[str, np.ndarray]], None]) -> None:
    """Rewrites the arrays of the problem file at ``path`` through ``change``."""
    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    change(arrays)
    with open(path, "wb") as stream:
        np.savez_compressed(stream, **arrays)


def rewrite_header(path: Path, change: Callable[[dict], None]) -> None:
    """Rewrites the JSON header of the problem file at ``path`` through ``change``."""
    def change_header(arrays: dict[str, np.ndarray]) -> None:
        header = json.loads(arrays["header_json"].tobytes().decode())
        change(header)
        arrays["header_json"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    rewrite(path, change_header)


@pytest.mark.parametrize("version", [files.FORMAT_VERSION + 1, "2.0", None, "x" * 1000,
                                     ["x"] * 1000])
def test_a_file_of_another_format_version_is_one_line_naming_the_field(
        tmp_path: Path, version: object) -> None:
    path = files.save(head_on_pair(), tmp_path / "pair")
    rewrite_header(path, lambda header: header.update(format=version))
    with pytest.raises(InputError) as raised:
        files.load(path)
    message = str(raised.value)
    assert message.startswith(f"{path} attribute 'format': format version ")
    assert "reads versions 1 and 2" in message and "\n" not in message
    assert len(message) < len(str(path)) + 200  # a long value is quoted cut short


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


def set_array(key: str, value: object) -> Callable[[dict[str, np.ndarray]], None]:
    return lambda arrays: arrays.update({key: np.asarray(value)})


def set_entry(key: str, index: int, value: float) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        arrays[key] = arrays[key].copy()
        arrays[key][index] = value
    return change


# the head-on pair's file holds G (4 x 1, rows 0 and 2), M^-1, v-, c, nrel and a reference
@pytest.mark.parametrize(
    ("change", "attribute", "message"),
    [
        (lambda arrays: arrays.pop("m_inv"), "m_inv", "missing array"),
        (lambda arrays: arrays.pop("ref_v_plus"), "ref_v_plus", "missing array"),
        (lambda arrays: arrays.pop("header_json"), "header_json", "missing array"),
        (set_array("header_json", np.frombuffer(b"{nope", dtype=np.uint8)), "header_json",
         "corrupt problem file header"),
        (set_array("header_json", np.frombuffer(b"[" * 100_000, dtype=np.uint8)),
         "header_json", "corrupt problem file header"),
        (set_entry("G_indices", 1, 10**6), "G", "not a valid sparse matrix"),
        (set_entry("G_indices", 0, -3), "G", "not a valid sparse matrix"),
        (set_array("G_indices", [2, 2]), "G_indices", "unsorted or repeated"),
        (set_array("G_indptr", [2, 0]), "G", "not a valid sparse matrix"),
        (set_array("G_shape", [[4, 1], [4, 1]]), "G_shape", "one-dimensional integer array"),
        (set_array("G_shape", [4, -1]), "G_shape", "two sizes >= 0"),
        (set_array("G_data", [1.0]), "G", "not a valid sparse matrix"),
        (set_entry("G_data", 0, 1e300), "G", r"magnitudes above 1e\+90"),
        (set_entry("n_rel", 0, 1e300), "n_rel", r"magnitudes above 1e\+90"),
        (set_entry("m_inv", 0, 1e-300), "m_inv", "at least 1e-90"),
        (set_array("v_minus", ["x", "y", "z", "w"]), "v_minus", "one-dimensional real array"),
        (set_array("ref_v_plus", np.zeros((2, 4))), "ref_v_plus", "one-dimensional real array"),
        (set_array("ref_v_plus", np.zeros(3)), "ref_v_plus", "does not match G"),
        (set_entry("ref_impulses", 0, np.nan), "ref_impulses", "NaN"),
        (set_array("data_warm_start", [np.inf]), "data_warm_start", "NaN or infinity"),
        (set_array("data_warm_start", [1.0, 2.0]), "data_warm_start", "does not match G"),
        (set_array("data_contact_keys", [0.5]), "data_contact_keys", "integer array"),
    ],
)
def test_a_damaged_problem_file_is_one_line_naming_the_array(
        tmp_path: Path, change: Callable[[dict[str, np.ndarray]], None], attribute: str,
        message: str) -> None:
    problem = attach_reference(head_on_pair())
    problem.data.update(warm_start=np.ones(1), contact_keys=np.array([7]))  # as a capture's
    path = files.save(problem, tmp_path / "pair")
    files.load(path)  # the undamaged file loads
    rewrite(path, change)
    with pytest.raises(InputError) as raised:
        files.load(path)
    assert str(raised.value).startswith(f"{path} attribute '{attribute}': ")
    assert re.search(message, str(raised.value)) and "\n" not in str(raised.value)


@pytest.mark.parametrize(
    ("change", "attribute", "message"),
    [
        (lambda header: header["reference"].pop("agreement"), "reference.agreement", "missing"),
        (lambda header: header["reference"].update(method=3), "reference.method",
         "must be str, got 3"),
        (lambda header: header["reference"].update(tolerance=True), "reference.tolerance",
         "must be int or float, got True"),
        (lambda header: header.update(reference=[]), "reference", "must be dict"),
        (lambda header: header.update(dofs_per_body="2"), "dofs_per_body", "must be int"),
        (lambda header: header.update(dofs_per_body=0), "dofs_per_body", "must be at least 1"),
        (lambda header: header.update(metadata=[]), "metadata", "must be dict"),
        (lambda header: header.update(data="warm_start"), "data", "must be list"),
        (lambda header: header.update(data=[1]), "data", "must list the names"),
        (lambda header: header.update(data=["warm_start"]), "data_warm_start", "missing array"),
    ],
)
def test_a_damaged_header_is_one_line_naming_the_field(
        tmp_path: Path, change: Callable[[dict], None], attribute: str, message: str) -> None:
    path = files.save(attach_reference(head_on_pair()), tmp_path / "pair")
    rewrite_header(path, change)
    with pytest.raises(InputError) as raised:
        files.load(path)
    assert str(raised.value).startswith(f"{path} attribute '{attribute}': {message}")


def test_fields_a_reader_does_not_know_are_left_alone(tmp_path: Path) -> None:
    path = files.save(attach_reference(head_on_pair()), tmp_path / "pair")
    rewrite_header(path, lambda header: header["reference"].update(note="checked by hand"))
    assert files.load(path).reference.verified


# a ball on the floor with friction: T (2 x 1, row 0), mu, d_rel and its reference
@pytest.mark.parametrize(
    ("change", "attribute", "message"),
    [
        (set_entry("T_indices", 0, 10**6), "T", "not a valid sparse matrix"),
        (lambda arrays: arrays.pop("mu"), "mu", "missing array"),
        (set_entry("d_rel", 0, -1e300), "d_rel", r"magnitudes above 1e\+90"),
        (set_array("fref_impulses", np.zeros(1)), "fref_impulses", "does not match G"),
        (set_array("header_json", np.frombuffer(json.dumps(
            {"format": 2, "kind": "frictional", "name": "ball", "frictional_reference": {
                "method": "enumeration", "residual": "small", "unique": True}}).encode(),
            dtype=np.uint8)), "frictional_reference.residual", "must be int or float"),
    ],
)
def test_a_damaged_frictional_file_is_one_line_naming_the_array(
        tmp_path: Path, change: Callable[[dict[str, np.ndarray]], None], attribute: str,
        message: str) -> None:
    problem = ball_on_floor(u_normal=-1.0, u_tangential=0.5, mu=0.5)
    problem.reference = FrictionalReference(impulses=np.array([1.0, -0.5]),
                                            v_plus=np.zeros(2), method="enumeration",
                                            residual=0.0, unique=True)
    path = files.save(problem, tmp_path / "ball")
    assert files.load(path).reference.verified  # the undamaged file loads
    rewrite(path, change)
    with pytest.raises(InputError) as raised:
        files.load(path)
    assert str(raised.value).startswith(f"{path} attribute '{attribute}': ")
    assert re.search(message, str(raised.value))
