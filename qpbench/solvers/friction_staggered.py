"""Staggered projections (``staggered``) for 2D Coulomb friction, with a frictionless solver
inside (docs/design.md section 8).

Source: Kaufman, Sueda, James and Pai, "Staggered projections for frictional contact in
multibody systems", SIGGRAPH Asia 2008; the loop follows SCISim's ``StaggeredProjections``
(keep the best iterate, end with one normal solve). A two-block Gauss-Seidel:

1. normal QP for the current l_T: :meth:`FrictionalProblem.normal_given` (the impact problem
   with ``b + W_NT l_T``), solved by X's own solve function;
2. friction box QP for that l_N: :meth:`FrictionalProblem.friction_box`,
   ``min 1/2 l_T^T W_TT l_T + (q_T + W_TN l_N)^T l_T`` over ``-mu l_N <= l_T <= mu l_N``,
   solved by X's backend with bounds (qpsolvers ``lb``/``ub``, cvxpy box constraints, IPOPT
   variable bounds); for the LCP solvers written here, which take no bounds, by projected
   Gauss-Seidel on the box (:func:`box_gauss_seidel`, compiled: it skips the coordinates of
   contacts with an empty box, ``l_N = 0`` or ``mu = 0``, which keep ``l_T = 0``). A backend
   gets the box QP restricted to the other contacts (:func:`on_free_coordinates`, its
   conversion inside its time). The answer is clipped into the box (IPOPT relaxes bounds
   slightly). W's blocks are the formulation's matrices, built before the clock;
3. qpbench's Coulomb residual (``friction_metrics.residual``) of ``(l_N, l_T)``; stop at
   ``<= eps``, or after ``max_outer`` rounds (the accuracy table's ``staggered`` row);
4. the l_T the next round starts from: that answer in SCISim's loop; here, with the table's
   ``anderson_depth`` m > 0, the Anderson mixing of the last m + 1 rounds
   (``qpbench.solvers.anderson``; Walker and Ni 2011), the loop being a fixed-point
   iteration ``l_T <- G(l_T)``, with the history restarted whenever ``||G(x) - x||`` grows.
   Each round's iterate is still a staggered one (the normal answer for the l_T it started
   from, the box answer for that normal answer), judged as in step 3; only where the next
   round starts changes, so that far fewer rounds are needed where contacts change between
   sticking and sliding (docs/notes/pi-robust.md, "pi-robust/staggered: the call, and the
   rounds").

A warm start r is checked first (returned as it is when it already meets eps) and its l_T
starts the loop. Both inner solves run at accuracy ``inner_accuracy`` (eps / 10, as Acary,
Bremond and Huber 2018 do). The best iterate is kept; at the end one normal solve given the
best l_T restores the normal law ("to prevent penetration"), and the better of that answer
and the best iterate, by the Coulomb residual, is returned. A fixed point is exact Coulomb
friction; convergence is not guaranteed. ``iterations`` is the sum of the inner solvers'
iterations (where they report them), ``info["outer_iterations"]`` the rounds. The claim is
the Coulomb residual's test, qpbench's own.

The twins of ``COMPILED_LOOPS`` (pi-robust) first run this whole loop as one compiled call
(``qpbench.solvers.staggered_compiled``: the same rounds and the same answers, without a
return to Python between inner solves); the loop here runs when that declines.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from qpbench.problem import friction_metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.metrics import TINY
from qpbench.solvers import (
    accuracy,
    anderson,
    box_sweeps,
    colouring,
    cvxpy_,
    ipopt_,
    qpsolvers_,
    registry,
    staggered_compiled,
)
from qpbench.solvers.base import SolveFunction, SolverOutput, SolverSpec
from qpbench.solvers.friction_ccp import derived, frictionless_solvers
from qpbench.solvers.quiet import c_stdout_silenced

FORMULATION = "staggered"
ROW = staggered_compiled.ROW  # the accuracy row of the outer loop and of the box sweeps


@dataclass
class BoxQP:
    """``min 1/2 x^T P x + c^T x`` over ``lower <= x <= upper`` (P symmetric PSD); a coordinate
    with ``lower == upper`` (an empty friction box: l_N = 0 or mu = 0) is fixed there."""

    P: sp.csc_matrix
    c: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @property
    def n(self) -> int:
        return int(self.c.shape[0])


@dataclass
class BoxAnswer:
    x: np.ndarray | None
    status: str
    claimed_success: bool
    iterations: int | None = None


# a box solver: (box QP, inner accuracy, scale, start) -> answer
BoxSolver = Callable[[BoxQP, float, float, np.ndarray], BoxAnswer]


# --- the box QP solved here: projected Gauss-Seidel ---------------------------------------
def _symmetric_arrays(box: BoxQP) -> tuple[sp.csc_matrix, tuple[np.ndarray, ...]]:
    """P as CSC with sorted indices, and the arrays ``qpbench.solvers.box_sweeps`` takes:
    P is symmetric, so its CSC arrays are its CSR arrays (rows in order), then c, lower,
    upper."""
    P = box.P if sp.isspmatrix_csc(box.P) else sp.csc_matrix(box.P)
    P.sort_indices()
    return P, (P.indptr, P.indices, P.data, np.ascontiguousarray(box.c, dtype=float),
               np.ascontiguousarray(box.lower, dtype=float),
               np.ascontiguousarray(box.upper, dtype=float))


def box_residual(box: BoxQP, x: np.ndarray) -> float:
    """The box QP's natural-map residual of ``x``, a velocity (``box_sweeps.box_residual``).

    ``||d x - clip(d x - g, d lower, d upper)||_inf`` with ``g = P x + c``, ``d = diag P``
    (1 where it is 0).

    Parameters
    ----------
    box : BoxQP
        The box QP of m coordinates.
    x : np.ndarray
        The point, shape (m,).

    Returns
    -------
    float
        The residual (absolute, not scaled).
    """
    _, arrays = _symmetric_arrays(box)
    return float(box_sweeps.box_residual(*arrays, np.ascontiguousarray(x, dtype=float)))


def box_gauss_seidel(box: BoxQP, tolerance: float, max_sweeps: int, check_every: int,
                     start: np.ndarray) -> BoxAnswer:
    """Projected Gauss-Seidel on the box QP, colour by colour on the graph of P.

    Coordinate descent with clamping, ``x_i <- clip(x_i - g_i / P_ii, lower_i, upper_i)``,
    colour by colour (as ``qpbench.solvers.pgs``), until the box residual
    (:func:`box_residual`) is at most ``tolerance`` (checked every ``check_every`` sweeps); the
    sweeps run compiled (``qpbench.solvers.box_sweeps``). A coordinate with ``P_ii = 0`` has a
    zero row (P is PSD) and a constant gradient c_i: it goes to the bound that gradient points
    to, once.

    Parameters
    ----------
    box : BoxQP
        The box QP of m coordinates.
    tolerance : float
        The absolute box residual to reach (a velocity).
    max_sweeps : int
        The most sweeps.
    check_every : int
        Sweeps between residual checks.
    start : np.ndarray
        The starting point, shape (m,); it is clipped into the box first.

    Returns
    -------
    BoxAnswer
        The last iterate, ``converged`` or the sweep limit, the claim and the sweeps done.
    """
    P, arrays = _symmetric_arrays(box)
    x, sweeps, converged = box_sweeps.box_gauss_seidel(
        *arrays, P.diagonal(), colouring.colour_order(P.indptr, P.indices),
        np.ascontiguousarray(start, dtype=float), tolerance, max_sweeps, check_every)
    if converged:
        return BoxAnswer(x, "converged", True, sweeps)
    return BoxAnswer(x, f"max_sweeps ({max_sweeps}) reached", False, sweeps)


def _own_box_solver(box: BoxQP, eps: float, scale: float, start: np.ndarray) -> BoxAnswer:
    options = accuracy.options_for(ROW, eps, scale)
    return box_gauss_seidel(box, eps * scale, options["box_max_sweeps"],
                            options["box_check_every"], start)


# --- the box QP through the backends --------------------------------------------------------
def on_free_coordinates(solve: BoxSolver) -> BoxSolver:
    """``solve`` on the coordinates whose box is not empty (``lower < upper``).

    The others are fixed at their bound and their terms moved into the linear term, so the
    backends get no degenerate bounds.

    Parameters
    ----------
    solve : BoxSolver
        A box solver for boxes whose coordinates are all free.

    Returns
    -------
    BoxSolver
        The same signature on any box: ``solve`` on the free coordinates (not called when
        there are none), its answer written back among the fixed ones.
    """

    def restricted(box: BoxQP, eps: float, scale: float, start: np.ndarray) -> BoxAnswer:
        free = box.upper > box.lower
        if free.all():
            return solve(box, eps, scale, start)
        x = box.lower.copy()
        if not free.any():
            return BoxAnswer(x, "empty boxes", True, 0)
        index, others = np.flatnonzero(free), np.flatnonzero(~free)
        rows = sp.csr_matrix(box.P)[index]
        linear = box.c[index] + rows[:, others] @ x[others]
        answer = solve(BoxQP(P=sp.csc_matrix(rows[:, index]), c=linear, lower=box.lower[index],
                             upper=box.upper[index]), eps, scale, start[index])
        if answer.x is None:
            return answer
        x[index] = answer.x
        return BoxAnswer(x, answer.status, answer.claimed_success, answer.iterations)

    return restricted


def _qpsolvers_box_solver(name: str) -> BoxSolver:
    solver = qpsolvers_.REGULARIZED.get(name, name)
    qpsolvers = qpsolvers_.qpsolvers

    def solve(box: BoxQP, eps: float, scale: float, start: np.ndarray) -> BoxAnswer:
        options = accuracy.options_for(name, eps, scale)
        P = box.P
        if "regularization" in options:
            delta = float(options.pop("regularization")) * max(
                float(np.max(P.diagonal(), initial=0.0)), TINY)
            P = sp.csc_matrix(P + delta * sp.identity(box.n, format="csc"))
        if solver in ("quadprog", "daqp"):
            P = P.toarray()
        qp = qpsolvers.Problem(P=P, q=box.c, lb=box.lower, ub=box.upper)
        initvals = start if solver in qpsolvers_.WARM_START else None
        quiet = c_stdout_silenced() if solver == "osqp" else contextlib.nullcontext()
        with warnings.catch_warnings(), quiet:
            warnings.simplefilter("ignore")
            try:
                solution = qpsolvers.solve_problem(qp, solver=solver, initvals=initvals,
                                                   **options)
            except (qpsolvers.ProblemError, qpsolvers.SolverError, ValueError) as error:
                return BoxAnswer(None, f"error: {error}", False)
        status, iterations = qpsolvers_._claim(solver, solution)
        x = solution.x if solution.x is not None and np.size(solution.x) == box.n else None
        return BoxAnswer(x, status, bool(solution.found), iterations)

    return solve


def _cvxpy_box_solver(name: str) -> BoxSolver:
    solver = next(key for key in cvxpy_.SOLVERS if cvxpy_.qpbench_name(key) == name)

    def solve(box: BoxQP, eps: float, scale: float, start: np.ndarray) -> BoxAnswer:
        import cvxpy as cp

        options = accuracy.options_for(name, eps, scale)
        x = cp.Variable(box.n, name="l_T")
        objective = 0.5 * cp.quad_form(x, cp.psd_wrap(box.P)) + box.c @ x
        model = cp.Problem(cp.Minimize(objective), [x >= box.lower, x <= box.upper])
        extra = {}
        if solver in cvxpy_.NLP_SOLVERS:
            extra["nlp"] = True
            x.value = start
        quiet = c_stdout_silenced() if solver in ("OSQP", "IPOPT") else contextlib.nullcontext()
        with warnings.catch_warnings(), quiet:
            warnings.simplefilter("ignore")
            try:
                model.solve(solver=solver, **extra, **options)
            except (cp.error.SolverError, ValueError, ArithmeticError) as error:
                return BoxAnswer(None, f"error: {type(error).__name__}: {error}", False)
        stats = model.solver_stats
        iterations = getattr(stats, "num_iters", None) if stats is not None else None
        value = None if x.value is None else np.asarray(x.value, dtype=float).ravel()
        return BoxAnswer(value, str(model.status), model.status == cp.OPTIMAL,
                         int(iterations) if isinstance(iterations, int | np.integer) else None)

    return solve


def _ipopt_box_solver(name: str) -> BoxSolver:
    def solve(box: BoxQP, eps: float, scale: float, start: np.ndarray) -> BoxAnswer:
        options = accuracy.options_for(name, eps, scale)
        program = ipopt_.QuadraticProgram(box.P, box.c, sp.csr_matrix((0, box.n)))
        nlp = ipopt_.cyipopt.Problem(n=box.n, m=0, problem_obj=program, lb=box.lower,
                                     ub=box.upper, cl=np.zeros(0), cu=np.zeros(0))
        for key, value in options.items():
            nlp.add_option(key, value)
        with c_stdout_silenced():
            x, info = nlp.solve(np.clip(start, box.lower, box.upper))
        code = int(info.get("status", -199))
        return BoxAnswer(np.asarray(x, dtype=float), f"{code}", code == 0, program.iterations)

    return solve


# the backends that take the friction box QP themselves, with bounds: (box solver of a
# solver name, description)
BOUNDED_BACKENDS: dict[str, tuple[Callable[[str], BoxSolver], str]] = {
    "qpsolvers": (_qpsolvers_box_solver, "{name} with lb/ub"),
    "cvxpy": (_cvxpy_box_solver, "{name} with box constraints"),
    "cyipopt": (_ipopt_box_solver, "ipopt with variable bounds"),
}


def box_solver_for(spec: SolverSpec) -> tuple[BoxSolver, str]:
    """The friction box QP solver that goes with the frictionless solver ``spec``.

    Its backend's with bounds (``BOUNDED_BACKENDS``), else projected Gauss-Seidel.

    Parameters
    ----------
    spec : SolverSpec
        The frictionless pair.

    Returns
    -------
    solver : BoxSolver
        The box solver, ``(box, inner accuracy, scale, start) -> BoxAnswer``.
    description : str
        How the twin's description names it.
    """
    if spec.backend in BOUNDED_BACKENDS:
        make, description = BOUNDED_BACKENDS[spec.backend]
        return on_free_coordinates(make(spec.name)), description.format(name=spec.name)
    return _own_box_solver, "projected Gauss-Seidel on the box (written here)"


# --- the outer loop --------------------------------------------------------------------
class Inner:
    """The two inner solves of one staggered run, counting their iterations."""

    def __init__(self, problem: FrictionalProblem, normal_solve: SolveFunction,
                 box_solver: BoxSolver, warm_normal: bool, accuracy_level: float) -> None:
        self.problem = problem
        self.normal_solve = normal_solve
        self.box_solver = box_solver
        self.warm_normal = warm_normal
        self.eps = accuracy_level
        self.iterations = 0
        self.known = False  # whether any inner solver reported an iteration count
        self.solves = 0

    def _count(self, iterations: int | None) -> None:
        self.solves += 1
        if iterations is not None:
            self.iterations += int(iterations)
            self.known = True

    def normal(self, tangential: np.ndarray, start: np.ndarray | None
               ) -> tuple[np.ndarray | None, str]:
        """Solve the normal QP for a fixed l_T with the frictionless solver.

        Parameters
        ----------
        tangential : np.ndarray
            l_T, shape (n,).
        start : np.ndarray or None
            A warm start of l_N, shape (n,); passed on only when the solver takes warm
            starts.

        Returns
        -------
        normal : np.ndarray or None
            l_N clipped to >= 0, shape (n,); None when the solver gave no finite answer of
            that shape.
        status : str
            The solver's status.
        """
        problem = self.problem
        sub = problem.normal_given(tangential)
        _share_matrices(sub, problem.normal)
        output = self.normal_solve(sub, self.eps, start if self.warm_normal else None)
        self._count(output.iterations)
        impulses = output.impulses
        if impulses is None or np.shape(impulses) != (problem.n_contacts,) or \
                not np.all(np.isfinite(impulses)):
            return None, output.status
        return np.maximum(np.asarray(impulses, dtype=float), 0.0), output.status

    def friction(self, normal: np.ndarray, start: np.ndarray) -> tuple[np.ndarray | None, str]:
        """Solve the friction box QP for a fixed l_N with the box solver.

        Parameters
        ----------
        normal : np.ndarray
            l_N, shape (n,).
        start : np.ndarray
            A start of l_T, shape (n,), clipped into the box before it is handed over.

        Returns
        -------
        tangential : np.ndarray or None
            l_T clipped into ``-mu l_N <= l_T <= mu l_N``, shape (n,); zeros when every box
            is empty; None when the box solver gave no finite answer of that shape.
        status : str
            The box solver's status (``empty boxes`` when it was not called).
        """
        W_TT, linear, lower, upper = self.problem.friction_box(normal)
        if not np.any(upper > lower):
            return np.zeros(self.problem.n_contacts), "empty boxes"
        box = BoxQP(P=W_TT, c=linear, lower=lower, upper=upper)
        answer = self.box_solver(box, self.eps, self.problem.scale,
                                 np.clip(start, lower, upper))
        self._count(answer.iterations)
        if answer.x is None or np.shape(answer.x) != (box.n,) or \
                not np.all(np.isfinite(answer.x)):
            return None, answer.status
        return np.clip(answer.x, lower, upper), answer.status


def _share_matrices(sub: ImpactProblem, normal: ImpactProblem) -> None:
    """Q, M^-1 G and diag(Q) of the normal problem do not depend on l_T: the sub-problem of
    every round reuses them (cached properties) instead of forming them again."""
    for name in ("M_inv_G", "Q", "diag_Q"):
        sub.__dict__[name] = getattr(normal, name)


def staggered(problem: FrictionalProblem, inner: Inner, eps: float, max_outer: int,
              warm_start: np.ndarray | None, depth: int = 0) -> SolverOutput:
    """Run the staggered-projections loop of the module docstring on ``problem``.

    With ``depth`` > 0 each round after the first starts from the Anderson mixing of the last
    ``depth + 1`` rounds' friction impulses (``qpbench.solvers.anderson.next_start``) instead
    of the last answer; the history restarts from the current round when the fixed-point
    residual ``||G(x) - x||`` grows. Every round's iterate stays a staggered one:
    the normal answer for the l_T the round started from and the box answer for it.

    Parameters
    ----------
    problem : FrictionalProblem
        The frictional problem of n contacts.
    inner : Inner
        Its two inner solves, which count their iterations.
    eps : float
        The Coulomb residual to reach (qpbench's relative residual).
    max_outer : int
        The most rounds.
    warm_start : np.ndarray or None
        r = (l_N, l_T), shape (2n,); returned as it is when it already meets ``eps``, and
        its l_T starts the loop; None or an unusable guess starts at 0.
    depth : int, optional
        Anderson acceleration's depth (the accuracy table's ``anderson_depth``); 0 (the
        default) for the plain loop.

    Returns
    -------
    SolverOutput
        The better of the best iterate and the final normal solve (no impulses when no
        round finished), claimed when its Coulomb residual is at most ``eps``;
        ``iterations`` is the inner solvers' sum (None when none reported any), ``info``
        holds ``outer_iterations``, ``inner_solves`` and, with an answer, its ``residual``
        and which one was ``returned``.
    """
    n = problem.n_contacts
    normal = np.zeros(n)
    tangential = np.zeros(n)
    best, best_residual = None, np.inf
    if warm_start is not None:
        warm = np.asarray(warm_start, dtype=float).ravel()
        if warm.shape == (2 * n,) and np.all(np.isfinite(warm)):
            normal, tangential = np.maximum(warm[:n], 0.0), warm[n:].copy()
            residual = friction_metrics.residual(problem, warm)
            best, best_residual = warm, residual
            if residual <= eps:
                return _output(warm, residual, eps, "warm start already converged", 0, inner)
    status = f"max_outer ({max_outer}) reached"
    rounds = 0
    start = tangential  # l_T that the next round starts from
    starts, answers = np.empty((depth + 1, n)), np.empty((depth + 1, n))  # the mixing's history
    kept, last_step = 0, np.inf
    while rounds < max_outer:
        rounds += 1
        solved_normal, normal_status = inner.normal(start, normal)
        if solved_normal is None:
            status = f"normal QP failed: {normal_status}"
            break
        normal = solved_normal
        solved_tangential, box_status = inner.friction(normal, start)
        if solved_tangential is None:
            status = f"friction QP failed: {box_status}"
            break
        tangential = solved_tangential
        impulses = np.concatenate([normal, tangential])
        residual = friction_metrics.residual(problem, impulses)
        if residual < best_residual:
            best, best_residual = impulses, residual
        if residual <= eps:
            status = "converged"
            break
        start, kept, last_step = anderson.next_start(starts, answers, kept, last_step,
                                                     np.asarray(start, dtype=float), tangential)
    if best is None:
        return SolverOutput(impulses=None, status=status, claimed_success=False,
                            iterations=inner.iterations if inner.known else None,
                            info={"outer_iterations": rounds, "inner_solves": inner.solves})
    # one normal solve given the best friction impulse (SCISim: "to prevent penetration")
    chosen, chosen_residual, ending = best, best_residual, "best iterate"
    final_normal, _ = inner.normal(best[n:], best[:n])
    if final_normal is not None:
        final = np.concatenate([final_normal, best[n:]])
        final_residual = friction_metrics.residual(problem, final)
        if final_residual <= best_residual or final_residual <= eps:
            chosen, chosen_residual, ending = final, final_residual, "final normal solve"
    if status != "converged" and chosen_residual <= eps:
        status = "converged"
    return _output(chosen, chosen_residual, eps, status, rounds, inner, ending)


def _output(impulses: np.ndarray, residual: float, eps: float, status: str, rounds: int,
            inner: Inner, ending: str = "warm start") -> SolverOutput:
    return SolverOutput(impulses=impulses, status=status, claimed_success=bool(residual <= eps),
                        iterations=inner.iterations if inner.known else None,
                        info={"outer_iterations": rounds, "inner_solves": inner.solves,
                              "residual": residual, "returned": ending})


# the solvers whose staggered twin runs its whole loop compiled first
# (``qpbench.solvers.staggered_compiled``), the Python loop when that declines
COMPILED_LOOPS = ("pi-robust",)


def make_solve(spec: SolverSpec, box_solver: BoxSolver) -> Callable[..., SolverOutput]:
    """The solve function of ``spec.name/staggered``.

    For ``COMPILED_LOOPS`` it first tries the compiled loop
    (``qpbench.solvers.staggered_compiled``) and runs :func:`staggered` when that declines.

    Parameters
    ----------
    spec : SolverSpec
        A usable frictionless pair; its solve function solves the normal QP.
    box_solver : BoxSolver
        The friction box QP's solver (:func:`box_solver_for`).

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` on a FrictionalProblem, with the options of
        the accuracy table's ``staggered`` row.
    """
    assert spec.solve is not None
    normal_solve = spec.solve

    def solve(problem: FrictionalProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        if spec.name in COMPILED_LOOPS:
            answer = staggered_compiled.solve(problem, eps, warm_start)
            if answer is not None:
                return answer
        options = accuracy.options_for(ROW, eps, problem.scale)
        inner = Inner(problem, normal_solve, box_solver, spec.warm_start,
                      options["inner_accuracy"])
        return staggered(problem, inner, eps, options["max_outer"], warm_start,
                         int(options["anderson_depth"]))

    return solve


def twin(spec: SolverSpec) -> SolverSpec:
    """``NAME/staggered`` of a frictionless solver ``spec`` (unusable with its reason).

    Parameters
    ----------
    spec : SolverSpec
        A pair of :func:`qpbench.solvers.friction_ccp.frictionless_solvers`.

    Returns
    -------
    SolverSpec
        The twin: it takes warm starts, stops on qpbench's own residual, and its set-up
        also loads the compiled box sweeps where it uses them.
    """

    def build(inner: SolverSpec) -> tuple[Callable[..., SolverOutput], str]:
        box_solver, box_name = box_solver_for(inner)
        return make_solve(inner, box_solver), (f"staggered projections: normal QP by "
                                               f"{inner.key}, friction box QP by {box_name}")

    sweeps_here = spec.backend not in BOUNDED_BACKENDS

    def prepare() -> None:  # the inner solver's set-up, the compiled mixing, sweeps and loop
        if spec.prepare is not None:
            spec.prepare()
        anderson.warm_up()
        if sweeps_here:
            box_sweeps.warm_up()
        if spec.name in COMPILED_LOOPS:
            staggered_compiled.warm_up()

    return derived(spec, FORMULATION, build, warm_start=True, own_stopping_rule=True,
                   prepare=prepare)


registry.register_derivation(
    lambda specs: [twin(spec) for spec in frictionless_solvers(specs)])
