"""The stable counting sort behind the colour order and the reverse Cuthill-McKee seeds."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from qpbench.solvers.counting_sort import stable_order


def test_equal_keys_keep_their_index_order() -> None:
    np.testing.assert_array_equal(stable_order(np.array([2, 0, 2, 1, 0])), [1, 4, 3, 0, 2])


def test_no_keys_give_an_empty_order() -> None:
    assert stable_order(np.zeros(0, dtype=np.int64)).size == 0


@settings(max_examples=80, deadline=None)
@given(keys=st.lists(st.integers(0, 30), max_size=60))
def test_it_is_numpys_stable_argsort(keys: list[int]) -> None:
    values = np.array(keys, dtype=np.int64)
    np.testing.assert_array_equal(stable_order(values), np.argsort(values, kind="stable"))
