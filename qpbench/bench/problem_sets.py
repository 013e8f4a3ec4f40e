"""Problem sets: a TOML file naming families, dumps, scenes and piles, built into problem files.

```toml
[families]                       # family -> sizes (default: the family's) and seeds per size
grid = { sizes = [3, 5], count = 2, seed = 0 }   # seeds 0 and 1 (plus build's seed_offset)
box = { sizes = [1000, 4000], count = [3, 1] }   # a count per size: 3 of 1000 balls, 1 of 4000
incline = { count = 2 }          # frictional families (qpbench.problem.friction_generate) too

[dumps]
paths = ["dumps/*"]              # globs, relative to the set file

[siconos]
paths = ["../../shared/siconos/fc2d/*.dat"]   # Siconos' fc2d, gfc2d and lcp text files
                                 # (qpbench.problem.siconos_import; a general LCP is skipped)
[fclib]
paths = ["fclib/*.hdf5"]         # FCLIB HDF5 files, 2D (qpbench.problem.fclib)

[[scenes]]                       # simulate, capture every impact, keep at most max_problems
path = "scenes/scisim/newtons_cradle.xml"   # or a glob: each scene it matches, alike
steps = 2000                     # step cap (default: the scene's end time)
solver = "clarabel"              # inner solver of the simulation (default: the scene's)
max_problems = 5                 # evenly spread over the captured impacts

[[piles]]                        # a dense pile of `qpbench scaling` (qpbench.simulation.scaling),
kind = "boxes"                   # "circles" or "boxes"
bodies = 10000                   # made here rather than read from a scene file
steps = 1                        # step cap (default 1); solver and max_problems as for scenes
```

Before anything is written, every family size and every scene is checked against the memory
available (qpbench.memory: a family's balls, a scene's bodies), and a size that cannot fit is
refused in one line. Families are made one problem at a time, so memory holds one problem
whatever ``count``; scenes are captured into a ``.tmp-capture-*`` folder inside the output
folder, removed when the scene is done.

Every problem file gets a reference: a verified one from two methods that agree
(qpbench.problem.reference), or for a frictional problem one polished to a Coulomb residual of
1e-12 with its uniqueness and solvability (qpbench.problem.friction_reference). Building is
incremental: a problem whose file exists is not made again. Building runs the simulator
(scenes) and the solvers (inner solves, references), so it lives above both, in bench.
"""

from __future__ import annotations

import glob
import math
import sys
import tempfile
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from qpbench.atomic import TEMPORARY_PREFIX
from qpbench.bench import reduced_reference
from qpbench.errors import InputError, QpbenchError, UnsupportedError
from qpbench.inner_solvers import choose_by_name
from qpbench.memory import OutOfMemory, out_of_memory, require
from qpbench.problem import fclib, files, friction_reference
from qpbench.problem.dumps import import_dump
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.friction_generate import FRICTION_FAMILIES
from qpbench.problem.friction_generate import generate as generate_frictional
from qpbench.problem.generate import FAMILIES, check_family_size, family_entry, generate
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import ReducedFrictionalProblem
from qpbench.problem.reference import attach_reference
from qpbench.problem.siconos_import import import_siconos
from qpbench.scenes import Scene, load_scene
from qpbench.simulation.scaling import PILES
from qpbench.simulation.stepper import BODY_BYTES, Simulator
from qpbench.solvers.registry import resolve

ALL_FAMILIES = (*FAMILIES, *FRICTION_FAMILIES)


