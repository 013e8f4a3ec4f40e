"""pi-robust against one sparse factorization on large box packings (issue 4, target 2).

On each box packing ``generate("box", size=N, seed)`` (largest first) this measures,
side by side in one process:

* ``factorization_s``: the time of ONE sparse factorization of ``Q + eps I`` with
  ``eps = FACTOR_SHIFT * max(diag Q)`` (``qpbench.studies.factorization``), the fastest of
  three: CHOLMOD's simplicial LDL^T in approximate-minimum-degree order (as pi-robust's
  sparse path factors its blocks; when scikit-sparse imports), and SuperLU's LU
  (``scipy.sparse.linalg.splu``) with two column orderings (``MMD_AT_PLUS_A`` in symmetric
  mode with diagonal pivots, and SuperLU's default ``COLAMD``); minimum over repeats, the
  fastest method and its library named;
* ``solve_s``: pi-robust's ``time_s`` at accuracy 1e-8 (``SolverOutput.time_s``, from
  Q and b to l, as ``qpbench run`` records it), minimum over repeats;
* ``ratio = solve_s / factorization_s`` against the target ``TARGET_RATIO`` (5x), with
  qpbench's residual and v_error (against a verified reference) of pi-robust's answer.

Every part of every packing is timed under the timing protocol of docs/design.md section 7
(:func:`timed_parts`): one untimed call each, then rounds of one call each in a rotated order,
never two calls of one part in a row.

Times depend on BLAS threads: the ``speed`` command runs in a process with single-threaded
BLAS (``SINGLE_THREAD_ENV``), and the JSON says whether it was.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from qpbench import SINGLE_THREAD_ENV
from qpbench.bench.defaults import REPEATS, SPEED_SIZES
from qpbench.bench.schedule import Schedule
from qpbench.problem import metrics
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reference import attach_reference
from qpbench.solvers.base import SolverOutput
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver
from qpbench.studies.factorization import (
    CHOLMOD,
    FACTOR_SHIFT,
    METHODS,
    SUPERLU,
    Factorize,
    fastest,
    shifted_block,
    time_once,
)

SOLVER = "pi-robust"
ACCURACY = 1e-8
TARGET_RATIO = 5.0
COLAMD = "SuperLU/COLAMD"


def colamd_splu(matrix: sp.csc_matrix) -> spla.SuperLU:
    """SuperLU's LU of ``matrix`` in its default column order (COLAMD), partial pivoting.

    Parameters
    ----------
    matrix : sp.csc_matrix
        The matrix to factor.

    Returns
    -------
    spla.SuperLU
        Its factor.

    Raises
    ------
    np.linalg.LinAlgError
        When it is exactly singular.
    """
    try:
        return spla.splu(matrix, permc_spec="COLAMD")
    except RuntimeError as error:
        raise np.linalg.LinAlgError(str(error)) from error


# the factorizations timed: CHOLMOD (when it imports) and SuperLU in symmetric mode, as
# qpbench.studies.factorization, and SuperLU in its default column order
FACTORIZATIONS: dict[str, Factorize] = {**METHODS, COLAMD: colamd_splu}


def timed_parts(problems: Sequence[ImpactProblem], repeats: int
                ) -> tuple[dict[tuple[int, str], list[float]], dict[int, SolverOutput]]:
    """Every part timed on every problem under the timing protocol, and pi-robust's answers.

    The parts are pi-robust (through ``call_solver``) and one factorization per method of
    FACTORIZATIONS (of ``factorization.shifted_block``, built outside the timed window); every
    (problem, part) is timed ``repeats`` times under the timing protocol of docs/design.md
    section 7 (``qpbench.bench.schedule.Schedule``): one untimed call of each first, then
    rounds of one call each, in an order that rotates from round to round, so no part is timed
    twice in a row.

    Parameters
    ----------
    problems : sequence of ImpactProblem
        The box packings.
    repeats : int
        Timed calls per (problem, part).

    Returns
    -------
    tuple of (dict, dict)
        The times in seconds of every timed call of each (problem index, part), and
        pi-robust's first timed output on each problem index.
    """
    spec = get(SOLVER)
    matrices = [shifted_block(problem) for problem in problems]
    items = [(number, part) for number in range(len(problems))
             for part in (SOLVER, *FACTORIZATIONS)]
    times: dict[tuple[int, str], list[float]] = {item: [] for item in items}
    first: dict[int, SolverOutput] = {}
    for call in Schedule(items, repeats, unit=lambda item: item, warm_up=True):
        number, part = call.item
        if part == SOLVER:
            output = call_solver(spec, problems[number], ACCURACY)
            seconds = output.time_s
            if call.timed:
                first.setdefault(number, output)
        else:
            seconds = time_once(matrices[number], FACTORIZATIONS[part])
        if call.timed:
            times[call.item].append(seconds)
    return times, first


def solver_figures(problem: ImpactProblem, first: SolverOutput, times: Sequence[float]
                   ) -> dict[str, Any]:
    """pi-robust at 1e-8: minimum solve time, and the judged figures of its first timed answer.

    Status, residual and v_error of the ``first`` timed answer are judged by qpbench's metrics,
    not by the solver's claim.

    Parameters
    ----------
    problem : ImpactProblem
        The box packing, with its reference.
    first : SolverOutput
        pi-robust's first timed output on it.
    times : sequence of float
        Its timed solves, in seconds.

    Returns
    -------
    dict
        ``solve_s``, the solver's status and claim, ``success``, ``residual``, ``v_error``,
        ``iterations`` and ``path``.
    """
    measured = metrics.evaluate(problem, first.impulses, ACCURACY)
    return {"solve_s": float(np.nanmin(times)), "solver_status": first.status,
            "claimed_success": first.claimed_success, "success": bool(measured["success"]),
            "residual": measured["residual"], "v_error": measured["v_error"],
            "iterations": first.iterations, "path": first.info.get("path", "")}


def measure_all(sizes: Sequence[int], seed: int, repeats: int) -> list[dict[str, Any]]:
    """The figures of one box packing per size of ``sizes`` (in that order), all timed together.

    Each packing gets its reference before the timings (:func:`timed_parts`).

    Parameters
    ----------
    sizes : sequence of int
        Ball counts of the packings.
    seed : int
        The packings' seed.
    repeats : int
        Timed calls per (packing, part).

    Returns
    -------
    list of dict
        One row per packing: size, nonzeros, the fastest factorization, its method and
        library and every method's time (:func:`qpbench.studies.factorization.fastest`),
        pi-robust's figures (:func:`solver_figures`), ``ratio`` (None when every
        factorization failed) and ``target_met``.
    """
    problems = [attach_reference(generate("box", size, seed=seed)[0]) for size in sizes]
    times, first = timed_parts(problems, repeats)
    rows = []
    for number, (size, problem) in enumerate(zip(sizes, problems, strict=True)):
        factor = fastest({name: times[(number, name)] for name in FACTORIZATIONS})
        solver = solver_figures(problem, first[number], times[(number, SOLVER)])
        ratio = (None if factor["factorization_s"] is None
                 else solver["solve_s"] / factor["factorization_s"])
        rows.append({
            "problem": problem.name, "balls": size, "contacts": problem.n_contacts,
            "nonzeros": int(problem.Q.nnz), **factor, **solver, "ratio": ratio,
            "target_met": bool(solver["success"] and ratio is not None
                               and ratio <= TARGET_RATIO)})
    return rows


def markdown(rows: Sequence[dict[str, Any]], repeats: int) -> str:
    """A short section with one table row per size.

    Parameters
    ----------
    rows : sequence of dict
        The rows of :func:`measure_all`.
    repeats : int
        Timed calls per part.

    Returns
    -------
    str
        The Markdown section, times in milliseconds.
    """
    lines = [
        "## pi-robust against one sparse factorization (box packings)\n",
        f"Target: `{SOLVER}`'s solve time at accuracy {ACCURACY:g} within {TARGET_RATIO:g}x "
        f"the time of ONE sparse factorization of Q + eps I (eps = {FACTOR_SHIFT:g} max diag Q; "
        f"the fastest of {_methods_text()}). Minimum of "
        f"{repeats} repeats each, interleaved (one untimed call of each part first, then "
        "rounds of one call of every part of every packing, in a rotated order), "
        "single-threaded BLAS, one process.\n",
        "| problem | contacts | nnz(Q) | factorization [ms] | "
        + " | ".join(f"{method} [ms]" for method in FACTORIZATIONS)
        + " | pi-robust [ms] | ratio | residual | v_error | target |",
        "|---|---:|---:|---:|" + "---:|" * len(FACTORIZATIONS) + "---:|---:|---:|---:|---|",
    ]
    for row in rows:
        verdict = "met" if row["target_met"] else "not met"
        if not row["success"]:
            verdict += " (pi-robust failed)"
        by_method = row["factorization_s_by_method"]
        lines.append(
            f"| {row['problem']} | {row['contacts']} | {row['nonzeros']} | "
            f"{_milliseconds(row['factorization_s'])} ({row['factorization_method']}) | "
            + " | ".join(_milliseconds(by_method.get(method)) for method in FACTORIZATIONS)
            + f" | {1e3 * row['solve_s']:.2f} | {_times(row['ratio'])} | "
            f"{row['residual']:.1e} | {row['v_error']:.1e} | {verdict} |")
    return "\n".join(lines) + "\n"


def _methods_text() -> str:
    """The factorizations timed, in words."""
    words = {CHOLMOD: f"`{CHOLMOD}` (simplicial LDL^T in approximate-minimum-degree order)",
             SUPERLU: f"`{SUPERLU}` (SuperLU `splu` in symmetric mode, diagonal pivots)",
             COLAMD: f"`{COLAMD}` (SuperLU `splu`, its default column order)"}
    return ", ".join(words[method] for method in FACTORIZATIONS)


def _milliseconds(seconds: float | None) -> str:
    """Seconds as milliseconds with two decimals; ``-`` for none (every call failed)."""
    return "-" if seconds is None else f"{1e3 * seconds:.2f}"


def _times(ratio: float | None) -> str:
    """A ratio as ``2.50x``; ``-`` for none."""
    return "-" if ratio is None else f"{ratio:.2f}x"


def single_threaded() -> bool:
    """Whether this process was started with single-threaded BLAS.

    The env variables are read when numpy loads, so setting them later changes nothing.

    Returns
    -------
    bool
        True when every variable of SINGLE_THREAD_ENV is ``1``.
    """
    return all(os.environ.get(name) == "1" for name in SINGLE_THREAD_ENV)


def speed(sizes: Sequence[int] = SPEED_SIZES, seed: int = 0,
          repeats: int = REPEATS) -> dict[str, Any]:
    """The JSON object of ``qpbench speed``: per-size figures, the verdict and a Markdown section.

    Per-size figures (largest first), whether the target is met on every size, and a ready
    ``markdown`` section.

    Parameters
    ----------
    sizes : sequence of int, optional
        Ball counts of the packings (duplicates once); SPEED_SIZES by default.
    seed : int, optional
        The packings' seed; 0 by default.
    repeats : int, optional
        Timed calls per part; REPEATS by default.

    Returns
    -------
    dict
        The settings, whether BLAS is single-threaded, ``rows``, ``target_met`` and
        ``markdown``.
    """
    rows = measure_all(sorted(set(sizes), reverse=True), seed, repeats)
    return {"solver": SOLVER, "accuracy": ACCURACY, "target_ratio": TARGET_RATIO,
            "factor_shift": FACTOR_SHIFT, "repeats": repeats, "seed": seed,
            "single_threaded_blas": single_threaded(), "rows": rows,
            "target_met": bool(rows) and all(row["target_met"] for row in rows),
            "markdown": markdown(rows, repeats)}
