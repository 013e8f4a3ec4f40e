"""No module of the project is over MAX_LINES lines (the style of README's "Layout"): a module
that grows past it holds more than one concept and is split by concern."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 900
FOLDERS = ("qpbench", "tests", "docs/notes/scripts")


def modules() -> list[Path]:
    """Every Python file below the project's own FOLDERS."""
    return sorted(path for folder in FOLDERS for path in (ROOT / folder).rglob("*.py"))


def test_no_module_is_over_the_line_limit() -> None:
    found = modules()
    assert len(found) > 100 and ROOT / "qpbench/solvers/pi_robust.py" in found
    too_long = {str(path.relative_to(ROOT)): count for path in found
                if (count := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not too_long, too_long
