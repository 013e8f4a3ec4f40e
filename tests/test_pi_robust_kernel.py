"""pi-robust's compiled kernel, function by function: its envelope factors and their row
deletions, the ordering, the active-set method's steps, the drift rule and the options that
cross into it; each against what it must compute (a dense factor, numpy's Cholesky, the
objective), compiled and Python alike where both exist."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
import scipy.sparse as sp
from bench_problems import CYCLING_DUMP
from hypothesis import given, settings
from hypothesis import strategies as st

from qpbench.problem.dumps import import_dump
from qpbench.problem.generate import generate

if TYPE_CHECKING:  # (the kernel's module is imported inside each test that runs it)
    from qpbench.solvers.pi_robust_kernel.structures import Csc, OrderedLcp


# run in a fresh process with an empty numba cache: numba loads a cached kernel whole, and
# only a compilation types (and so lists the signatures of) every function it calls
UNCOUNTED_RETURN_TYPES = """
import json
from numba.core import types
import importlib
import pkgutil
from qpbench.solvers import pi_robust_kernel
from qpbench.solvers.pi_robust_kernel import entry
entry.warm_up()
functions = {}
for module in pkgutil.iter_modules(pi_robust_kernel.__path__):
    kernel = importlib.import_module(f"{pi_robust_kernel.__name__}.{module.name}")
    functions.update(vars(kernel))
returned = {}
for name, function in functions.items():
    if getattr(function, "targetoptions", {}).get("_nrt") is False:
        returned[name] = []
        for signature in function.signatures:
            result = function.overloads[signature].signature.return_type
            parts = result.types if isinstance(result, types.BaseTuple) else (result,)
            returned[name] += [isinstance(part, types.Array) for part in parts]
