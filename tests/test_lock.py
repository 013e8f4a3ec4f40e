"""Every package version is locked: requirements.lock pins each dependency with hashes, the
environment the tests run in is exactly the lock, and rows name the lock by its hash."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from qpbench.bench import lock

ROOT = Path(__file__).resolve().parents[1]


def _declared() -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    names = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        names.extend(extra)
    return {re.sub(r"[-_.]+", "-", re.split(r"[<>=!~ \[;]", name, maxsplit=1)[0]).lower()
            for name in names}


def test_the_lock_pins_every_declared_dependency_with_hashes() -> None:
    text = lock.LOCK_FILE.read_text(encoding="utf-8")
    pinned = lock.pinned_versions()
    assert _declared() <= set(pinned), sorted(_declared() - set(pinned))
    blocks = re.split(r"\n(?=[a-z0-9])", text.split("\n", 1)[1].strip())
    for block in blocks:
        if block.startswith("#") or not block.strip():
            continue
        assert "--hash=sha256:" in block, block.splitlines()[0]


def test_this_environment_is_exactly_the_lock() -> None:
    assert lock.deviations() == []
    assert lock.lock_label() == lock.lock_hash()


def test_the_hash_names_the_file_content(tmp_path: Path) -> None:
    first = tmp_path / "a.lock"
    first.write_text("numpy==2.0.0 \\\n    --hash=sha256:00\n", encoding="utf-8")
    before = lock.lock_hash(first)
    assert len(before) == 16 and lock.pinned_versions(first) == {"numpy": "2.0.0"}
    first.write_text("numpy==2.0.1 \\\n    --hash=sha256:00\n", encoding="utf-8")
    assert lock.lock_hash(first) != before
    assert lock.lock_hash(tmp_path / "missing.lock") == "no-lock"
