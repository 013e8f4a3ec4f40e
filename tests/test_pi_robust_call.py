"""pi-robust's call of its compiled kernel: past numba's dispatcher only for the compiled types.

``call_pi_robust_into`` reaches the same machine code as ``entry.pi_robust_into``'s dispatcher
would; arrays of any other type go through the dispatcher. Either way the answer is the
same to the last bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import pi_robust, pi_robust_call
from qpbench.solvers.pi_robust_kernel import call, entry

LEVEL = 1e-8


def posed(family: str, size: int | None, seed: int) -> ImpactProblem:
    problem = generate(family, size, seed=seed)[0]
    pose(problem, "lcp")
    return problem


def arrays(problem: ImpactProblem) -> tuple[np.ndarray, ...]:
    Q = problem.Q
    return Q.indptr, Q.indices, Q.data, problem.b


def through_dispatcher(problem: ImpactProblem, options: np.ndarray) -> tuple:
    out = np.full(problem.b.size, np.nan)
    return out, entry.pi_robust_into(*arrays(problem), out, options)


@pytest.fixture
def dispatcher_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    """The calls that reach ``entry.pi_robust_into``'s dispatcher from here on."""
    calls: list[tuple] = []
    dispatcher = entry.pi_robust_into

    def counted(*args: np.ndarray) -> tuple:
        calls.append(args)
        return dispatcher(*args)

    entry.warm_up()
    call.call_pi_robust_into(*arrays(posed("k3", None, 0)), np.full(3, np.nan),
                             pi_robust_call.settings_for(LEVEL).call_options)
    monkeypatch.setattr(entry, "pi_robust_into", counted)
    return calls


@pytest.mark.parametrize(("family", "size", "seed"), [("k3", None, 0), ("grid", 5, 2),
                                                      ("grid", 9, 3), ("near-duplicate", 4, 1)])
def test_the_direct_call_answers_as_the_dispatcher_does(family: str, size: int | None,
                                                        seed: int,
                                                        dispatcher_calls: list[tuple]) -> None:
    problem = posed(family, size, seed)
    options = pi_robust_call.settings_for(LEVEL).call_options
    expected, expected_scalars = through_dispatcher(problem, options)
    dispatcher_calls.clear()
    out = np.full(problem.b.size, np.nan)
    assert call.call_pi_robust_into(*arrays(problem), out, options) == expected_scalars
    assert np.array_equal(out, expected)
    assert dispatcher_calls == []  # the compiled types: straight to the machine code


def test_arrays_of_other_types_are_left_to_the_dispatcher(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """64-bit indices, a float32, strided or two-dimensional b: not the compiled types, so the
    dispatcher types them (and compiles for them, or refuses), never the machine code
    compiled for others. A read-only Q, which the kernel only reads, may go straight to it."""
    problem = posed("grid", 5, 0)
    options = pi_robust_call.settings_for(LEVEL).call_options
    indptr, indices, data, b = arrays(problem)
    out = np.full(b.size, np.nan)
    variants = [(indptr.astype(np.int64), indices.astype(np.int64), data, b, out),
                (indptr, indices, data, b.astype(np.float32), out),
                (indptr, indices, data, np.repeat(b, 2)[::2], out),
                (indptr, indices, data, b.reshape(-1, 1), out)]
    entry.warm_up()
    call.call_pi_robust_into(indptr, indices, data, b, out, options)  # the lookup made
    typed_by_the_dispatcher = ("dispatcher",)
    monkeypatch.setattr(entry, "pi_robust_into", lambda *args: typed_by_the_dispatcher)
    for variant in variants:
        assert call.call_pi_robust_into(*variant, options) is typed_by_the_dispatcher
    read_only = data.copy()
    read_only.setflags(write=False)
    for plain in (data, read_only):
        assert call.call_pi_robust_into(indptr, indices, plain, b, out, options) \
            is not typed_by_the_dispatcher


@pytest.mark.parametrize(("family", "size", "seed"), [("grid", 5, 1), ("grid", 7, 4)])
def test_a_call_from_zero_ignores_what_out_holds(family: str, size: int | None,
                                                 seed: int) -> None:
    """With the from-zero options the array that receives l need not be written first: any
    content, a solution included, gives the answer from zero."""
    problem = posed(family, size, seed)
    settings = pi_robust_call.settings_for(LEVEL)
    expected, expected_scalars = through_dispatcher(problem, settings.call_options)
    for content in (np.zeros(problem.b.size), np.ones(problem.b.size), expected.copy()):
        assert call.call_pi_robust_into(*arrays(problem), content,
                                        settings.call_options_from_zero) == expected_scalars
        assert np.array_equal(content, expected)
    # from the start it holds, the solution itself: certified at once, no solve
    start = expected.copy()
    scalars = call.call_pi_robust_into(*arrays(problem), start, settings.call_options)
    assert scalars[2] == 0 and np.array_equal(start, expected)


def test_solve_from_a_warm_start_of_another_length_starts_from_zero() -> None:
    problem = posed("grid", 5, 3)
    cold = pi_robust.solve(problem, LEVEL)
    for start in (np.ones(problem.b.size + 1), [1.0] * (problem.b.size - 1)):
        again = pi_robust.solve(problem, LEVEL, start)
        assert np.array_equal(again.impulses, cold.impulses)
        assert again.iterations == cold.iterations