print(json.dumps(returned))
"""


@pytest.mark.slow
def test_the_kernels_functions_without_reference_counts_return_no_array(tmp_path: Path) -> None:
    """A function compiled without numba's reference counting may take arrays but not return
    one: nothing would own it, and the caller would free it while it is in use. Every such
    function of the kernel, as compiled for a solve, returns scalars and flags only."""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    printed = subprocess.run([sys.executable, "-c", UNCOUNTED_RETURN_TYPES], env=environment,
                             capture_output=True, text=True, check=True).stdout
    returned = json.loads(printed)
    assert {"_block_solve", "_inner_lcp", "_prox_policy_iteration"} <= set(returned)
    for name, array_parts in returned.items():
        assert array_parts and not any(array_parts), name


def test_a_blocks_envelope_factor_from_the_upper_triangle_is_the_dense_blocks() -> None:
    """For a free set I, the rows of the factor of Q_II + rho D_I start at each row's first
    nonzero of Q_II, L L^T is Q_II + rho D_I, and the forward substitution made row by row
    with it is L's: all read from Q's upper triangle alone (a copy, or Q's own sorted columns'
    leading entries), from a first row on as well (the rows before it kept from an earlier
    factor)."""
    from qpbench.solvers.pi_robust_kernel.factor import _backward_substitution, _factor_rows
    from qpbench.solvers.pi_robust_kernel.ordering import _leading_upper, _upper

    Q = generate("grid", 10, seed=0)[0].Q
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    upper = _upper(csc)
    # Q's own arrays, rows sorted in each column, serve as the upper triangle: same entries
    ends = np.empty(Q.shape[0], dtype=np.int64)
    assert _leading_upper(csc, ends)
    for column in range(Q.shape[0]):
        copied = slice(upper[0][column], upper[1][column])
        leading = slice(Q.indptr[column], ends[column])
        assert np.array_equal(upper[2][copied], Q.indices[leading])
        assert np.array_equal(upper[3][copied], Q.data[leading])
    unsorted = (csc[0], csc[1].copy(), csc[2])
    unsorted[1][[0, 1]] = unsorted[1][[1, 0]]  # the first column's first two rows swapped
    assert not _leading_upper(unsorted, ends)
    diag, rho = Q.diagonal(), 1e-3
    rng = np.random.default_rng(3)
    for _ in range(5):
        free = np.flatnonzero(rng.uniform(size=Q.shape[0]) < 0.6)
        position = np.full(Q.shape[0], -1, dtype=np.int64)
        position[free] = np.arange(free.size)
        block = Q[free][:, free].toarray() + rho * np.diag(diag[free])
        offsets = np.zeros(free.size + 1, dtype=np.int64)
        values = np.empty(Q.nnz + free.size ** 2)
        _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, 0,
                     np.empty(0))
        for a in range(free.size):
            assert a + 1 - (offsets[a + 1] - offsets[a]) == np.flatnonzero(block[a])[0]
        lower = dense_factor(values, offsets, free.size)
        assert np.allclose(lower @ lower.T, block, rtol=1e-12, atol=1e-12 * diag.max())
        # refactored from a middle row on (the rows before it kept), with a right side
        kept = free.size // 2
        rhs = rng.normal(size=free.size)
        solution = rhs.copy()
        values[offsets[kept]:] = np.nan  # must be written before being read
        _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, kept,
                     solution)
        _backward_substitution(values, offsets, free.size, solution)
        assert np.allclose(block @ solution, rhs, rtol=1e-10, atol=1e-10)


def test_an_envelope_factor_of_random_patterns_is_numpys_cholesky() -> None:
    """Rows whose envelopes start anywhere (at the row itself, one or two columns before it,
    or far back) and of every parity of width: the envelope factor's entries, formed two at a
    time with each row's newest entries subtracted last, are those of numpy's Cholesky factor."""
    import scipy.sparse as sp

    from qpbench.solvers.pi_robust_kernel.factor import _factor_rows
    from qpbench.solvers.pi_robust_kernel.ordering import _upper

    rng = np.random.default_rng(11)
    for size, density in ((1, 1.0), (2, 1.0), (7, 0.3), (30, 0.1), (61, 0.05), (61, 0.5)):
        pattern = sp.random(size, size, density=density, random_state=rng, format="csc")
        symmetric = (pattern + pattern.T).tocsc()
        matrix = symmetric + sp.diags(abs(symmetric).sum(axis=1).A1 + 1.0)
        Q = sp.csc_matrix(matrix)
        Q.sort_indices()
        upper = _upper((Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data))
        everything = np.arange(size)
        offsets = np.zeros(size + 1, dtype=np.int64)
        values = np.full(size * size, np.nan)
        _factor_rows(upper, everything, everything, np.empty(0), 0.0, np.zeros(size), values,
                     offsets, 0, np.empty(0))
        expected = np.linalg.cholesky(Q.toarray())
        for row in range(size):
            first = row + 1 - (offsets[row + 1] - offsets[row])
            stored = values[offsets[row]:offsets[row + 1]].copy()
            stored[-1] = 1.0 / stored[-1]  # the diagonal is kept as its reciprocal
            assert np.allclose(stored, expected[row, first:row + 1], rtol=1e-12, atol=1e-12)
            assert not expected[row, :first].any()


def test_a_block_factor_counts_its_dependent_contacts() -> None:
    """Two contacts with the same column of G make Q_FF singular: the second one's pivot is
    only its share of rho D (L_ii^2 < DEPENDENT_PIVOT rho D_i), so the factor counts one
    dependent contact, which block pivoting reads (a nearly singular block goes to the
    active-set method); independent contacts count none, and a solve from the kept factor
    reports its count again."""
    import scipy.sparse as sp

    from qpbench.solvers.pi_robust_kernel.factor import _block_solve
    from qpbench.solvers.pi_robust_kernel.ordering import _upper
    from qpbench.solvers.pi_robust_kernel.structures import _work

    G = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 1.0]])  # contacts 1 and 2 are one contact twice
    for Q, expected in ((G.T @ G, 1), (np.diag([2.0, 1.0, 3.0]), 0)):
        csc = sp.csc_matrix(Q)
        csc.sort_indices()
        A = (csc.indptr.astype(np.int64), csc.indices.astype(np.int64), csc.data)
        work = _work(3, 6)[0]
        policy = np.ones(3, dtype=np.bool_)
        for _ in range(2):  # factored, then solved from the kept factor
            _block_solve(_upper(A), Q.diagonal().copy(), policy, np.arange(3), 1e-5,
                         np.ones(3), work.cache)
            assert work.cache.counters[2] == expected
        assert work.cache.counters[0] == 1


def dense_factor(values: np.ndarray, offsets: np.ndarray, size: int) -> np.ndarray:
    """The dense L of an envelope factor stored as the kernel stores it (row i in
    ``values[offsets[i]:offsets[i + 1]]``, its diagonal last, kept as its reciprocal)."""
    lower = np.zeros((size, size))
    for row in range(size):
        first = row + 1 - (offsets[row + 1] - offsets[row])
        lower[row, first:row + 1] = values[offsets[row]:offsets[row + 1]]
        lower[row, row] = 1.0 / lower[row, row]
    return lower


def test_deleting_a_contacts_row_from_a_factor_gives_the_factor_of_the_smaller_block() -> None:
    """A free set of a reverse Cuthill-McKee-ordered grid, factored: deleting the row and
    column of its first, a middle or its last contact in place (without a right side, or with
    one, to the same numbers and the forward substitution ``L' y = x`` made as the rows are
    formed) leaves a lower-triangular L' with positive diagonal and ``L' L'^T = H`` without
    that row and column (H = Q_II + rho D_I); deleting a second contact from that, the same
    for H without both."""
    from qpbench.solvers.pi_robust_kernel.factor import _delete_contact, _factor_rows

    Q, _, order, _, _, (starts, rows, data) = ordered_grid(7, 0)
    upper = (starts, starts[1:], rows, data)
    n = starts.size - 1
    dense = Q[order][:, order].toarray()
    diag, rho = dense.diagonal().copy(), 1e-5
    rng = np.random.default_rng(7)
    free = np.flatnonzero(rng.uniform(size=n) < 0.5)
    block = dense[np.ix_(free, free)] + rho * np.diag(diag[free])
    position = np.full(n, -1, dtype=np.int64)
    position[free] = np.arange(free.size)
    values = np.full(data.size + n * n, np.nan)
    offsets = np.zeros(free.size + 1, dtype=np.int64)
    _factor_rows(upper, free, position, np.empty(0), rho, diag, values, offsets, 0, np.empty(0))
    cosines, sines = np.empty(free.size), np.empty(free.size)

    def check(factor: np.ndarray, factor_offsets: np.ndarray, kept: np.ndarray) -> None:
        lower = dense_factor(factor, factor_offsets, kept.size)
        assert np.array_equal(lower, np.tril(lower)) and np.all(np.diag(lower) > 0.0)
        assert np.allclose(lower @ lower.T, block[np.ix_(kept, kept)], rtol=1e-12,
                           atol=1e-12 * diag.max())

    everything = np.arange(free.size)
    for place in (0, free.size // 2, free.size - 1):
        target, target_offsets = values.copy(), offsets.copy()
        _delete_contact(target, target_offsets, free.size, place, cosines, sines, np.empty(0))
        kept = np.delete(everything, place)
        check(target, target_offsets, kept)
        # with a right side: the same numbers, and L' y = x solved as the rows are formed
        with_right, with_right_offsets = values.copy(), offsets.copy()
        right = rng.normal(size=free.size - 1)
        forward = right.copy()
        _delete_contact(with_right, with_right_offsets, free.size, place, cosines, sines,
                        forward)
        assert np.array_equal(with_right_offsets[:free.size], target_offsets[:free.size])
        used = target_offsets[free.size - 1]
        assert np.array_equal(with_right[:used], target[:used])
        lower = dense_factor(target, target_offsets, free.size - 1)
        assert np.allclose(lower @ forward, right, rtol=1e-12, atol=1e-12)
        second = place // 2
        _delete_contact(target, target_offsets, free.size - 1, second, cosines, sines,
                        np.empty(0))
        check(target, target_offsets, np.delete(kept, second))


def posed_order_lcp(Q: sp.csc_matrix, b: np.ndarray) -> tuple[OrderedLcp, Csc, np.ndarray]:
    """(the kernel's OrderedLcp of LCP(Q, b) in the posed order (no ordering, scale 1), Q's
    CSC arrays with 64-bit indices, diag(Q)); Q's row indices are sorted in place first."""
    from qpbench.solvers.pi_robust_kernel.ordering import _upper
    from qpbench.solvers.pi_robust_kernel.structures import OrderedLcp, Posed

    Q.sort_indices()
    A = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    diag = Q.diagonal()
    posed = Posed(A, b, diag, np.empty(0, dtype=np.int64))
    return OrderedLcp(A, _upper(A), posed, b, diag, diag, 1.0), A, diag


