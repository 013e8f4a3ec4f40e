"""The sets of ``qpbench head-to-head`` (``qpbench.studies.head_to_head``): which set a problem
belongs to, the order the sets are measured in, and the seeds of the generated problems.

A problem's set is named by its family: the fork's dumps and grid scenes, the hard families
(a set each, named by the family), and for the generated grids and box packings and the
impacts captured from dense piles (scenes ``circle_pile_N`` and ``box_pile_N`` of N bodies,
as a set file's ``[[piles]]`` makes them) a set per size bucket (``grids 10-14``, ``box
packings 1k-4k``, ``dense piles 1k``), so that a speedup is shown per size rather than
averaged over sizes whose times differ by orders of magnitude. A frictional problem's set
is named by the model its pair's formulation solves (``coulomb`` or ``ccp``), so that each set
compares pairs that solve one law; Siconos' granular flows (imported, family ``siconos``) form
sets of their own, those given in global form (M, H: ``gfc2d`` files) apart from those given
reduced to the contacts (W alone: ``fc2d`` files, 667 to 7,002 contacts in the shared data).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from qpbench.problem.friction import MODELS, FrictionalProblem, model_of
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import ReducedFrictionalProblem
from qpbench.problem.siconos_import import FAMILY as SICONOS_FAMILY

# generated families of a set each, named by the family; each family's fastest external pair
# of the main benchmark runs on its set
HARD_FAMILIES = ("k3", "k4", "k4-middle", "cradle", "near-duplicate", "mass-ratio")
# size buckets of the generated grids (balls per side) and box packings (balls), smaller
# first: (set name, smallest size, largest size); a size in no bucket is a set of its own
GRID_BUCKETS = (("grids 4-9", 4, 9), ("grids 10-14", 10, 14), ("grids 16-20", 16, 20),
                ("grids 30-40", 30, 40))
BOX_BUCKETS = (("box packings 1k-4k", 1_000, 4_000), ("box packings 8k-16k", 8_000, 16_000))
# dense piles by bodies, circles and boxes alike (a box pile of N bodies has about 2.6 times the
# contacts of a circle pile of N)
PILE_BUCKETS = (("dense piles 1k", 1_000, 4_000), ("dense piles 10k", 8_000, 16_000))
# family -> (the start of its sets' names, its buckets)
SIZE_BUCKETS = {"grid": ("grids", GRID_BUCKETS), "box": ("box packings", BOX_BUCKETS),
                "pile": ("dense piles", PILE_BUCKETS)}
# the family of the impacts captured from a pile scene, and the pile's bodies in its name
PILE_FAMILY = re.compile(r"scene:(?:circle|box)_pile_(\d+)")
SETS = ("fork 5x5 grid dumps", "fork 7x7 grid scenes", "grid scene captures",
        *(name for name, _, _ in GRID_BUCKETS), *(name for name, _, _ in BOX_BUCKETS),
        *(name for name, _, _ in PILE_BUCKETS), *HARD_FAMILIES,
        *(f"frictional ({model})" for model in MODELS),
        *(f"Siconos granular ({model})" for model in MODELS),
        *(f"Siconos granular, reduced ({model})" for model in MODELS))


def set_of(problem: ImpactProblem | FrictionalProblem, formulation: str = "") -> str | None:
    """The head-to-head set a problem of ``problems/head_to_head.toml`` belongs to.

    A frictional problem's set is that of the model the pair's ``formulation`` solves
    (:func:`~qpbench.problem.friction.model_of`): ``frictional (coulomb)`` for staggered
    projections, the LCP, NSGS and Siconos' ``fc2d`` alike, ``frictional (ccp)`` for Anitescu's
    relaxation; for a granular flow imported from Siconos, ``Siconos granular (coulomb)`` or
    ``Siconos granular (ccp)``, and ``Siconos granular, reduced (coulomb)`` ... for one given
    reduced to the contacts (another Siconos problem: ``Siconos (coulomb)``, ...).
    A generated grid or box packing, and an impact of a dense pile (``PILE_FAMILY``: its size
    the pile's bodies), is in the set of its size's bucket (:func:`size_bucket`), a problem of
    a hard family in the set named by the family.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem; an impact problem's set is named by its family (and size).
    formulation : str, optional
        The pair's formulation, for a frictional problem; empty by default (the Coulomb
        set).

    Returns
    -------
    str or None
        One of SETS, or the own set of a grid or box size in no bucket; None for a problem
        of no set.
    """
    if isinstance(problem, FrictionalProblem):
        prefix = "frictional"
        if problem.family == SICONOS_FAMILY:
            prefix = "Siconos granular" if "granular" in problem.name else "Siconos"
            if isinstance(problem, ReducedFrictionalProblem):
                prefix += ", reduced"
        return f"{prefix} ({model_of(formulation)})"
    family = str(problem.family or "")
    if family == "dump":
        return "fork 5x5 grid dumps"
    if family.startswith("scene:grid7_"):
        return "fork 7x7 grid scenes"
    if family.startswith("scene:grid"):
        return "grid scene captures"
    pile = PILE_FAMILY.fullmatch(family)
    if pile is not None:
        return size_bucket("pile", int(pile.group(1)))
    if family in SIZE_BUCKETS:
        return size_bucket(family, problem.metadata.get("size"))
    if family in HARD_FAMILIES:
        return family
    return None


def size_bucket(family: str, size: int | None) -> str:
    """The set of a generated grid or box packing, or a dense pile, of ``size``: its bucket in
    SIZE_BUCKETS.

    Parameters
    ----------
    family : str
        ``grid``, ``box`` or ``pile``.
    size : int or None
        Balls per side (grid), balls (box) or bodies (pile), as the problem's metadata or the
        pile's name records it; None when it does not.

    Returns
    -------
    str
        The bucket's set name (``grids 10-14``); for a size in no bucket the family's sets'
        name and the size (``grids 25``), and that name alone when the size is None.
    """
    prefix, buckets = SIZE_BUCKETS[family]
    if size is None:
        return prefix
    for name, smallest, largest in buckets:
        if smallest <= int(size) <= largest:
            return name
    return f"{prefix} {size}"


def larger_buckets(set_name: str) -> list[str]:
    """The size buckets of ``set_name``'s family larger than it, smaller first.

    Parameters
    ----------
    set_name : str
        A set.

    Returns
    -------
    list of str
        Their set names; empty for a set that is no bucket or the largest one.
    """
    for _, buckets in SIZE_BUCKETS.values():
        names = [name for name, _, _ in buckets]
        if set_name in names:
            return names[names.index(set_name) + 1:]
    return []


def set_rank(problem: ImpactProblem | FrictionalProblem) -> int:
    """Where a problem's set comes in SETS, the order the problems are measured in.

    Smaller size buckets come first; a set not in SETS, and a frictional problem's, after them
    all.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem.

    Returns
    -------
    int
        The index of its set in SETS, or ``len(SETS)``.
    """
    name = set_of(problem)
    return SETS.index(name) if name in SETS else len(SETS)


def seed_ranges(seeds: Sequence[int]) -> str:
    """Seeds as runs of consecutive numbers: ``[5, 6, 7, 9]`` gives ``5-7, 9``.

    Parameters
    ----------
    seeds : sequence of int
        The seeds, in any order, repeats allowed.

    Returns
    -------
    str
        The runs, ascending, comma-separated.
    """
    runs: list[list[int]] = []
    for seed in sorted(set(seeds)):
        if runs and seed == runs[-1][1] + 1:
            runs[-1][1] = seed
        else:
            runs.append([seed, seed])
    return ", ".join(str(first) if first == last else f"{first}-{last}" for first, last in runs)


def generated_seeds(problems: Sequence[ImpactProblem | FrictionalProblem]
                    ) -> dict[str, list[int]]:
    """The seeds of the generated problems, per family, from the problems' metadata.

    Parameters
    ----------
    problems : sequence of ImpactProblem or FrictionalProblem
        The problems measured.

    Returns
    -------
    dict of str to list of int
        Family -> its problems' seeds, ascending, each once; dumps and captured scenes (no
        ``seed`` in their metadata) have none.
    """
    seeds: dict[str, set[int]] = {}
    for problem in problems:
        seed = problem.metadata.get("seed")
        if isinstance(seed, int) and not isinstance(seed, bool):
            seeds.setdefault(str(problem.family), set()).add(seed)
    return {family: sorted(numbers) for family, numbers in sorted(seeds.items())}
