"""Anitescu's convex relaxation (``ccp``) of a frictional problem, run by every frictionless
solver of the ``dual`` or ``lcp`` formulation (docs/design.md section 8).

In 2D the relaxed cone problem is an ordinary impact problem in ``z = (z+, z-) >= 0`` with the
columns ``n + mu t`` and ``n - mu t`` (:meth:`FrictionalProblem.relaxed`), so each such solver
``X`` gets a twin ``X/ccp`` that hands ``problem.relaxed()`` to X's own solve function, with
X's own accuracy row, and maps its answer back with :meth:`FrictionalProblem.from_relaxed`.
The twin is judged by the ccp model's natural map; its Coulomb residual is the model error.
Its claim is X's claim on the relaxed problem, whose residual is computed with other weights
(the relaxed problem's ``diag(Q)`` and scale), so it is not qpbench's ccp verdict by
construction.

A warm start r = (l_N, l_T) enters as ``z+- = (l_N +- l_T / mu) / 2`` (``l_N / 2`` each where
mu = 0), clipped to z >= 0 (the maps of ``qpbench.solvers.relaxation``). pi-robust's twin does
all of it in one compiled call first (``pi_robust.solve_relaxed``: the same maps; its start is
first swept contact by contact, each contact's (z+, z-) as one 2x2 block, and the general path
runs only where it declines).
The twins are a derivation of the registry (``registry.register_derivation``): they are made
once every family is imported, whatever the order, and an unusable X gives an unusable twin with
X's reason. The native and Siconos backends get none (``UNTWINNED_BACKENDS``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from qpbench.problem.friction import FrictionalProblem
from qpbench.solvers import pi_robust, registry
from qpbench.solvers.base import SolveFunction, SolverOutput, SolverSpec
from qpbench.solvers.relaxation import mapped_back, relaxed_start

FORMULATION = "ccp"
INNER_FORMULATIONS = ("dual", "lcp")  # the forms whose solvers take an ImpactProblem's Q, b
# backends without frictional twins: a native pair measures a backend's own call path beside
# its qpsolvers twin (which is twinned), and Siconos brings its own 2D friction solvers (fc2d)
UNTWINNED_BACKENDS = ("native", "siconos")


def frictionless_solvers(specs: list[SolverSpec]) -> list[SolverSpec]:
    """The impact solvers among ``specs`` of a ``dual`` or ``lcp`` formulation, usable or not.

    One per name (its ``dual`` form where it has both), in the order given, but for
    ``UNTWINNED_BACKENDS``.

    Parameters
    ----------
    specs : list[SolverSpec]
        Registered pairs.

    Returns
    -------
    list[SolverSpec]
        The pairs that get a frictional twin.
    """
    chosen: dict[str, SolverSpec] = {}
    for spec in specs:
        if ("impact" not in spec.kinds or spec.formulation not in INNER_FORMULATIONS
                or spec.backend in UNTWINNED_BACKENDS):
            continue
        if spec.name not in chosen or spec.formulation == "dual":
            chosen[spec.name] = spec
    return list(chosen.values())


def make_solve(inner: SolveFunction, compiled: Callable[..., SolverOutput | None] | None = None
               ) -> Callable[..., SolverOutput]:
    """The solve function of a twin: ``inner`` on the relaxed problem, mapped back to r.

    First ``compiled`` (the relaxation, solve and maps in one compiled call) where the solver
    has one, unless it declines (None).

    Parameters
    ----------
    inner : SolveFunction
        The frictionless solver's solve function.
    compiled : callable or None, optional
        ``compiled(problem, eps, warm_start)`` giving the twin's output or None when it
        declines; None (the default) when the solver has none.

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` on a FrictionalProblem, whose impulses are
        r = (l_N, l_T).
    """

    def solve(problem: FrictionalProblem, eps: float, warm_start: np.ndarray | None = None
              ) -> SolverOutput:
        if compiled is not None:
            answer = compiled(problem, eps, warm_start)
            if answer is not None:
                return answer
        return mapped_back(problem, inner(problem.relaxed(), eps,
                                          relaxed_start(problem, warm_start)))

    return solve


def derived(spec: SolverSpec, formulation: str,
            build: Callable[[SolverSpec], tuple[Callable[..., SolverOutput], str]],
            **fields: Any) -> SolverSpec:
    """The frictional twin ``NAME/formulation`` of a frictionless solver ``spec``.

    Its solve function and description are what ``build(spec)`` gives; it is unusable with
    spec's reason if spec is. Its set-up is spec's unless ``fields`` name a ``prepare`` of
    its own.

    Parameters
    ----------
    spec : SolverSpec
        The frictionless pair.
    formulation : str
        The twin's formulation (``ccp``, ``staggered``).
    build : callable
        Gives the twin's solve function and description from ``spec``; not called when
        ``spec`` is unusable.
    **fields : Any
        Further SolverSpec fields of a usable twin (``warm_start``, ``prepare``, ...).

    Returns
    -------
    SolverSpec
        The twin, of kind ``frictional``, with spec's name, backend and version.
    """
    common = {"name": spec.name, "formulation": formulation, "backend": spec.backend,
              "version": spec.version, "kinds": ("frictional",)}
    if not spec.usable:
        return SolverSpec(**common, solve=None, reason=spec.reason)
    solve, description = build(spec)
    fields.setdefault("prepare", spec.prepare)
    return SolverSpec(**common, solve=solve, description=description, **fields)


def twin(spec: SolverSpec) -> SolverSpec:
    """``NAME/ccp`` of a frictionless solver ``spec`` (unusable with its reason if it is).

    Parameters
    ----------
    spec : SolverSpec
        A pair of :func:`frictionless_solvers`.

    Returns
    -------
    SolverSpec
        The twin; it takes warm starts when ``spec`` does.
    """
    return derived(spec, FORMULATION, lambda inner: (
        make_solve(inner.solve, COMPILED_TWINS.get(inner.name)),
        f"Anitescu's relaxation (z >= 0, columns n +- mu t) solved by {inner.key}"),
        warm_start=spec.warm_start)


# the solvers whose twin first runs as one compiled call: relaxation, solve and both maps
COMPILED_TWINS: dict[str, Callable[..., SolverOutput | None]] = {
    pi_robust.NAME: pi_robust.solve_relaxed}


registry.register_derivation(
    lambda specs: [twin(spec) for spec in frictionless_solvers(specs)])