def test_a_policy_that_fixes_contacts_of_the_last_one_is_solved_by_deleting_their_rows() -> None:
    """After a policy's block is factored and solved, the policy with two of its contacts
    fixed is solved from that factor with their rows deleted, with no factorization: x_F
    solves ``(Q_FF + rho D_F) x_F = -q_F`` and is zero off F; the updated factor is kept for
    that policy, so solving it again takes it from the cache, to the same x."""
    from qpbench.solvers.pi_robust_kernel.factor import _policy_solve
    from qpbench.solvers.pi_robust_kernel.structures import _work

    Q = generate("grid", 7, seed=1)[0].Q.tocsc()
    n, rho = Q.shape[0], 1e-5
    lcp, _, diag = posed_order_lcp(Q, np.zeros(n))
    rng = np.random.default_rng(2)
    q = rng.normal(size=n)
    policy = rng.uniform(size=n) < 0.5
    capacity = n * (n + 1) // 2
    work = _work(n, capacity)[0]
    refactor = np.empty(0, dtype=np.int64)  # no places of fixed contacts: factor or cache
    size = _policy_solve(lcp, policy, rho, q, work, refactor)
    free = np.flatnonzero(policy)
    assert size == free.size and work.cache.counters[0] == 1
    places = np.array([3, free.size - 5], dtype=np.int64)
    policy[free[places]] = False
    assert _policy_solve(lcp, policy, rho, q, work, places) == free.size - 2
    assert work.cache.counters[0] == 1  # no factorization
    kept = np.flatnonzero(policy)
    H = Q[kept][:, kept].toarray() + rho * np.diag(diag[kept])
    expected = np.zeros(n)
    expected[kept] = np.linalg.solve(H, -q[kept])
    assert np.allclose(work.x, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    updated = work.x.copy()
    _policy_solve(lcp, policy, rho, q, work, refactor)
    assert work.cache.counters[0] == 1  # the updated factor, from the cache
    assert np.array_equal(work.x, updated)


def test_block_pivoting_hands_a_nearly_singular_block_to_the_active_set_method() -> None:
    """On the first prox step of this fork dump (from the start sweeps' policy) the first
    block solved has dependent contacts and leaves mostly negative free contacts: block
    pivoting hands over to the active-set method right after that solve, so that with no solve
    left x is the method's feasible start max(x, 0), where block pivoting alone (no
    active-set method) would exchange them next and stops at its x, with negative entries.
    Given the solves it needs, the active-set method solves the prox LCP."""
    from qpbench.solvers.pi_robust_kernel.entry import _gauss_seidel
    from qpbench.solvers.pi_robust_kernel.pivoting import _inner_lcp
    from qpbench.solvers.pi_robust_kernel.structures import Prox, _work

    problem = import_dump(CYCLING_DUMP)
    Q = problem.Q.tocsc()
    n, rho, b = Q.shape[0], 1e-5, problem.b
    lcp, A, diag = posed_order_lcp(Q, b)
    tol_w = 1e-9 * np.abs(b).max()
    tol_l = tol_w / diag
    centre = np.zeros(n)
    _gauss_seidel(A, b, diag, centre, np.empty(n), 5)
    q = b - rho * diag * centre

    def inner(active_set: bool, budget: int) -> tuple[np.ndarray, np.ndarray, bool]:
        work = _work(n, n * (n + 1) // 2)[0]
        policy = Q @ centre + b <= diag * centre
        _, solved = _inner_lcp(lcp, policy, rho, q, tol_l, tol_w,
                               Prox(1e-14, 0.01, 0.5, 3, 0, active_set, 0), budget, work)
        return work.x.copy(), policy, solved

    handed_over, _, _ = inner(True, 1)
    pivoted, _, _ = inner(False, 1)
    assert np.all(handed_over >= 0.0) and np.any(pivoted < 0.0)
    x, free, solved = inner(True, 10 * n)
    w = Q @ x + rho * diag * x + q
    assert solved and np.all(x >= 0.0) and np.all(x[~free] == 0.0)
    assert np.all(w[~free] >= -tol_w) and np.all(np.abs(w[free]) <= 1e-6 * np.abs(b).max())


def test_the_diagonal_spread_that_gates_row_updates_ignores_contacts_that_move_nothing() -> None:
    """max D_i / min D_i over D_i > 0: a contact with D_i = 0 moves nothing and does not count;
    with none left the spread is 1."""
    from qpbench.solvers.pi_robust_kernel.active_set import _diagonal_spread

    assert _diagonal_spread(np.array([0.0, 2.0, 1e-7, 5.0])) == pytest.approx(5e7)
    assert _diagonal_spread(np.array([3.0, 3.0])) == 1.0
    assert _diagonal_spread(np.zeros(2)) == 1.0


def test_the_active_set_methods_objective_without_products_is_the_objective() -> None:
    """At s minimizing f(x) = x^T H x / 2 + q^T x (H = Q + rho D) on a free set F, zero off F:
    f(s) = q^T s / 2, f(max(s, 0)) = f(s) + d^T H d / 2 with d = max(-s, 0), and for x zero
    off F, f(x + t (s - x)) = f(s) + (1 - t)^2 (f(x) - f(s)): the values the active-set
    method uses instead of products with Q."""
    from qpbench.solvers.pi_robust_kernel.active_set import _clipped_curvature, _objective

    problem = generate("grid", 7, seed=0)[0]
    Q = problem.Q.tocsc()
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    diag, rho = Q.diagonal(), 1e-3
    H = Q.toarray() + rho * np.diag(diag)
    rng = np.random.default_rng(5)
    product = np.empty(problem.n_contacts)
    q = np.empty(problem.n_contacts)

    def f(x: np.ndarray) -> float:
        return _objective(csc, rho, diag, q, x, product)

    for _ in range(5):
        free = np.flatnonzero(rng.uniform(size=problem.n_contacts) < 0.5)
        q[:] = rng.normal(size=problem.n_contacts) * diag
        s = np.zeros(problem.n_contacts)
        s[free] = np.linalg.solve(H[np.ix_(free, free)], -q[free])
        at_minimum = 0.5 * q @ s
        assert (s < 0).any() and (s > 0).any()

        scale = abs(f(np.maximum(s, 0.0))) + abs(at_minimum)
        assert abs(at_minimum - f(s)) <= 1e-9 * scale
        assert abs(at_minimum + _clipped_curvature(csc, rho, diag, s, np.flatnonzero(s < 0))
                   - f(np.maximum(s, 0.0))) <= 1e-9 * scale
        x = np.zeros(problem.n_contacts)
        x[free] = rng.uniform(size=free.size)
        for t in (0.25, 0.8):
            assert abs(at_minimum + (1 - t) ** 2 * (f(x) - at_minimum) - f(x + t * (s - x))) \
                <= 1e-9 * (abs(f(x)) + scale)


@pytest.mark.parametrize("all_of_them, freed", [(True, [1, 2]), (False, [1])])
def test_the_active_set_method_frees_violators_not_coupled_to_one_freed_before(
        all_of_them: bool, freed: list[int]) -> None:
    """Contacts 0, 1 and 2 violate (slacks -2, -3, -1; contact 3's is +1). Contact 1, the
    most negative, is freed first; contact 0 is coupled to it (Q_01 = 0.5 sqrt(D_0 D_1),
    above COUPLED), so freeing 1 raises 0's slack and 0 waits; contact 2 is coupled to 0 only
    (and weakly): freed. When f has not fallen since the last freeing, only contact 1 is.
    The kernel and the Python path free the same contacts."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.pi_robust import _violators_to_free
    from qpbench.solvers.pi_robust_kernel.active_set import _free_violators

    Q = sp.csc_matrix(np.array([[1.0, 0.5, 0.01, 0.0], [0.5, 1.0, 0.0, 0.0],
                                [0.01, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]))
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    slack = np.array([-2.0, -3.0, -1.0, 1.0])
    diag = Q.diagonal()
    policy = np.zeros(4, dtype=bool)
    assert _free_violators(csc, diag, policy, np.zeros(4), slack, 1e-12, all_of_them,
                           np.zeros(4, dtype=np.int64), np.zeros(4))
    assert np.flatnonzero(policy).tolist() == freed

    lcp = Lcp(Q=Q.tocsr(), b=slack, diag=diag, scale=1.0)
    chosen = _violators_to_free(lcp, slack < 0.0, slack, all_of_them=all_of_them)
    assert np.flatnonzero(chosen).tolist() == freed


def test_the_active_set_method_frees_nothing_without_a_violator() -> None:
    """No fixed contact's slack below -tol_w: nothing is freed, and the method is told the
    point is the solution."""
    from qpbench.solvers.pi_robust_kernel.active_set import _free_violators

    Q = sp.identity(3, format="csc")
    csc = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    policy = np.array([True, False, False])
    assert not _free_violators(csc, np.ones(3), policy, np.zeros(3), np.array([-5.0, 0.0, -1e-13]),
                               1e-12, True, np.zeros(3, dtype=np.int64), np.zeros(3))
    assert policy.tolist() == [True, False, False]


def empty_upper(n: int, entries: int) -> Csc:
    """Zeroed arrays for an upper triangle of n columns: (starts, rows, values), room for
    ``entries`` entries."""
    return np.zeros(n + 1, dtype=np.int64), np.zeros(entries, dtype=np.int64), np.zeros(entries)


def ordered_grid(size: int, seed: int) -> tuple[sp.csc_matrix, Csc, np.ndarray, Csc,
                                                np.ndarray, Csc]:
    """A generated grid's Q, its 64-bit CSC arrays, its reverse Cuthill-McKee order, and
    _permuted's arrays for that order: (Q, (indptr, indices, data), order, permuted CSC,
    envelope offsets, upper triangle)."""
    from qpbench.solvers.pi_robust_kernel.ordering import _permuted, reverse_cuthill_mckee

    Q = generate("grid", size, seed=seed)[0].Q
    n = Q.shape[0]
    posed = (Q.indptr.astype(np.int64), Q.indices.astype(np.int64), Q.data)
    order = reverse_cuthill_mckee(posed[0], posed[1], n)
    widths = np.zeros(n + 1, dtype=np.int64)
    upper = empty_upper(n, Q.nnz)
    permuted = _permuted(*posed, order, widths, upper)
    return Q, posed, order, permuted, widths, upper


def test_reverse_cuthill_mckee_is_a_permutation_that_narrows_a_grid() -> None:
    from qpbench.solvers.pi_robust_kernel.ordering import _envelope_widths

    Q, posed, order, _, ordered, _ = ordered_grid(10, seed=0)
    assert sorted(order) == list(range(Q.shape[0]))
    natural = np.zeros(Q.shape[0] + 1, dtype=np.int64)
    _envelope_widths(posed, natural)
    assert ordered[-1] < natural[-1]


def test_the_permutation_copies_its_upper_triangle_and_envelope_in_the_same_pass() -> None:
    """_permuted fills the permuted matrix's upper triangle and envelope offsets as
    _upper_into and _envelope_widths would from its CSC arrays."""
    from qpbench.solvers.pi_robust_kernel.ordering import _envelope_widths, _upper_into

    Q, _, order, permuted, widths, upper = ordered_grid(7, seed=1)
    n = Q.shape[0]
    new_indptr, new_indices, new_data = permuted
    np.testing.assert_array_equal(
        sp.csc_matrix((new_data, new_indices, new_indptr), shape=(n, n)).toarray(),
        Q.toarray()[np.ix_(order, order)])
    expected_widths = np.zeros(n + 1, dtype=np.int64)
    _envelope_widths(permuted, expected_widths)
    np.testing.assert_array_equal(widths, expected_widths)
    expected = empty_upper(n, Q.nnz)
    _upper_into(permuted, expected)
    entries = int(expected[0][-1])
    assert 0 < entries < Q.nnz
    np.testing.assert_array_equal(upper[0], expected[0])
    np.testing.assert_array_equal(upper[1][:entries], expected[1][:entries])
    np.testing.assert_array_equal(upper[2][:entries], expected[2][:entries])


def test_the_kernels_packed_options_unpack_to_the_accuracy_table_row() -> None:
    """Options travel to the compiled kernel as one array; unpacked they are the row's."""
    from qpbench.solvers import accuracy
    from qpbench.solvers.pi_robust_kernel.structures import options_of, unpacked

    row = accuracy.options_for("pi-robust", 1e-6)
    options = unpacked(options_of(row))
    flat = {**options._asdict(), **options.prox._asdict()}
    assert {name: flat[name] for name in flat if name != "prox"} == {
        name: row[name] for name in flat if name != "prox"}



@pytest.mark.parametrize("family, size, seed", [("k3", None, 0), ("cradle", 5, 1), ("grid", 5, 2),
                                                ("grid", 9, 3), ("mass-ratio", 7, 4)])
def test_the_narrow_entry_gives_the_wide_entrys_answer(family: str, size: int | None,
                                                       seed: int) -> None:
    """pi_robust_into, which solve() calls (l written into the caller's array, diag(Q) read
    from Q), answers as envelope_pi_robust does from the same start: the same l to the last
    bit and the same counts, from zero (a first entry NaN) and from a start."""
    from qpbench.problem.formulations import pose
    from qpbench.solvers import pi_robust, pi_robust_call
    from qpbench.solvers.pi_robust_kernel import entry

    problem = generate(family, size, seed=seed)[0]
    pose(problem, "lcp")
    settings = pi_robust.settings_for(1e-8)
    Q = problem.Q
    half = 0.5 * pi_robust.solve(problem, 1e-8).impulses
    for start in (None, half):
        wide = entry.envelope_pi_robust(
            Q.indptr, Q.indices, Q.data, problem.b, problem.diag_Q,
            pi_robust_call.NO_START if start is None else start, pi_robust_call.ORDERING_ABOVE,
            settings.compiled_work_limit, settings.kernel)
        impulses, narrow = pi_robust.kernel_into(problem, settings, start)
        assert np.array_equal(impulses, wide[0])
        assert narrow == wide[1:]
    # a start of the wrong size starts from zero, as in the Python path
    impulses, narrow = pi_robust.kernel_into(problem, settings, np.ones(problem.b.size + 1))
    _, cold = pi_robust.kernel_into(problem, settings, None)
    assert narrow == cold


@pytest.mark.parametrize("compiled", [True, False])
def test_a_prox_steps_drift_is_followed_to_the_first_free_contact_at_zero(compiled: bool) -> None:
    """A settled prox step's change d of l, as long as the step before's (a drift along Q_FF's
    null space), moves the centre z to where the first free contact falling along d reaches
    zero; fixed contacts stay. A d that shrinks by 1% a step (a slow contraction) moves
    nothing, nor does a drift along which no free contact falls. Compiled and Python alike."""
    from qpbench.solvers import pi_robust
    from qpbench.solvers.pi_robust_kernel import prox

    def moved(centre: list[float], drift: list[float], previous: list[float],
              policy: list[bool]) -> np.ndarray | None:
        z, d, d_before, free = (np.array(centre), np.array(drift), np.array(previous),
                                np.array(policy))
        if not compiled:
            return pi_robust._drifted(z, d, d_before, free)
        return z if prox._extrapolate_drift(z, d, d_before, free) else None

    free = [True, True, True, False]
    drift = [-0.5, 1.0, -1.0, -6.0]
    # contacts 0 and 2 fall; 2 reaches zero first (after 0.5 of the step), 3 is fixed
    np.testing.assert_array_equal(moved([1.0, 2.0, 0.5, 3.0], drift, drift, free),
                                  [0.75, 2.5, 0.0, 3.0])
    assert moved([1.0, 2.0, 0.5, 3.0], drift, [value / 0.99 for value in drift], free) is None
    assert moved([1.0, 2.0, 0.5, 3.0], [0.5, 1.0, 1.0, -6.0], [0.5, 1.0, 1.0, -6.0],
                 free) is None
    # g = 0.9995: the geometric series ends after 1999 steps, before any contact reaches zero
    slow = [-1e-4, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(moved([1.0, 2.0, 0.5, 0.0], slow,
                                     [value / 0.9995 for value in slow], free),
                               [1.0 - 0.1999, 2.0, 0.5, 0.0], rtol=1e-9)



@settings(max_examples=30, deadline=None)
@given(family=st.sampled_from(["grid", "k4", "mass-ratio", "near-duplicate", "cradle"]),
       size=st.integers(3, 7), seed=st.integers(0, 10_000),
       rho=st.sampled_from([1e-6, 1e-3, 1.0]))
def test_primal_active_set_solves_the_prox_lcp_from_zero(family: str, size: int, seed: int,
                                                         rho: float) -> None:
    """From l = 0 (every contact fixed) the active-set method solves LCP(Q + rho D, b):
    x >= 0; ``w = (Q + rho D) x + b >= -tol`` where x = 0 and ``w = 0`` (up to the block
    solve's rounding) where x is free; and its objective ``x^T (Q + rho D) x / 2 + b^T x`` is
    at most the start's, 0."""
    from qpbench.solvers.lcp import Lcp
    from qpbench.solvers.pi_robust import BlockSolver, _primal_active_set

    problem = generate(family, size, seed=seed)[0]
    lcp = Lcp.of(problem, dense_limit=300)
    n = lcp.n
    tol_w = 1e-10 * lcp.scale
    tol_l = tol_w / lcp.safe_diag
    x, free, _, solved = _primal_active_set(lcp, BlockSolver(lcp), rho, lcp.b, np.zeros(n),
                                            tol_l, tol_w, budget=10 * n + 10)
    assert solved
    w = lcp.op @ x + rho * lcp.safe_diag * x + lcp.b
    assert np.all(x >= 0.0) and np.all(x[~free] == 0.0)
    assert np.all(w[~free] >= -tol_w)
    assert np.all(np.abs(w[free]) <= 1e-6 * lcp.scale)
    assert 0.5 * x @ (w + lcp.b) <= 0.0

