"""Where pi-robust's time goes, against a floor of compiled linear algebra.

Problems (all in the repository): the SCISim research fork's 5x5 grid dumps
(``problems/dumps/grid5_itr_*.out``), the first impact of its first 7x7 grid scene
(``problems/head_to_head/fork_7x7_grid/grid7_itr_0.xml``, copied verbatim), a box packing
of 1000 balls (``generate("box", 1000, seed=0)``) and grids of 20 and 30 balls a side
(``generate("grid", size, seed=0)``: the sizes where pi-robust is furthest behind the best
peer; the 30x30 grid takes the Python path's interior point). For each, at accuracy 1e-8, the
fastest of rounds that each time every part below once, in turn:

* ``total_s``: pi-robust's ``time_s`` (the one stopwatch, ``call_solver``);
* ``harness_s``: ``call_solver`` around a solve function that returns zeros (blind copy,
  formulation, stopwatch): what every solver pays;
* ``trivial_s``: pi-robust's ``time_s`` on a one-contact problem (its fixed Python cost);
* ``kernel_s``: the compiled call of ``pi_robust_kernel.entry.pi_robust_into`` alone, as
  pi-robust makes it (``pi_robust_kernel.call.call_pi_robust_into``; 0 when the compiled path
  is not taken), ``python_path_s``: the Python fallback
  ``pi_robust.pi_robust`` when it runs; ``outside_kernel_s = total_s - kernel_s -
  python_path_s`` (set-up in Python, confirming the answer, the harness), never below 0;
* ``kernel_back_to_back_s``: the same compiled call on the same posed arrays, repeated back to
  back with nothing in between, and ``cold_kernel_s = kernel_s - kernel_back_to_back_s``: what
  the kernel loses inside ``call_solver``, where other work (the blind copy, the posing) has
  run since its last call. Back to back, the caches hold the kernel's code and data and the
  branch predictors have learned this very solve; other work in between wipes some of that.
  ``time_s`` includes this loss for every solver alike;
* ``product_s``: one product ``Q l`` over the problem's CSC Q in compiled code, and the
  counts the solver reports (linear solves, factorizations, interior iterations, its path);
* ``floor_s``: one Cholesky of the final active block ``Q_AA + eps I``, the faster of dense
  (LAPACK ``dpotrf``) and banded in reverse Cuthill-McKee order (``dpbtrf``), with A =
  contacts with l > 0 in pi-robust's answer and eps = 1e-8 max diag Q (redundant contacts
  make Q_AA singular), plus ``product_s``: what any active-set method that already knew the
  answer's support would pay. Both are timed inside one compiled call, repeated
  (``compiled_floor``), so no Python call overhead is in them, as it is in ``total_s``
  (``floor_s_by_kind``: the factorization alone, by kind).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from qpbench.bench.defaults import BREAKDOWN_REPEATS
from qpbench.inner_solvers import choose_by_name
from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump
from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.problem.impact import ImpactProblem
from qpbench.scenes import load_scene
from qpbench.simulation.stepper import Simulator
from qpbench.solvers import fixed_order_dense, lcp_interior, pi_robust, pi_robust_blocks
from qpbench.solvers.base import SolverOutput, SolverSpec
from qpbench.solvers.pi_robust_blocks import BlockSolver
from qpbench.solvers.pi_robust_kernel import call as kernel_call
from qpbench.solvers.registry import get
from qpbench.solvers.run import call_solver
from qpbench.solvers.sparse_cholesky import PatternFactor
from qpbench.studies import compiled_floor

SOLVER = "pi-robust"
ACCURACY = 1e-8
FLOOR_SHIFT = 1e-8
ROOT = Path(__file__).resolve().parents[2]
DUMPS = ("problems/dumps/grid5_itr_0.out", "problems/dumps/grid5_itr_1.out")
GRID7_SCENE = "problems/head_to_head/fork_7x7_grid/grid7_itr_0.xml"
TRIVIAL_DUMP = "problems/dumps/2_balls.json"
BOX_BALLS = 1000
GRID_SIZES = (20, 30)
# where the Python path factors a matrix, as (owner, attribute), each name as its callers look
# it up at call time: a policy block (dense, sparse, or in Woodbury form over the degrees of
# freedom, made anew or updated), the interior point's matrices (_timed counts a
# factorization inside another once)
FACTOR_CALLS = ((BlockSolver, "_factor"), (pi_robust_blocks, "updated_gram_factor"),
                (fixed_order_dense, "cholesky"), (PatternFactor, "factorize"),
                (lcp_interior, "gram_factor"), (pi_robust_blocks, "symmetric_factor"))


def first_impact(scene_path: str | Path, max_steps: int = 100) -> ImpactProblem:
    """The first impact problem (some contact approaching) of a frictionless scene.

    Parameters
    ----------
    scene_path : str or Path
        The scene file, simulated with its own inner solver.
    max_steps : int, optional
        The steps searched at most; 100 by default.

    Returns
    -------
    ImpactProblem
        The problem of the first step where ``b < 0`` somewhere.

    Raises
    ------
    ValueError
        When no step within ``max_steps`` has an impact.
    """
    simulator = Simulator(load_scene(scene_path), choose_by_name(None))
    for _ in range(max_steps):
        event = simulator.step()
        if isinstance(event.problem, ImpactProblem) and np.any(event.problem.b < 0):
            return event.problem
    raise ValueError(f"{scene_path}: no impact in {max_steps} steps")


def default_problems(root: Path = ROOT) -> list[ImpactProblem]:
    """The breakdown's problems: the 5x5 grid dumps, the 7x7 grid's first impact, a box packing
    and the generated grids of ``GRID_SIZES`` balls a side.

    Parameters
    ----------
    root : Path, optional
        The repository's folder, where DUMPS and GRID7_SCENE lie; ROOT by default.

    Returns
    -------
    list of ImpactProblem
        The problems, in that order.
    """
    problems = [import_dump(root / path) for path in DUMPS]
    problems.append(first_impact(root / GRID7_SCENE))
    problems.append(generate("box", BOX_BALLS, seed=0)[0])
    problems.extend(generate("grid", size, seed=0)[0] for size in GRID_SIZES)
    return problems


def _zeros(problem: ImpactProblem, accuracy: float, warm_start: np.ndarray | None = None
           ) -> SolverOutput:
    return SolverOutput(impulses=np.zeros(problem.n_contacts), status="zeros",
                        claimed_success=False)


HARNESS = SolverSpec(name="harness-zeros", formulation="lcp", backend="qpbench-breakdown",
                     solve=_zeros)


@contextmanager
def _timed(calls: tuple[tuple[Any, str], ...], sink: list[float]) -> Iterator[None]:
    """Replaces each ``owner.name`` of ``calls`` by a wrapper that appends to ``sink`` the wall
    time of each call made while no other of them runs: a call inside another is timed once,
    as part of the outer one."""
    depth = [0]
    originals = [(owner, name, getattr(owner, name)) for owner, name in calls]

    def wrapped(original: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            depth[0] += 1
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                depth[0] -= 1
                if depth[0] == 0:
                    sink.append(time.perf_counter() - start)
        return wrapper

    try:
        for owner, name, original in originals:
            setattr(owner, name, wrapped(original))
        yield
    finally:
        for owner, name, original in originals:
            setattr(owner, name, original)


def _banded_lower(block: sp.spmatrix) -> np.ndarray:
    """The lower band storage (``cholesky_banded``'s, lower=True) of a symmetric matrix after
    reverse Cuthill-McKee ordering."""
    order = reverse_cuthill_mckee(sp.csr_matrix(block), symmetric_mode=True)
    ordered = sp.coo_matrix(sp.csr_matrix(block)[order][:, order])
    lower = ordered.row >= ordered.col
    rows, cols, values = ordered.row[lower], ordered.col[lower], ordered.data[lower]
    width = int(np.max(rows - cols, initial=0))
    band = np.zeros((width + 1, block.shape[0]))
    band[rows - cols, cols] = values
    return band


class _FloorRounds:
    """The floor of one problem (``floor_s``), timed one round at a time (:meth:`round`), so
    that the caller can interleave its rounds with other timings: one Cholesky of the final
    active block ``Q_AA + eps I`` plus one product with Q, in compiled code
    (``compiled_floor``), the factorization the faster of dense (LAPACK ``dpotrf``) and banded
    in reverse Cuthill-McKee order (``dpbtrf``); the block and its band are built here,
    outside any clock."""

    def __init__(self, problem: ImpactProblem, impulses: np.ndarray) -> None:
        active = np.flatnonzero(impulses > 0)
        Q = problem.Q.tocsc()
        shift = FLOOR_SHIFT * metrics.vector_scale(problem.diag_Q)
        sparse_block = sp.csc_matrix(Q[active][:, active] + shift * sp.identity(active.size))
        band = _banded_lower(sparse_block) if active.size else np.zeros((1, 0))
        self.active, self.bandwidth = int(active.size), int(band.shape[0] - 1)
        self.product = compiled_floor.product_rounds(Q.indptr, Q.indices, Q.data, impulses)
        self.factorizations = {
            "dense": compiled_floor.cholesky_rounds(sparse_block.toarray(), False),
            "banded": compiled_floor.cholesky_rounds(band, True)}
        self.products: list[float] = []
        # per kind, each round's (seconds with the copy, seconds of the copy alone)
        self.rounds: dict[str, list[tuple[float, float]]] = {
            kind: [] for kind in self.factorizations}

    def round(self) -> None:
        self.products.append(self.product())
        for kind, timer in self.factorizations.items():
            if timer is not None:
                self.rounds[kind].append(timer())

    def figures(self) -> dict[str, Any]:
        """The floor's row entries: each part's fastest round (a factorization: with its
        copy, less the copy alone; inf when the block is not positive definite)."""
        by_kind = {kind: max(0.0, min(with_copy for with_copy, _ in self.rounds[kind])
                             - min(copy for _, copy in self.rounds[kind]))
                   if timer is not None else np.inf
                   for kind, timer in self.factorizations.items()}
        kind = min(by_kind, key=by_kind.get)
        product = min(self.products)
        return {"active": self.active, "bandwidth": self.bandwidth, "product_s": product,
                "floor_s": by_kind[kind] + product, "floor_kind": kind,
                "floor_s_by_kind": by_kind}


def _back_to_back(spec: SolverSpec, problem: ImpactProblem) -> Callable[[], float]:
    """A function that times two compiled calls in a row on one copy of ``problem`` posed for
    ``spec`` and returns the second's time: the kernel back to back, with nothing in between
    (the caller has seen the compiled path run)."""
    blind = problem.blind_copy()
    pose(blind, spec.formulation)
    settings = pi_robust.settings_for(ACCURACY)

    def once() -> float:
        start = time.perf_counter()
        pi_robust.kernel_into(blind, settings, None)
        return time.perf_counter() - start

    def twice() -> float:
        once()
        return once()

    return twice


def measure(problem: ImpactProblem, trivial: ImpactProblem, repeats: int = BREAKDOWN_REPEATS
            ) -> dict[str, Any]:
    """The breakdown of one problem (module docstring).

    Each of ``repeats`` rounds times every part once, in turn, so that a burst of load on the
    host falls on all parts alike; each part keeps its fastest round.

    Parameters
    ----------
    problem : ImpactProblem
        The problem measured.
    trivial : ImpactProblem
        A one-contact problem, for pi-robust's fixed cost.
    repeats : int, optional
        The rounds; BREAKDOWN_REPEATS by default.

    Returns
    -------
    dict
        The row: the problem's size, pi-robust's answer (success, residual, path, counts),
        every part's seconds (module docstring), the floor and ``ratio_to_floor``.
    """
    spec = get(SOLVER)
    first = call_solver(spec, problem, ACCURACY)  # untimed: its answer and counts are reported
    kernel_ran = bool(first.info.get("compiled"))  # True, or how the Python path followed it
    back_to_back_call = _back_to_back(spec, problem) if kernel_ran else None
    impulses = np.zeros(problem.n_contacts) if first.impulses is None else first.impulses
    floor_rounds = _FloorRounds(problem, impulses)
    parts: dict[str, list[float]] = {name: [] for name in (
        "total", "instrumented", "kernel", "python", "python_factor", "back_to_back",
        "harness", "trivial")}
    for _ in range(repeats):
        # pi-robust's own parts as the timing protocol (docs/design.md section 7) finds them:
        # never right after a solve of this problem by pi-robust, other parts ran since
        parts["total"].append(call_solver(spec, problem, ACCURACY).time_s)
        parts["trivial"].append(call_solver(spec, trivial, ACCURACY).time_s)
        parts["harness"].append(call_solver(HARNESS, problem, ACCURACY).time_s)
        kernel_calls: list[float] = []
        python_calls: list[float] = []
        factor_calls: list[float] = []
        with ExitStack() as timers:
            timers.enter_context(_timed(((kernel_call, "call_pi_robust_into"),),
                                        kernel_calls))
            timers.enter_context(_timed(((pi_robust, "pi_robust"),), python_calls))
            timers.enter_context(_timed(FACTOR_CALLS, factor_calls))
            parts["instrumented"].append(call_solver(spec, problem, ACCURACY).time_s)
        parts["kernel"].append(sum(kernel_calls))
        parts["python"].append(sum(python_calls))
        # (inside the Python path only: the kernel's own factors are compiled code)
        parts["python_factor"].append(sum(factor_calls) if python_calls else 0.0)
        parts["back_to_back"].append(back_to_back_call() if back_to_back_call else 0.0)
        floor_rounds.round()  # between the back-to-back calls and the next round's total
    total, kernel_s, python_s, back_to_back = (
        min(parts[name]) for name in ("total", "kernel", "python", "back_to_back"))
    measured = metrics.evaluate(problem, impulses, ACCURACY)
    info = first.info
    row = {
        "problem": problem.name, "contacts": problem.n_contacts, "nonzeros": int(problem.Q.nnz),
        "success": bool(measured["success"]), "residual": measured["residual"],
        "path": str(info.get("path", "")), "compiled": info.get("compiled", False) is True,
        "linear_solves": first.iterations, "factorizations": info.get("factorizations"),
        "interior_iterations": info.get("interior_iterations", 0),
        "total_s": total, "instrumented_total_s": min(parts["instrumented"]),
        "harness_s": min(parts["harness"]), "trivial_s": min(parts["trivial"]),
        "kernel_s": kernel_s, "python_path_s": python_s,
        # the factorizations of the round whose Python path was fastest
        "python_factor_s": parts["python_factor"][int(np.argmin(parts["python"]))],
        "outside_kernel_s": max(0.0, total - kernel_s - python_s),
        "kernel_back_to_back_s": back_to_back,
        "cold_kernel_s": max(0.0, kernel_s - back_to_back),
        **floor_rounds.figures(),  # product_s and floor_s
    }
    row["ratio_to_floor"] = row["total_s"] / row["floor_s"] if row["floor_s"] > 0 else math.nan
    return row


def markdown(rows: list[dict[str, Any]], repeats: int) -> str:
    """The breakdown as a Markdown section: what each part is, and a table of the rows.

    Parameters
    ----------
    rows : list of dict
        The rows of :func:`measure`.
    repeats : int
        The rounds each part was timed.

    Returns
    -------
    str
        The ``## Where pi-robust's time goes`` section, times in milliseconds.
    """
    lines = [
        "## Where pi-robust's time goes\n",
        f"pi-robust at accuracy {ACCURACY:g}, {repeats} rounds that each time every part once "
        "in turn (so that a burst of load on the host falls on all parts alike), each part's "
        "fastest round kept; single-threaded BLAS. total = `time_s`; harness = `call_solver` "
        "around a solver that returns zeros; trivial = pi-robust on one contact; kernel = the "
        "compiled call `pi_robust_into` alone; Python path = the fallback when it runs; of it, "
        "factorizations = the Python path's matrix factorizations (dense in a fixed order, "
        "CHOLMOD or SuperLU; the rest of that path is its products, step lengths and "
        "bookkeeping in Python); outside = total - kernel - Python path; back to back = the "
        "same compiled call repeated with nothing in between, and cold = kernel - back to back:"
        " what the kernel loses when other work (the blind copy, the posing) has run since its "
        "last call, so that its caches and branch predictors no longer hold this very solve "
        "(`time_s` includes such a loss for every solver); product = one `Q l` in compiled "
        "code; floor = one Cholesky in LAPACK (dense or banded in RCM order, the faster) of the"
        " final active block (l > 0) plus that product, both timed inside one compiled call, "
        "without Python call overhead.\n",
        "| problem | contacts | active | path | solves | factorizations | interior its | "
        "total [ms] | harness [ms] | trivial [ms] | kernel [ms] | back to back [ms] | "
        "cold [ms] | Python path [ms] | of it, factorizations [ms] | outside [ms] | "
        "product [ms] | floor [ms] | total / floor |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        "---:|---:|",
    ]
    for row in rows:
        ms = {key: 1e3 * row[key] for key in ("total_s", "harness_s", "trivial_s", "kernel_s",
                                              "kernel_back_to_back_s", "cold_kernel_s",
                                              "python_path_s", "python_factor_s",
                                              "outside_kernel_s",
                                              "product_s", "floor_s")}
        lines.append(
            f"| {row['problem']} | {row['contacts']} | {row['active']} | {row['path']}"
            f"{' (compiled)' if row['compiled'] else ''} | {row['linear_solves']} | "
            f"{row['factorizations']} | {row['interior_iterations']} | "
            f"{ms['total_s']:.3f} | {ms['harness_s']:.3f} | {ms['trivial_s']:.3f} | "
            f"{ms['kernel_s']:.3f} | {ms['kernel_back_to_back_s']:.3f} | "
            f"{ms['cold_kernel_s']:.3f} | {ms['python_path_s']:.3f} | "
            f"{ms['python_factor_s']:.3f} | {ms['outside_kernel_s']:.3f} | "
            f"{ms['product_s']:.4f} | {ms['floor_s']:.4f} ({row['floor_kind']}) | "
            f"{row['ratio_to_floor']:.1f}x |")
    return "\n".join(lines) + "\n"


def breakdown(problems: list[ImpactProblem] | None = None,
              repeats: int = BREAKDOWN_REPEATS) -> dict[str, Any]:
    """The JSON object of ``qpbench breakdown``: one row per problem and a ``markdown`` section.

    Parameters
    ----------
    problems : list of ImpactProblem or None, optional
        The problems measured; None (default) for :func:`default_problems`.
    repeats : int, optional
        The rounds; BREAKDOWN_REPEATS by default.

    Returns
    -------
    dict
        ``title``, ``solver``, ``accuracy``, ``repeats``, ``rows`` and ``markdown``.
    """
    problems = default_problems() if problems is None else problems
    trivial = import_dump(ROOT / TRIVIAL_DUMP)
    rows = [measure(problem, trivial, repeats) for problem in problems]
    return {"title": "Where pi-robust's time goes", "solver": SOLVER, "accuracy": ACCURACY,
            "repeats": repeats, "rows": rows, "markdown": markdown(rows, repeats)}
