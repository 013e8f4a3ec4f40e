"""Atomic output: a file appears whole, with a new file's mode, or not at all."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from qpbench.atomic import atomic_path


def test_a_finished_write_replaces_the_target_with_a_new_files_mode(tmp_path: Path) -> None:
    target = tmp_path / "out" / "result.json"
    with atomic_path(target) as temporary:
        assert temporary.parent == target.parent and temporary.suffix == ".json"
        temporary.write_text("{}")
        assert not target.exists()  # nothing visible until the block ends
    umask = os.umask(0)
    os.umask(umask)
    assert target.read_text() == "{}"
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask
    assert [p.name for p in target.parent.iterdir()] == ["result.json"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "result.json"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]
