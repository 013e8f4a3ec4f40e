"""The one registry of solvers. Backend modules call :func:`register`; a backend whose
import fails registers its solvers as unusable with the reason, so it drops out and says why.
"""

from __future__ import annotations

from collections.abc import Callable

from qpbench import EXTRA_SOLVERS_ENV
from qpbench.errors import QpbenchError
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverSpec

# a rule that derives pairs from the pairs the families register (the frictional twins of
# the frictionless solvers, say)
Derivation = Callable[[list[SolverSpec]], list[SolverSpec]]

_SOLVERS: dict[str, SolverSpec] = {}
_DERIVATIONS: list[Derivation] = []
_derived = False


def register(spec: SolverSpec) -> SolverSpec:
    """Adds ``spec`` under ``NAME/FORMULATION`` (a later registration replaces an earlier one).

    A solver that can run must have its row in the accuracy-options table
    (``qpbench.solvers.accuracy.OPTIONS``): none runs on defaults nobody chose.

    Parameters
    ----------
    spec : SolverSpec
        The solver-formulation pair, usable or not.

    Returns
    -------
    SolverSpec
        ``spec`` itself.

    Raises
    ------
    QpbenchError
        When a usable ``spec`` has no row in the accuracy-options table.
    """
    if spec.solve is not None and spec.name not in accuracy.OPTIONS:
        raise QpbenchError(f"solver '{spec.name}' has no row in the accuracy-options table "
                           "(qpbench/solvers/accuracy.py): add one, even an empty one, to say "
                           "that its defaults are chosen")
    _SOLVERS[spec.key] = spec
    return spec


def register_unusable(name: str, formulations: tuple[str, ...], backend: str, reason: str) -> None:
    """Records that ``name`` exists but cannot run here, and why.

    Parameters
    ----------
    name : str
        The solver's name.
    formulations : tuple[str, ...]
        The formulations it would pose; one unusable pair is registered for each.
    backend : str
        The backend family that would run it.
    reason : str
        Why it cannot run (the import error, say), shown wherever it is listed.
    """
    for formulation in formulations:
        register(SolverSpec(name=name, formulation=formulation, backend=backend, solve=None,
                            reason=reason))




def _import_extra_solvers() -> None:
    """Imports the modules named in $QPBENCH_EXTRA_SOLVERS (``module,module``), which register
    more solvers (e.g. test-only ones); worker processes inherit the variable, so see them too."""
    import importlib
    import os

    for module in os.environ.get(EXTRA_SOLVERS_ENV, "").split(","):
        if module.strip():
            try:
                importlib.import_module(module.strip())
            except ImportError as error:
                raise QpbenchError(f"${EXTRA_SOLVERS_ENV}: cannot import '{module.strip()}': "
                                   f"{error}") from error


def register_derivation(derive: Derivation) -> None:
    """Adds a rule that derives pairs from those the families register.

    Every rule runs once, after every family is imported (:func:`all_solvers`), on all the
    pairs they registered, so no family depends on the order in which the families are
    imported.

    Parameters
    ----------
    derive : Derivation
        Takes every registered pair, sorted by key, and gives the pairs to register.
    """
    _DERIVATIONS.append(derive)


def _derive() -> None:
    """Registers what every derivation gives, the first time every family is imported."""
    global _derived
    if _derived:
        return
    _derived = True
    registered = [_SOLVERS[key] for key in sorted(_SOLVERS)]
    for derive in _DERIVATIONS:
        for spec in derive(registered):
            register(spec)


def all_solvers() -> list[SolverSpec]:
    """Every registered solver-formulation pair, usable or not, sorted by key.

    The families' own, those derived from them, and those of $QPBENCH_EXTRA_SOLVERS. Every
    family is imported by then: importing this module imports its package first, whose
    ``__init__`` imports every family module (``qpbench.solvers.FAMILIES``).

    Returns
    -------
    list[SolverSpec]
        The pairs, sorted by ``NAME/FORMULATION``.

    Raises
    ------
    QpbenchError
        When a module of $QPBENCH_EXTRA_SOLVERS cannot be imported.
    """
    _derive()
    _import_extra_solvers()
    return [_SOLVERS[key] for key in sorted(_SOLVERS)]


def usable_solvers() -> list[SolverSpec]:
    """The registered pairs that can run here.

    Returns
    -------
    list[SolverSpec]
        The usable pairs of :func:`all_solvers`, sorted by key.
    """
    return [spec for spec in all_solvers() if spec.usable]


def resolve(names: list[str] | str) -> list[SolverSpec]:
    """Solver specs for names; ``NAME`` alone is every formulation it supports, ``NAME/FORM`` one.

    Parameters
    ----------
    names : list[str] or str
        Solver names, ``NAME`` or ``NAME/FORMULATION``, as a list or one comma-separated
        string.

    Returns
    -------
    list[SolverSpec]
        The usable pairs they name, each once, in the order named.

    Raises
    ------
    QpbenchError
        For an unknown name or one that is not usable here (with why).
    """
    if isinstance(names, str):
        names = [part for part in names.split(",") if part.strip()]
    specs = all_solvers()
    chosen: list[SolverSpec] = []
    for raw in names:
        name = raw.strip()
        matches = [s for s in specs if s.key == name or s.name == name]
        if not matches:
            known = ", ".join(sorted({s.name for s in specs}))
            raise QpbenchError(f"unknown solver '{name}' (known: {known})")
        usable = [s for s in matches if s.usable]
        if not usable:
            raise QpbenchError(f"solver '{name}' is not usable here: {matches[0].reason}")
        chosen.extend(s for s in usable if s not in chosen)
    return chosen


DEFAULT_FORMULATIONS = {"impact": ("dual", "lcp", "primal", "dual-factored"),
                        "frictional": ("nsgs", "staggered", "lcp", "ccp")}


def get(name: str, kind: str = "impact") -> SolverSpec:
    """The usable solver ``NAME/FORMULATION`` for problems of ``kind``.

    ``NAME`` alone means its default formulation for that kind, the first it has of
    DEFAULT_FORMULATIONS[kind] (any of its formulations when it has none of those).

    Parameters
    ----------
    name : str
        ``NAME`` or ``NAME/FORMULATION``.
    kind : str, optional
        ``impact`` (the default) or ``frictional``.

    Returns
    -------
    SolverSpec
        The chosen pair.

    Raises
    ------
    QpbenchError
        For an unknown or unusable name, or one that takes no problems of that kind.
    """
    specs = [spec for spec in resolve([name]) if kind in spec.kinds]
    if not specs:
        raise QpbenchError(f"solver '{name}' takes no {kind} problems")
    order = DEFAULT_FORMULATIONS.get(kind, ())
    rank = {formulation: i for i, formulation in enumerate(order)}
    return min(specs, key=lambda spec: rank.get(spec.formulation, len(rank)))
