"""A stable counting sort of small non-negative integer keys, compiled (numba): the order of
contacts by colour (``colouring``) and by degree (the reverse Cuthill-McKee seeds of
``pi_robust_kernel.ordering``). It takes O(n + largest key) operations where
``np.argsort(kind="stable")``, a merge sort, takes O(n log n) (Knuth, "The Art of Computer
Programming", vol. 3, section 5.2, algorithm D)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def stable_order(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for non-negative integer keys.

    The indices by rising key, by index among equal keys. Counts per key, their running sums
    as each key's first place, then each index put at its key's next place
    (O(n + largest key)).

    Parameters
    ----------
    keys : np.ndarray
        Non-negative integers, shape (n,).

    Returns
    -------
    np.ndarray
        The permutation, shape (n,), int64.
    """
    n = keys.size
    largest = 0
    for key in keys:
        largest = max(largest, key)
    starts = np.zeros(largest + 2, dtype=np.int64)
    for key in keys:
        starts[key + 1] += 1
    for key in range(largest + 1):
        starts[key + 1] += starts[key]
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[starts[keys[i]]] = i
        starts[keys[i]] += 1
    return order
