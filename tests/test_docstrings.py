"""Docstrings in numpydoc form, read from the source.

Every public function of qpbench/ (module level, or a method of a public class; its name and
its class's name without a leading underscore) is parsed with ast, nothing imported, and its
docstring held to numpydoc's sections (https://numpydoc.readthedocs.io/en/latest/format.html):
a summary line; a ``Parameters`` section when it takes parameters besides ``self`` and
``cls``; a ``Returns`` (or ``Yields``) section when its return annotation is not ``None``.
Properties, dunder methods and overloads say what they give in their summary line alone.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "qpbench"
MODULE_PATHS = sorted(path for path in PACKAGE.rglob("*.py") if "__pycache__" not in path.parts)
# decorators whose functions need no sections: the summary line says what they give
SUMMARY_ONLY = frozenset({"property", "cached_property", "overload", "setter"})


@dataclass(frozen=True)
class PublicFunction:
    """A public function or method and what its docstring must carry."""

    where: str
    docstring: str
    takes_parameters: bool
    returns_value: bool


def decorator_names(node: ast.FunctionDef) -> set[str]:
    """The last dotted part of each decorator's name (``functools.cached_property`` gives
    ``cached_property``, ``x.setter`` gives ``setter``)."""
    names = set()
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        if isinstance(target, ast.Attribute):
            names.add(target.attr)
        elif isinstance(target, ast.Name):
            names.add(target.id)
    return names


def returns_value(node: ast.FunctionDef) -> bool:
    """Whether the annotation says the function gives a value (anything but ``None``)."""
    annotation = node.returns
    if annotation is None:
        return any(isinstance(inner, ast.Return) and inner.value is not None
                   for inner in ast.walk(node))
    return not (isinstance(annotation, ast.Constant) and annotation.value is None)


def public_functions(path: Path) -> Iterator[PublicFunction]:
    """The public functions and public classes' public methods of one module."""
    tree = ast.parse(path.read_text())
    relative = path.relative_to(PACKAGE.parent)

    def visit(body: list[ast.stmt], owner: str) -> Iterator[PublicFunction]:
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                yield from visit(node.body, f"{owner}{node.name}.")
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            if node.name.startswith("_") or decorator_names(node) & SUMMARY_ONLY:
                continue
            arguments = node.args
            names = [argument.arg for argument in
                     arguments.posonlyargs + arguments.args + arguments.kwonlyargs]
            takes = bool([name for name in names if name not in ("self", "cls")]
                         or arguments.vararg or arguments.kwarg)
            yield PublicFunction(f"{relative}:{node.lineno} {owner}{node.name}",
                                 ast.get_docstring(node) or "", takes, returns_value(node))

    yield from visit(tree.body, "")


def missing_sections(function: PublicFunction) -> list[str]:
    """What a function's docstring lacks of numpydoc's form, empty when nothing."""
    lines = [line.strip() for line in function.docstring.splitlines()]
    missing = [] if lines and lines[0] else ["a summary line"]

    def has(section: str) -> bool:
        return any(line == section and below == "-" * len(section)
                   for line, below in zip(lines, lines[1:], strict=False))

    if function.takes_parameters and not has("Parameters"):
        missing.append("Parameters")
    if function.returns_value and not (has("Returns") or has("Yields")):
        missing.append("Returns")
    return missing


@pytest.mark.parametrize("path", MODULE_PATHS,
                         ids=[str(path.relative_to(PACKAGE.parent)) for path in MODULE_PATHS])
def test_public_functions_have_numpydoc_sections(path: Path) -> None:
    lacking = [f"{function.where}: no {', '.join(missing)}"
               for function in public_functions(path)
               if (missing := missing_sections(function))]
    assert not lacking, "\n".join(lacking)


def test_the_check_finds_a_missing_section() -> None:
    function = PublicFunction("example", "Add two numbers.", takes_parameters=True,
                              returns_value=True)
    assert missing_sections(function) == ["Parameters", "Returns"]
    documented = PublicFunction(
        "example", "Add two numbers.\n\nParameters\n----------\na, b : float\n    The numbers."
        "\n\nReturns\n-------\nfloat\n    Their sum.", takes_parameters=True, returns_value=True)
    assert missing_sections(documented) == []
