"""The timing protocol (docs/design.md section 7): the order in which timed calls run.

A solver timed on repeats of one problem back to back finds its whole working set (its code,
its workspace, the problem's arrays, the branch history of this very solve) still in the
caches, and a small compiled kernel gains far more from that than a solver with a larger
working set. So no measurement times repeats back to back. Every measurement hands its
timed calls of a *batch* (problems x pairs x levels x variants, each repeated) to a
:class:`Schedule`, which runs them in *rounds*:

* round 0 (when asked for): one untimed warm-up per *unit*, a (problem, solver/formulation)
  pair, on the unit's first item, so that no timed call pays a cold start another escapes;
* rounds 1, 2, ...: every item still running once; an item leaves after its last round
  (:meth:`Schedule.retire`: its repeats are done, its budget spent, or it failed).

Within a round the calls are ordered so that no two consecutive calls (across the round
boundaries too) belong to the same unit whenever another unit has calls left in that round:
the unit with the most calls left goes next, other than the one just run, ties broken in the
round's rotation of the units (round r starts r places further along the units' order). So
the repeats of an item are separated by every other item of the batch, the levels of one
unit by the other units' calls, and the order changes from round to round. Only when a round
holds the calls of one unit alone (a batch of one problem and one pair) do they follow each
other. ``time_s`` of an item is then the minimum over its interleaved repeats
(:func:`fastest`), ``time_median_s`` their median.

The *cold* variant of a measurement calls :func:`flush_caches` before each timed call,
outside the stopwatch: it writes a buffer as large as the last-level cache the operating
system reports (at most ``FLUSH_CAP_BYTES``), evicting the previous calls' code and data.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Hashable, Iterator, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Generic, TypeVar

import numpy as np

Item = TypeVar("Item")

WARM_UP_ROUND = 0
# the largest buffer flush_caches writes: on a host that reports a far larger last-level cache
# (a virtual machine may report a whole socket's), writing it all before every timed call
# would take longer than the solves measured
FLUSH_CAP_BYTES = 32 * 2**20
# used when the operating system reports no cache sizes
FLUSH_FALLBACK_BYTES = 32 * 2**20
CACHE_FOLDER = Path("/sys/devices/system/cpu/cpu0/cache")


@dataclass(frozen=True)
class Call(Generic[Item]):
    """One call of a schedule: ``item``, the ``index``-th of the batch, in round ``round``
    (0: its unit's untimed warm-up)."""

    item: Item
    index: int
    round: int

    @property
    def timed(self) -> bool:
        """Whether the call is timed (every round but the warm-up round)."""
        return self.round != WARM_UP_ROUND


class Schedule(Generic[Item]):
    """The calls of a batch of ``items`` in interleaved, rotated rounds (module docstring).

    Parameters
    ----------
    items
        What to time, in a canonical order (problem-major, say); each item is timed up to
        ``repeats`` times, once per round.
    repeats
        Timed rounds at most.
    unit
        The unit of an item: its (problem, solver/formulation) pair. Two consecutive calls
        share a unit only when nothing else is left in the round.
    warm_up
        Whether round 0 warms up every unit once, untimed, on its first item in ``items``.

    Iterating yields :class:`Call` objects; a round's order is fixed when the round starts,
    from the items not retired by then.
    """

    def __init__(self, items: Sequence[Item], repeats: int, unit: Callable[[Item], Hashable],
                 warm_up: bool = False) -> None:
        self.items = list(items)
        self.repeats = repeats
        self.unit = unit
        self.warm_up = warm_up
        self._retired: set[int] = set()
        self._units: list[Hashable] = list(dict.fromkeys(unit(item) for item in self.items))

    def retire(self, index: int) -> None:
        """Take the ``index``-th item out of every later round.

        Parameters
        ----------
        index : int
            The item's position in ``items`` (its repeats are done, its budget spent, or it failed).
        """
        self._retired.add(index)

    def __iter__(self) -> Iterator[Call[Item]]:
        previous: Hashable | None = None
        rounds = range(WARM_UP_ROUND if self.warm_up else 1, self.repeats + 1)
        for number in rounds:
            if number == WARM_UP_ROUND:
                firsts = {}
                for index, item in enumerate(self.items):
                    firsts.setdefault(self.unit(item), index)
                members = sorted(firsts.values())
            else:
                members = [index for index in range(len(self.items))
                           if index not in self._retired]
            for index in self.round_order(members, number, previous):
                previous = self.unit(self.items[index])
                yield Call(self.items[index], index, number)

    def round_order(self, members: Sequence[int], number: int, previous: Hashable | None
                    ) -> list[int]:
        """Order the calls of one round.

        Each next call is of the unit with the most calls left in the round, other than the unit
        of the call before (``previous`` at the start), ties broken by the units' order rotated
        by ``number``; a unit's own calls keep their order in ``items``.

        Parameters
        ----------
        members : sequence of int
            The indices in ``items`` of the round's calls.
        number : int
            The round's number, which rotates the units' order.
        previous : Hashable or None
            The unit of the call just before the round; None at the start.

        Returns
        -------
        list of int
            ``members`` in the order they run.
        """
        if not self._units:
            return []
        rotation = number % len(self._units)
        place = {unit: (position - rotation) % len(self._units)
                 for position, unit in enumerate(self._units)}
        queues: dict[Hashable, list[int]] = {}
        for index in members:
            queues.setdefault(self.unit(self.items[index]), []).append(index)
        order: list[int] = []
        while queues:
            candidates = [unit for unit in queues if unit != previous] or list(queues)
            chosen = min(candidates, key=lambda unit: (-len(queues[unit]), place[unit]))
            order.append(queues[chosen].pop(0))
            if not queues[chosen]:
                del queues[chosen]
            previous = chosen
        return order


def fastest(times: Sequence[float]) -> tuple[float, float]:
    """Summarise an item's timed repeats by their minimum and median.

    Parameters
    ----------
    times : sequence of float
        The ``time_s`` of the repeats; None and non-finite values are left out.

    Returns
    -------
    tuple of (float, float)
        (minimum, median) of the finite times; (NaN, NaN) when none is finite.
    """
    finite = [value for value in times if value is not None and math.isfinite(value)]
    if not finite:
        return math.nan, math.nan
    return min(finite), statistics.median(finite)


@cache
def last_level_cache_bytes() -> int:
    """Read the size of the largest CPU cache the operating system reports for CPU 0.

    Linux reports them in ``/sys/devices/system/cpu/cpu0/cache/index*/size``.

    Returns
    -------
    int
        The size in bytes, or ``FLUSH_FALLBACK_BYTES`` when none is reported (read once).
    """
    sizes = []
    for entry in CACHE_FOLDER.glob("index*/size"):
        try:
            text = entry.read_text().strip().upper()
        except OSError:
            continue
        factor = {"K": 2**10, "M": 2**20, "G": 2**30}.get(text[-1:], 1)
        digits = text.rstrip("KMG")
        if digits.isdigit():
            sizes.append(int(digits) * factor)
    return max(sizes, default=FLUSH_FALLBACK_BYTES)


def flush_bytes() -> int:
    """Size the buffer :func:`flush_caches` writes.

    Returns
    -------
    int
        The last-level cache's size in bytes, at most ``FLUSH_CAP_BYTES``.
    """
    return min(last_level_cache_bytes(), FLUSH_CAP_BYTES)


_FLUSH_BUFFER: list[np.ndarray] = []


def flush_caches() -> None:
    """Evicts the previous calls' code and data from the CPU caches by writing every cache
    line of a buffer of :func:`flush_bytes` (allocated once, kept for the next call). Called
    before a timed call of the cold variant, outside its stopwatch."""
    if not _FLUSH_BUFFER:
        _FLUSH_BUFFER.append(np.zeros(flush_bytes() // 8))
    _FLUSH_BUFFER[0] += 1.0