def read_set(path: str | Path) -> dict[str, Any]:
    """Read and check a set file.

    Every section and key is checked against what a set file may hold (module docstring), so
    a misspelt key is refused rather than ignored.

    Parameters
    ----------
    path : str or pathlib.Path
        The TOML set file.

    Returns
    -------
    dict of str to Any
        The parsed set file.

    Raises
    ------
    InputError
        Naming the file and the entry at fault: a missing or unreadable file, malformed TOML,
        an unknown section, family or key, or a value of the wrong type.
    """
    path = Path(path)
    try:
        definition = tomllib.loads(path.read_text())
    except FileNotFoundError as error:
        raise InputError(str(path), "no such set file") from error
    except (OSError, UnicodeDecodeError) as error:  # a folder, a binary file
        raise InputError(str(path), f"cannot read set file ({error})") from error
    except tomllib.TOMLDecodeError as error:
        raise InputError(str(path), f"malformed TOML: {error}") from error
    except RecursionError as error:  # tomllib's own limit on nested arrays and tables
        raise InputError(str(path), "malformed TOML: arrays or tables nested too deeply") \
            from error
    _check_entries(path, definition, "set", _SECTIONS)
    for family, options in definition.get("families", {}).items():
        if family not in ALL_FAMILIES:
            raise InputError(str(path), f"unknown family (known: {', '.join(ALL_FAMILIES)})",
                             "families", family)
        if not isinstance(options, dict):
            raise InputError(str(path), "must be a table such as { count = 2 }", "families",
                             family)
        _check_entries(path, options, f"families.{family}", _FAMILY_KEYS)
        if isinstance(options.get("count"), list) and \
                len(options["count"]) != len(options.get("sizes", ())):
            raise InputError(str(path), "a list of counts needs one count per size in sizes",
                             f"families.{family}", "count")
    for section in ("dumps", "siconos", "fclib"):
        _check_entries(path, definition.get(section, {}), section, _DUMPS_KEYS)
    for section, required, keys in (("scenes", ("path",), _SCENE_KEYS),
                                    ("piles", ("kind", "bodies"), _PILE_KEYS)):
        for index, entry in enumerate(definition.get(section, [])):
            if not isinstance(entry, dict):
                raise InputError(str(path), f"must be a table ([[{section}]])",
                                 f"{section}[{index}]")
            for key in required:
                if key not in entry:
                    raise InputError(str(path), "missing", f"{section}[{index}]", key)
            _check_entries(path, entry, f"{section}[{index}]", keys)
    return definition


