"""The package layering of README's "Layout" and docs/design.md section 3, read from the source.

Every module of qpbench/ is parsed (ast: nothing is imported or run) and each of its
``import qpbench...`` / ``from qpbench... import ...`` statements resolved to the module it
names. Then: each package imports only the packages below it in LAYERS; no module imports,
at module level, a module that imports it back (directly or around a loop); and imports inside
functions are few, each with a comment saying why it is not at module level.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "qpbench"

# the top-level modules every layer may use: the version and environment names, the one-line
# errors, atomic writes, memory guards, interrupt handling
BASE = "base"
BASE_MODULES = ("qpbench", "qpbench.errors", "qpbench.atomic", "qpbench.memory",
                "qpbench.interrupts")
# each layer and the layers it may import (its own modules it always may), lowest first
LAYERS: dict[str, frozenset[str]] = {
    BASE: frozenset(),
    "scenes": frozenset({BASE}),
    "problem": frozenset({BASE}),
    "simulation": frozenset({BASE, "scenes", "problem"}),
    "solvers": frozenset({BASE, "problem"}),
    "inner_solvers": frozenset({BASE, "scenes", "problem", "simulation", "solvers"}),
    "bench": frozenset({BASE, "scenes", "problem", "simulation", "solvers", "inner_solvers"}),
    "studies": frozenset({BASE, "scenes", "problem", "simulation", "solvers", "inner_solvers",
                          "bench"}),
    "cli": frozenset({BASE, "scenes", "problem", "simulation", "solvers", "inner_solvers",
                      "bench", "studies"}),
}
# imports inside functions, at most: each one waits for something (its comment says what)
MAX_FUNCTION_LOCAL = 10


@dataclass(frozen=True)
class Import:
    """One import of a qpbench module: who imports what, where, and whether inside a function."""

    source: str
    target: str
    line: int
    in_function: bool
    commented: bool


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))
           if "__pycache__" not in path.parts}


def layer(module: str) -> str:
    """The layer of a module: its package under qpbench, or BASE for the top-level modules."""
    if module in BASE_MODULES:
        return BASE
    return module.split(".")[1]


def _targets(source: str, node: ast.Import | ast.ImportFrom, is_package: bool) -> list[str]:
    """The qpbench modules an import statement names (``from P import M`` names P.M when M is a
    module, else P)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names if alias.name.split(".")[0] == "qpbench"]
    if node.level:
        base = source.split(".") if is_package else source.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        named = ".".join([*base, node.module] if node.module else base)
    else:
        named = node.module or ""
    if named.split(".")[0] != "qpbench":
        return []
    return [f"{named}.{alias.name}" if f"{named}.{alias.name}" in MODULES else named
            for alias in node.names]


def _commented(lines: list[str], node: ast.stmt) -> bool:
    """A comment on the import's own line or on the line right above it."""
    own = lines[node.lineno - 1]
    above = lines[node.lineno - 2].strip() if node.lineno > 1 else ""
    return "#" in own or above.startswith("#")


def imports() -> Iterator[Import]:
    """Every import of a qpbench module in qpbench/, in function bodies or not."""
    for source, path in MODULES.items():
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        is_package = path.name == "__init__.py"

        def visit(node: ast.AST, in_function: bool, source: str = source,
                  lines: list[str] = lines, is_package: bool = is_package) -> Iterator[Import]:
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.Import | ast.ImportFrom):
                    for target in _targets(source, child, is_package):
                        yield Import(source, target, child.lineno, in_function,
                                     _commented(lines, child))
                else:
                    yield from visit(child, in_function or isinstance(
                        child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda))

        yield from visit(ast.parse(text, filename=str(path)), False)


IMPORTS = list(imports())


def module_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph ``edges`` (modules in order, the first repeated at the end), or
    None: a depth-first search that meets a module still on its path."""
    state: dict[str, str] = {}
    path: list[str] = []

    def search(module: str) -> list[str] | None:
        state[module] = "on path"
        path.append(module)
        for target in sorted(edges.get(module, ())):
            if state.get(target) == "on path":
                return [*path[path.index(target):], target]
            if target not in state:
                found = search(target)
                if found:
                    return found
        path.pop()
        state[module] = "done"
        return None

    for module in sorted(edges):
        if module not in state:
            found = search(module)
            if found:
                return found
    return None


def test_the_source_is_read_every_module_and_its_imports() -> None:
    assert {"qpbench.bench.runner", "qpbench.studies.head_to_head", "qpbench.cli"} <= set(MODULES)
    assert any(one.source == "qpbench.studies.head_to_head"
               and one.target == "qpbench.solvers.registry" for one in IMPORTS)
    assert all(one.target in MODULES for one in IMPORTS), \
        sorted({one.target for one in IMPORTS} - set(MODULES))


def test_every_module_belongs_to_a_layer_of_the_table() -> None:
    assert sorted({layer(module) for module in MODULES} - set(LAYERS)) == []


def test_each_package_imports_only_the_layers_below_it() -> None:
    crossing = [f"{one.source} (line {one.line}) imports {one.target}" for one in IMPORTS
                if layer(one.target) != layer(one.source)
                and layer(one.target) not in LAYERS[layer(one.source)]]
    assert crossing == []


def test_the_layers_table_runs_one_way() -> None:
    """No layer may import one that may import it back: the table is an order."""
    edges = {name: set(allowed) for name, allowed in LAYERS.items()}
    assert module_cycle(edges) is None


def test_no_module_imports_one_that_imports_it_back() -> None:
    edges: dict[str, set[str]] = {}
    for one in IMPORTS:
        if not one.in_function and one.target != one.source:
            edges.setdefault(one.source, set()).add(one.target)
    assert module_cycle(edges) is None


def test_the_cycle_search_finds_a_cycle_around_a_loop() -> None:
    assert module_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert module_cycle({"a": {"b", "c"}, "b": {"c"}}) is None


def test_function_local_imports_are_few_and_each_says_why() -> None:
    local = [one for one in IMPORTS if one.in_function]
    assert len({(one.source, one.line) for one in local}) <= MAX_FUNCTION_LOCAL
    assert [f"{one.source} line {one.line}" for one in local if not one.commented] == []


def test_design_names_every_module() -> None:
    """docs/design.md's table of folders and modules (section 3) names every module file, so
    that a newcomer finds each concept's place from the design."""
    design = (PACKAGE.parent / "docs" / "design.md").read_text()
    table = "\n".join(line for line in design.splitlines() if line.startswith("| `qpbench"))
    unnamed = [str(path.relative_to(PACKAGE.parent)) for path in MODULES.values()
               if path.name not in ("__init__.py", "__main__.py")
               and f"`{path.name}`" not in table
               and f"`{path.relative_to(PACKAGE.parent)}`" not in table]
    assert not unnamed, f"modules docs/design.md's table does not name: {unnamed}"
