"""Frictional families: deterministic in their seed, with the outcomes their names promise."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qpbench.bench import problem_sets
from qpbench.cli import main
from qpbench.errors import QpbenchError
from qpbench.problem import files
from qpbench.problem.friction_generate import FRICTION_FAMILIES, generate, tangents_of
from qpbench.problem.friction_reference import attach_reference
from qpbench.problem.generate import generate as generate_frictionless


@pytest.mark.parametrize("family", sorted(FRICTION_FAMILIES))
def test_each_family_is_deterministic_in_its_seed(family: str) -> None:
    first, second = generate(family, seed=3)[0], generate(family, seed=3)[0]
    other = generate(family, seed=4)[0]
    assert first.name == f"{family}-{first.metadata['size']}-s3" and first.family == family
    assert (first.T != second.T).nnz == 0 and first.mu == pytest.approx(second.mu)
    assert first.n_contacts > 0
    assert not (first.G.shape == other.G.shape and np.allclose(first.v_minus, other.v_minus)
                and np.allclose(first.mu, other.mu))


def sticking(problem) -> list[bool]:
    normal, tangential = problem.split(problem.reference.impulses)
    return (np.abs(tangential) < problem.mu * normal * (1 - 1e-9)).tolist()


@pytest.mark.parametrize("seed", range(4))
def test_incline_balls_stick_below_the_friction_angle_and_slide_above(seed: int) -> None:
    problem = attach_reference(generate("incline", seed=seed)[0])
    theta = problem.metadata["theta"]
    assert problem.reference.verified
    assert problem.metadata["sticks"] == [bool(theta <= np.arctan(mu)) for mu in problem.mu]
    assert sticking(problem) == problem.metadata["sticks"]
    assert True in sticking(problem) and False in sticking(problem)


def test_a_sliding_ball_on_the_incline_moves_down_it_and_a_sticking_one_stops() -> None:
    problem = attach_reference(generate("incline", seed=0)[0])
    velocity = problem.reference.v_plus.reshape(-1, 2)
    theta = problem.metadata["theta"]
    along = np.array([np.cos(theta), np.sin(theta)])
    assert velocity[0] == pytest.approx([0.0, 0.0], abs=1e-12)  # sticks
    assert velocity[1] @ along < 0  # slides down
    assert velocity[1] @ np.array([-np.sin(theta), np.cos(theta)]) == pytest.approx(0, abs=1e-12)


def test_rough_floor_discs_carry_the_arm_term_and_stick_by_the_hand_rule() -> None:
    problem = attach_reference(generate("rough-floor", size=3, seed=1)[0])
    T = problem.T.toarray()
    radii = problem.metadata["radii"]
    assert [T[3 * i + 2, i] for i in range(3)] == pytest.approx([-r for r in radii])
    assert problem.reference.verified
    assert sticking(problem) == problem.metadata["sticks"]


def test_pyramid_has_more_unknowns_than_dofs() -> None:
    problem = attach_reference(generate("pyramid", size=2)[0])
    assert (problem.n_bodies, problem.n_contacts) == (3, 5)
    assert 2 * problem.n_contacts > problem.normal.n_dofs  # W is singular
    assert problem.reference.residual <= 1e-12 and problem.reference.solvable


@pytest.mark.parametrize("seed", range(3))
def test_the_jammed_wedge_has_no_solution(seed: int) -> None:
    problem = attach_reference(generate("wedge", seed=seed)[0])
    assert problem.metadata["ccp_unbounded"]
    assert problem.reference.solvable is False
    assert problem.metadata["reference_no_solution_proven"]


def test_friction_mass_ratio_spans_six_decades_and_has_a_reference() -> None:
    problem = attach_reference(generate("friction-mass-ratio", seed=1)[0])
    masses = 1.0 / problem.m_inv
    assert masses.max() / masses.min() > 1e2
    assert problem.reference.residual <= 1e-12


def test_rough_box_tangents_are_the_box_normals_turned_a_quarter() -> None:
    box = generate_frictionless("box", size=30, seed=0, restitution=0.0)[0]
    rough = generate("rough-box", size=30, seed=0)[0]
    assert (rough.G != box.G).nnz == 0
    T = tangents_of(box.G).toarray()
    G = box.G.toarray()
    assert T[0::2] == pytest.approx(-G[1::2]) and T[1::2] == pytest.approx(G[0::2])
    assert np.allclose(np.sum(T * G, axis=0), 0.0)  # t . n = 0 per body


def test_unknown_family_and_bad_size_are_clear_errors() -> None:
    with pytest.raises(QpbenchError, match="unknown frictional family 'nope'"):
        generate("nope")
    with pytest.raises(QpbenchError, match="size must be >= 1"):
        generate("incline", size=0)


def test_qpbench_generate_writes_frictional_problems_with_references(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["generate", "incline", "--count", "2", "-o", str(tmp_path)]) == 0
    assert main(["generate", "wedge", "-o", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "wedge-1-s0: no solution" in captured.err
    problem = files.load(tmp_path / "incline-2-s1.npz")
    assert problem.reference.verified and problem.family == "incline"
    assert files.load(tmp_path / "wedge-1-s0.npz").reference.solvable is False


def test_a_set_file_lists_frictional_families_beside_frictionless_ones(tmp_path: Path) -> None:
    set_file = tmp_path / "small.toml"
    set_file.write_text('[families]\nk3 = { count = 1 }\nincline = { count = 1 }\n'
                        'pyramid = { sizes = [2], count = 1 }\n')
    written = problem_sets.build(set_file, tmp_path / "out")
    assert sorted(path.stem for path in written) == ["incline-2-s0", "k3-3-s0", "pyramid-2-s0"]
    pyramid = files.load(tmp_path / "out" / "pyramid-2-s0.npz")
    assert pyramid.reference is not None and pyramid.reference.residual <= 1e-12
    assert problem_sets.build(set_file, tmp_path / "out") == []
