"""Timed repeats under the timing protocol (docs/design.md section 7), as the head-to-head, the
sequence mode and ``speed`` time their solves (the main benchmark's workers run the same
protocol over their batches of cells, ``qpbench.bench.worker``).

A solve's ``time_s`` varies from run to run with what else the machine does; the fastest of a
few repeats is the least disturbed. The repeats of one (problem, pair) are never timed back to
back: :func:`time_interleaved` hands every timed call of a batch to a
:class:`~qpbench.bench.schedule.Schedule`, so that other pairs' and other problems' solves run
between them, in an order rotated from round to round. Repeats of one timing stop once they
have taken ``REPEAT_BUDGET_S`` in all: a slow solve varies little, and repeating it would
only take the benchmark's time. With a cap, a (problem, pair) whose untimed warm-up took
longer is timed no further: its warm-up's answer and time stand for it, so that a solve of
minutes is not made three times over (a dense factorization on a large pile).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np

from qpbench.bench.defaults import REPEATS
from qpbench.bench.schedule import Schedule, flush_caches
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.run import call_solver

REPEAT_BUDGET_S = 0.2


@dataclass(frozen=True)
class Timing:
    """One thing to time: ``spec`` on ``problem`` from ``warm_start``.

    ``cold``: the cold variant, the CPU caches flushed before each timed call (outside the
    stopwatch). ``repeats``: this timing's own number of timed calls (None: the batch's).
    ``unit``: the (problem, pair) it belongs to, which the schedule keeps apart from itself
    (None: the problem's name and the pair's key)."""

    spec: SolverSpec
    problem: ImpactProblem | FrictionalProblem
    warm_start: np.ndarray | None = None
    cold: bool = False
    repeats: int | None = None
    unit: Hashable = None

    def unit_key(self) -> Hashable:
        """Give the (problem, pair) this timing is a repeat of.

        Returns
        -------
        Hashable
            ``unit`` when set, else (the problem's name, the pair's key).
        """
        if self.unit is not None:
            return self.unit
        return (self.problem.name, self.spec.key)


def time_interleaved(timings: Sequence[Timing], repeats: int = REPEATS,
                     accuracy: float = 1e-8, warm_up: bool = True,
                     budget_s: float = REPEAT_BUDGET_S,
                     flush: Callable[[], None] | None = None,
                     accuracies: Sequence[float] | None = None,
                     cap_s: float = math.inf) -> list[list[SolverOutput]]:
    """Time every one of ``timings`` through the one stopwatch, interleaved by a schedule.

    Every call goes through ``call_solver`` at ``accuracy`` (or ``accuracies[i]`` for the
    i-th), in the order of a :class:`~qpbench.bench.schedule.Schedule`: with ``warm_up``, one
    untimed solve per unit first (on its first timing; its output discarded), then rounds of
    one timed call of each timing still running. A timing stops after its ``repeats`` (or the
    batch's), after a failed solve, or once its calls have taken ``budget_s`` in all. A cold
    timing's every timed call follows a call of ``flush`` (outside the stopwatch). A unit whose
    warm-up took more than ``cap_s`` gets no timed call: the warm-up's output is the one output
    of the timing it ran on, and the unit's other timings have none.

    Parameters
    ----------
    timings : sequence of Timing
        What to time, in a canonical order (problem-major, say).
    repeats : int, optional
        Timed calls per timing whose own ``repeats`` is None; REPEATS by default.
    accuracy : float, optional
        The accuracy level of every call when ``accuracies`` is None; 1e-8 by default.
    warm_up : bool, optional
        Run one untimed solve per unit first; True by default.
    budget_s : float, optional
        Seconds of timed calls after which a timing stops; REPEAT_BUDGET_S by default.
    flush : callable, optional
        Called before each timed call of a cold timing; None:
        :func:`~qpbench.bench.schedule.flush_caches`.
    accuracies : sequence of float, optional
        One accuracy level per timing, in place of ``accuracy``.
    cap_s : float, optional
        Seconds of a warm-up past which its unit is timed no further; infinite by default.

    Returns
    -------
    list of list of SolverOutput
        Per timing, the outputs of its timed calls in the order they ran.
    """
    levels = list(accuracies) if accuracies is not None else [accuracy] * len(timings)
    wanted = [timing.repeats or repeats for timing in timings]
    schedule = Schedule(range(len(timings)), max(wanted, default=1),
                        unit=lambda index: timings[index].unit_key(), warm_up=warm_up)
    outputs: list[list[SolverOutput]] = [[] for _ in timings]
    capped: set[Hashable] = set()  # the units whose warm-up took more than cap_s
    for call in schedule:
        timing = timings[call.item]
        if not call.timed:
            output = call_solver(timing.spec, timing.problem, levels[call.item],
                                 timing.warm_start)
            if output.time_s > cap_s:
                capped.add(timing.unit_key())
                outputs[call.item].append(output)
            continue
        if timing.unit_key() in capped:
            schedule.retire(call.index)
            continue
        if timing.cold:
            (flush or flush_caches)()
        output = call_solver(timing.spec, timing.problem, levels[call.item], timing.warm_start)
        done = outputs[call.item]
        done.append(output)
        if (output.impulses is None or len(done) >= wanted[call.item]
                or sum(one.time_s for one in done) >= budget_s):
            schedule.retire(call.index)
    return outputs


def fastest_output(outputs: Sequence[SolverOutput]) -> SolverOutput:
    """Pick the output of the fastest of a timing's timed calls.

    Parameters
    ----------
    outputs : sequence of SolverOutput
        The outputs of one timing's timed calls (at least one).

    Returns
    -------
    SolverOutput
        The output of least ``time_s``.
    """
    return min(outputs, key=lambda output: output.time_s)