def _is_integer(value: Any, minimum: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= minimum


# what each key of a set file must be: (as the message says it, the test)
_Rule = tuple[str, Callable[[Any], bool]]
_SECTIONS: dict[str, _Rule] = {
    "families": ("a table of families", lambda value: isinstance(value, dict)),
    "dumps": ("a table with paths", lambda value: isinstance(value, dict)),
    "siconos": ("a table with paths", lambda value: isinstance(value, dict)),
    "fclib": ("a table with paths", lambda value: isinstance(value, dict)),
    "scenes": ("an array of tables ([[scenes]])", lambda value: isinstance(value, list)),
    "piles": ("an array of tables ([[piles]])", lambda value: isinstance(value, list)),
}
_FAMILY_KEYS: dict[str, _Rule] = {
    "sizes": ("a list of integers >= 1", lambda value: isinstance(value, list) and bool(value)
              and all(_is_integer(size, 1) for size in value)),
    "count": ("an integer >= 1, or a list of them (one per size)",
              lambda value: _is_integer(value, 1) or isinstance(value, list) and bool(value)
              and all(_is_integer(count, 1) for count in value)),
    "seed": ("an integer >= 0", lambda value: _is_integer(value, 0)),
}
_DUMPS_KEYS: dict[str, _Rule] = {
    "paths": ("a list of globs", lambda value: isinstance(value, list)
              and all(isinstance(pattern, str) for pattern in value)),
}
_SCENE_KEYS: dict[str, _Rule] = {
    "path": ("a path or glob", lambda value: isinstance(value, str)),
    "steps": ("an integer >= 0", lambda value: _is_integer(value, 0)),
    "end_time": ("a number >= 0", lambda value: isinstance(value, int | float)
                 and not isinstance(value, bool) and 0 <= value < math.inf),
    "solver": ("a solver name", lambda value: isinstance(value, str)),
    "max_problems": ("an integer >= 1", lambda value: _is_integer(value, 1)),
}
_PILE_KEYS: dict[str, _Rule] = {
    "kind": (f"one of {', '.join(PILES)}", lambda value: value in PILES),
    "bodies": ("an integer >= 1", lambda value: _is_integer(value, 1)),
    "steps": _SCENE_KEYS["steps"],
    "solver": _SCENE_KEYS["solver"],
    "max_problems": _SCENE_KEYS["max_problems"],
}
PILE_STEPS = 1  # a [[piles]] entry's step cap when it names none


def _check_entries(path: Path, table: dict[str, Any], element: str,
                   rules: dict[str, _Rule]) -> None:
    """InputError naming the file, ``element`` and the key: a key ``rules`` does not know (a
    misspelt key would otherwise be ignored) or a value that breaks its rule."""
    for key, value in table.items():
        if key not in rules:
            raise InputError(str(path), f"unknown key (known: {', '.join(rules)})", element,
                             key)
        what, test = rules[key]
        if not test(value):
            raise InputError(str(path), f"must be {what}, got {value!r}"[:200], element, key)


def _family_problems(definition: dict[str, Any], existing: set[str], seed_offset: int = 0
                     ) -> Iterator[ImpactProblem | FrictionalProblem]:
    """The problems of the ``families`` section not in ``existing``: per family and size,
    ``count`` problems (that size's entry when ``count`` is a list) from seed
    ``seed + seed_offset`` on."""
    for family, options in definition.get("families", {}).items():
        sizes = options.get("sizes", [None])
        count = options.get("count", 1)
        counts = count if isinstance(count, list) else [count] * len(sizes)
        make = generate_frictional if family in FRICTION_FAMILIES else generate
        first = options.get("seed", 0) + seed_offset
        for size, problems in zip(sizes, counts, strict=True):
            # one problem at a time: make(seed=s + i, count=1) is make(seed=s, count=n)[i]
            for seed in range(first, first + problems):
                [problem] = make(family, size=size, seed=seed, count=1)
                if problem.name not in existing:
                    yield problem


def check_sizes(definition: dict[str, Any], scenes: list[tuple[dict[str, Any], Scene]],
                set_file: Path) -> None:
    """Check, before anything is built, that every family size and scene fits in memory.

    Parameters
    ----------
    definition : dict of str to Any
        The parsed set file (:func:`read_set`).
    scenes : list of tuple of (dict, Scene)
        Each ``[[scenes]]`` entry and a scene it names, read.
    set_file : pathlib.Path
        The set file, named in the error.

    Raises
    ------
    OutOfMemory
        One line naming the set file, the entry and its size, when one problem of a family
        size, or the state of a scene, needs more than the memory available.
    """
    for family, options in definition.get("families", {}).items():
        table = FRICTION_FAMILIES if family in FRICTION_FAMILIES else FAMILIES
        for size in options.get("sizes", [None]):
            _, size = family_entry(table, family, size)
            try:
                check_family_size(family, size)
            except OutOfMemory as error:
                raise OutOfMemory(f"{set_file}: <families> '{family}': {error}") from None
    for _, scene in scenes:
        require(scene.bodies.count * BODY_BYTES, f"{scene.path}: {scene.bodies.count} bodies")


def _dump_problems(definition: dict[str, Any], root: Path, existing: set[str]
                   ) -> Iterator[ImpactProblem]:
    for pattern in definition.get("dumps", {}).get("paths", []):
        for path in sorted(glob.glob(str(root / pattern))):
            if Path(path).stem not in existing:
                yield import_dump(path)


def _imported_problems(definition: dict[str, Any], root: Path, existing: set[str]
                       ) -> Iterator[ImpactProblem | FrictionalProblem]:
    """The problems of the ``siconos`` and ``fclib`` sections' files; a general LCP is skipped
    with one line (qpbench has no kind for it)."""
    for section, read in (("siconos", import_siconos), ("fclib", fclib.read)):
        for pattern in definition.get(section, {}).get("paths", []):
            for path in sorted(glob.glob(str(root / pattern))):
                if Path(path).stem in existing:
                    continue
                try:
                    yield read(path)
                except UnsupportedError as refused:
                    print(f"qpbench build-set: skipped: {refused}", file=sys.stderr)


def _scene_paths(root: Path, entry: dict[str, Any], index: int) -> list[Path]:
    """The scene files of one ``[[scenes]]`` entry: its path, or every file its glob matches
    (sorted); InputError for a glob that matches none."""
    pattern = str(root / entry["path"])
    if not any(character in pattern for character in "*?["):
        return [Path(pattern)]
    paths = sorted(glob.glob(pattern))
    if not paths:
        raise InputError(pattern, "matches no scene file", f"scenes[{index}]", "path")
    return [Path(path) for path in paths]


def _scenes(definition: dict[str, Any], set_file: Path) -> list[tuple[dict[str, Any], Scene]]:
    """(entry, scene) of every scene the ``[[scenes]]`` entries name, each read, then of every
    ``[[piles]]`` entry, its pile made once its bodies fit in memory (its step cap
    ``PILE_STEPS`` unless it names one); each inner solver's name is looked up, so that a bad
    scene or solver stops the build before anything is written."""
    scenes = []
    for section in ("scenes", "piles"):
        for entry in definition.get(section, []):
            if "solver" in entry:
                resolve([entry["solver"]])  # an unknown name is one line here, before output
    for index, entry in enumerate(definition.get("scenes", [])):
        scenes += [(entry, load_scene(path))
                   for path in _scene_paths(set_file.parent, entry, index)]
    for index, entry in enumerate(definition.get("piles", [])):
        # (checked before the pile is made: its bodies are allocated at once)
        require(entry["bodies"] * BODY_BYTES,
                f"{set_file}: piles[{index}]: {entry['bodies']} bodies")
        scenes.append(({"steps": PILE_STEPS, **entry},
                       PILES[entry["kind"]](entry["bodies"])))
    return scenes


def _scene_problems(scenes: list[tuple[dict[str, Any], Scene]], existing: set[str],
                    output: Path) -> Iterator[ImpactProblem]:
    for entry, scene in scenes:
        with tempfile.TemporaryDirectory(dir=output,
                                         prefix=f"{TEMPORARY_PREFIX}capture-") as capture:
            simulator = Simulator(scene, choose_by_name(entry.get("solver")), capture=capture)
            result = simulator.run(end_time=entry.get("end_time"),
                                   max_steps=entry.get("steps"))
            failure = result.failure
            if failure is not None and "MemoryError" in str(failure.get("solver_status", "")):
                raise out_of_memory(f"simulating {scene.path}",
                                    f"the inner solve of step {failure['step']}")
            captured = files.find([capture])
            keep = entry.get("max_problems", len(captured))
            if captured and keep < len(captured):
                picks = np.unique(np.linspace(0, len(captured) - 1, keep).round().astype(int))
                captured = [captured[i] for i in picks]
            for path in captured:
                problem = files.load(path)
                if problem.name not in existing and problem.n_contacts > 0:
                    yield problem


def build(set_file: str | Path, output: str | Path,
          on_problem: Callable[[str], None] | None = None, seed_offset: int = 0) -> list[Path]:
    """Write every problem of the set to ``output``, skipping those already there.

    Families, dumps, Siconos and FCLIB files, then scenes and piles, each problem with its
    reference (module docstring); a reference that is not verified is said in one line on
    stderr.
    ``seed_offset`` is added to every family's seeds (problem i of a family size gets seed
    ``seed + seed_offset + i``), so that one set file gives problems never seen before.

    Parameters
    ----------
    set_file : str or pathlib.Path
        The TOML set file; the globs in it are relative to its folder.
    output : str or pathlib.Path
        The folder of problem files, created when missing.
    on_problem : callable, optional
        Called with each problem's name after its file is written; None calls nothing.
    seed_offset : int, optional
        Added to every family's seeds; 0 (default) builds the seeds the set file names.

    Returns
    -------
    list of pathlib.Path
        The problem files written, in the order written.

    Raises
    ------
    QpbenchError
        On a bad set file or scene (InputError), an unknown inner solver, a problem or
        scene too large for the memory available (OutOfMemory), or a negative
        ``seed_offset``.
    """
    if seed_offset < 0:
        raise QpbenchError(f"the seed offset must be at least 0, got {seed_offset}")
    set_file, output = Path(set_file), Path(output)
    definition = read_set(set_file)
    root = set_file.parent
    scenes = _scenes(definition, set_file)
    check_sizes(definition, scenes, set_file)
    output.mkdir(parents=True, exist_ok=True)
    existing = {path.stem for path in output.glob(f"*{files.SUFFIX}")}
    written = []
    sources = (
        _family_problems(definition, existing, seed_offset),
        _dump_problems(definition, root, existing),
        _imported_problems(definition, root, existing),
        _scene_problems(scenes, existing, output),
    )
    for source in sources:
        for problem in source:
            if isinstance(problem, FrictionalProblem):
                if isinstance(problem, ReducedFrictionalProblem):
                    reduced_reference.attach(problem)
                else:
                    friction_reference.attach_reference(problem)
                note = friction_reference.describe(problem.reference)
                if note:
                    print(f"qpbench build-set: {problem.name}: {note}", file=sys.stderr)
                written.append(files.save(problem, output / problem.name))
                existing.add(problem.name)
                if on_problem is not None:
                    on_problem(problem.name)
                continue
            attach_reference(problem)
            if not problem.reference.verified:
                print(f"qpbench build-set: {problem.name}: references disagree "
                      f"({problem.reference.agreement:.1e}); v_error will not be computed",
                      file=sys.stderr)
            written.append(files.save(problem, output / problem.name))
            existing.add(problem.name)
            if on_problem is not None:
                on_problem(problem.name)
    return written
