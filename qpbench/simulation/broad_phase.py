"""Broad phase: candidate ball pairs from a uniform grid, linear in the number of balls.

Each ball's box swept over the step, ``[min(x0, x1) - r, max(x0, x1) + r]``, has
its centre hashed into a square cell of side ``h`` = the largest box extent, so
two boxes can overlap only when their cells are neighbours. The balls are sorted
by cell key (numpy), and each ball is paired with the balls of its own cell
(later in the order) and of four neighbour cells (the other four are covered
from the other side). Work and memory are O(balls + candidates).
"""

from __future__ import annotations

import numpy as np

from qpbench.memory import require

# Half of the 3x3 neighbourhood: with (0, 0) handled separately, every unordered pair of
# neighbouring cells is visited exactly once.
_HALF_NEIGHBOURS = ((1, -1), (1, 0), (1, 1), (0, 1))
_MAX_KEY = 2**62
# a lower bound of the bytes each candidate pair takes at the peak of candidate_pairs: its two
# indices in the lists of ranges, again once concatenated, and one gathered box corner
CANDIDATE_BYTES = 48


def swept_boxes(x0: np.ndarray, x1: np.ndarray, radii: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners of the boxes swept by balls moving from x0 to x1.

    Parameters
    ----------
    x0, x1 : np.ndarray
        (balls, 2) centres at the start and at the end of the step.
    radii : np.ndarray
        (balls,) radii.

    Returns
    -------
    tuple of (np.ndarray, np.ndarray)
        The (balls, 2) lower corners ``min(x0, x1) - r`` and upper corners
        ``max(x0, x1) + r``.
    """
    reach = radii[:, None]
    return np.minimum(x0, x1) - reach, np.maximum(x0, x1) + reach


def candidate_pairs(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Pairs (i, j), i < j, whose boxes overlap, found through the uniform grid of the module.

    Parameters
    ----------
    lower, upper : np.ndarray
        (boxes, 2) lower and upper corners of the axis-aligned boxes.

    Returns
    -------
    np.ndarray
        (pairs, 2) int64 array, each row (i, j) with i < j, rows sorted.

    Raises
    ------
    OutOfMemory
        When the candidate pairs would need more memory than the cap allows
        (:func:`qpbench.memory.require`).
    """
    count = lower.shape[0]
    if count < 2:
        return np.zeros((0, 2), dtype=np.int64)
    centres = 0.5 * (lower + upper)
    extent = float(np.max(upper - lower))
    origin = centres.min(axis=0)
    span = centres.max(axis=0) - origin
    cell = max(extent, 1e-300)
    while np.prod(np.floor(span / cell) + 3.0) >= _MAX_KEY:  # far-flung balls: coarser cells
        cell *= 2.0
    cells = np.floor((centres - origin) / cell).astype(np.int64) + 1
    height = int(np.floor(span[1] / cell)) + 3
    keys = cells[:, 0] * height + cells[:, 1]
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]

    firsts: list[np.ndarray] = []
    seconds: list[np.ndarray] = []
    positions = np.arange(count)
    # same cell: each ball with the balls after it in the sorted order
    same_end = np.searchsorted(sorted_keys, sorted_keys, side="right")
    ranges = [(positions + 1, same_end)]
    for dx, dy in _HALF_NEIGHBOURS:
        neighbour = sorted_keys + dx * height + dy
        ranges.append((np.searchsorted(sorted_keys, neighbour, side="left"),
                       np.searchsorted(sorted_keys, neighbour, side="right")))
    candidates = sum(int(np.maximum(end - start, 0).sum()) for start, end in ranges)
    require(candidates * CANDIDATE_BYTES, f"{candidates} candidate pairs of {count} balls")
    for start, end in ranges:
        _append_ranges(positions, start, end, order, firsts, seconds)
    if not firsts:
        return np.zeros((0, 2), dtype=np.int64)
    first = np.concatenate(firsts)
    second = np.concatenate(seconds)
    overlap = np.all((lower[first] <= upper[second]) & (lower[second] <= upper[first]), axis=1)
    pairs = np.stack([first[overlap], second[overlap]], axis=1)
    pairs.sort(axis=1)
    if pairs.shape[0]:
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs


def _append_ranges(positions: np.ndarray, start: np.ndarray, end: np.ndarray, order: np.ndarray,
                   firsts: list[np.ndarray], seconds: list[np.ndarray]) -> None:
    """For each sorted position p, the pairs (order[p], order[q]) for q in [start_p, end_p)."""
    counts = np.maximum(end - start, 0)
    total = int(counts.sum())
    if total == 0:
        return
    owner = np.repeat(positions, counts)
    offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    partner = np.repeat(start, counts) + offsets
    firsts.append(order[owner])
    seconds.append(order[partner])
