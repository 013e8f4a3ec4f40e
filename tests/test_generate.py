"""Hard-case families: deterministic, with the structure their names promise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qpbench.errors import QpbenchError
from qpbench.problem.generate import FAMILIES, generate, libm


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_each_family_is_deterministic_in_its_seed(family: str) -> None:
    first, second = generate(family, seed=3)[0], generate(family, seed=3)[0]
    other = generate(family, seed=4)[0]
    assert (first.G != second.G).nnz == 0
    assert first.v_minus == pytest.approx(second.v_minus)
    assert first.n_contacts > 0
    assert not (first.G.shape == other.G.shape and np.allclose(first.v_minus, other.v_minus))


def test_k4_has_six_contacts_and_rank_five() -> None:
    k4 = generate("k4")[0]
    assert k4.n_contacts == 6
    assert k4.n_contacts - k4.rank_deficiency == 5


def test_k4_middle_adds_a_ball_and_four_contacts() -> None:
    problem = generate("k4-middle")[0]
    assert (problem.n_bodies, problem.n_contacts) == (5, 10)


def test_grid_is_size_squared_overlapping_balls_with_redundant_contacts() -> None:
    grid = generate("grid", size=10)[0]
    assert grid.n_bodies == 100
    assert grid.n_contacts > grid.n_bodies  # more contacts than bodies: Q is singular
    assert grid.rank_deficiency > 0


def test_mass_ratio_spreads_masses_over_twelve_decades() -> None:
    masses = 1.0 / generate("mass-ratio", size=10)[0].m_inv
    assert masses.min() < 1e-4 and masses.max() > 1e4


def test_near_duplicate_contacts_differ_by_about_a_nanoradian() -> None:
    problem = generate("near-duplicate", size=3)[0]
    columns = problem.G.toarray().T
    unit = columns / np.linalg.norm(columns, axis=1)[:, None]
    cosines = unit @ unit.T - 2 * np.eye(len(unit))
    closest = np.arccos(np.clip(cosines.max(axis=1), -1, 1))
    assert np.all(closest < 1e-7)


def test_box_has_wall_contacts() -> None:
    box = generate("box", size=100)[0]
    one_ball_columns = np.diff(box.G.indptr) == 2  # a wall contact touches one ball's x, y
    assert one_ball_columns.any()


def test_unknown_family_is_a_clear_error() -> None:
    with pytest.raises(QpbenchError, match="unknown family 'k5'"):
        generate("k5")


def test_libm_applies_the_c_librarys_function_to_each_value_and_keeps_the_shape() -> None:
    """Generators take sin, cos, tan, atan and powers from ``math`` (the C library), so that a
    problem's numbers do not depend on which vector code NumPy picks for this CPU."""
    values = np.array([[0.1, 0.7, 1.3], [-2.0, 5.5, 1e-9]])
    result = libm(math.atan, values)
    assert result.shape == values.shape
    assert [float(x) for x in result.ravel()] == [math.atan(float(x)) for x in values.ravel()]
    assert libm(lambda exponent: 10.0 ** exponent, 3.0).shape == ()
    assert float(libm(lambda exponent: 10.0 ** exponent, 3.0)) == 1000.0
