"""The greedy colouring that orders the Gauss-Seidel sweeps (pgs, nsgs, staggered's box QP)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from qpbench.solvers import colouring


def random_pattern(size: int, density: float, seed: int) -> sp.csr_matrix:
    """A symmetric sparse pattern with its diagonal (as Q's)."""
    pattern = sp.random(size, size, density=density, random_state=seed, format="csr")
    return sp.csr_matrix(pattern + pattern.T + sp.identity(size))


def test_three_contacts_in_a_row_take_two_colours() -> None:
    chain = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]]))
    np.testing.assert_array_equal(colouring.colours_of(chain), [0, 1, 0])
    np.testing.assert_array_equal(colouring.colour_order(chain.indptr, chain.indices), [0, 2, 1])


@settings(max_examples=60, deadline=None)
@given(size=st.integers(0, 40), density=st.floats(0.0, 0.5), seed=st.integers(0, 10_000))
def test_each_contact_takes_the_smallest_colour_its_earlier_neighbours_leave(
        size: int, density: float, seed: int) -> None:
    pattern = random_pattern(size, density, seed)
    colours = colouring.colours_of(pattern)
    for i in range(size):
        neighbours = pattern.indices[pattern.indptr[i]:pattern.indptr[i + 1]]
        others = neighbours[neighbours != i]
        assert colours[i] not in colours[others]  # no two neighbours share a colour
        earlier = set(colours[others[others < i]].tolist())
        assert colours[i] == min(set(range(size + 1)) - earlier)  # greedy: the smallest free


@settings(max_examples=60, deadline=None)
@given(size=st.integers(0, 40), density=st.floats(0.0, 0.5), seed=st.integers(0, 10_000))
def test_the_order_is_class_by_class_and_by_index_within_a_class(
        size: int, density: float, seed: int) -> None:
    pattern = random_pattern(size, density, seed)
    expected = np.argsort(colouring.colours_of(pattern), kind="stable")
    np.testing.assert_array_equal(colouring.colour_order(pattern.indptr, pattern.indices),
                                  expected)
