"""Atomic output: a file appears whole, with a new file's mode, or not at all."""

from __future__ import annotations

import errno
import os
import re
import stat
from pathlib import Path

import pytest

from qpbench.atomic import FOLLOW_SYMLINKS_ENV, atomic_path
from qpbench.errors import OutputError


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


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".tmp-"))


def test_a_fifo_a_folder_and_a_symbolic_link_are_refused_before_anything_is_written(
        tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "folder").mkdir()
    (tmp_path / "real.json").write_text("old")
    (tmp_path / "link.json").symlink_to("real.json")
    for name, what in (("pipe", "is a FIFO"), ("folder", "is a folder"),
                       ("link.json", "is a symbolic link (to real.json)")):
        refused = pytest.raises(OutputError, match=f"^{tmp_path / name}: {re.escape(what)}")
        with refused, atomic_path(tmp_path / name) as temporary:
            temporary.write_text("never")
    assert stat.S_ISFIFO(os.lstat(tmp_path / "pipe").st_mode)
    assert (tmp_path / "link.json").is_symlink() and (tmp_path / "real.json").read_text() == "old"
    assert _leftovers(tmp_path) == []


def test_a_character_device_is_refused_and_left_as_it_is(tmp_path: Path) -> None:
    device = tmp_path / "device"
    try:  # the null device's numbers, on a node of our own in tmp_path
        os.mknod(device, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    except (PermissionError, OSError) as error:
        pytest.skip(f"cannot create a device node here: {error}")
    refused = pytest.raises(OutputError, match="is a character device, not a file qpbench can")
    with refused, atomic_path(device):
        pass
    assert stat.S_ISCHR(os.lstat(device).st_mode)
    assert _leftovers(tmp_path) == []


def test_a_symbolic_link_is_written_through_when_asked_and_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "real.json").write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "data" / "real.json")
    monkeypatch.setenv(FOLLOW_SYMLINKS_ENV, "1")
    with atomic_path(link) as temporary:
        assert temporary.parent == tmp_path / "data"  # beside the file it replaces
        temporary.write_text("new")
    assert link.is_symlink() and (tmp_path / "data" / "real.json").read_text() == "new"


def test_a_followed_link_to_a_device_is_still_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "link").symlink_to("pipe")
    monkeypatch.setenv(FOLLOW_SYMLINKS_ENV, "1")
    refused = pytest.raises(OutputError, match="is a symbolic link to .*pipe, which is a FIFO")
    with refused, atomic_path(tmp_path / "link"):
        pass


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC])
def test_a_disk_that_refuses_the_rename_is_one_error_and_leaves_the_old_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, code: int) -> None:
    target = tmp_path / "result.json"
    target.write_text("old")

    def refuse(source: object, destination: object) -> None:
        raise OSError(code, os.strerror(code), str(destination))

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OutputError) as raised, atomic_path(target) as temporary:
        temporary.write_text("new")
    assert str(raised.value) == f"{target}: cannot write: {os.strerror(code)}"
    assert target.read_text() == "old" and _leftovers(tmp_path) == []


def test_a_disk_that_fills_while_writing_is_one_error_and_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "new" / "result.json"
    refused = pytest.raises(OutputError, match="result.json: cannot write: No space left on")
    with refused, atomic_path(target) as temporary:
        temporary.write_text("half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert not target.exists() and _leftovers(target.parent) == []


def test_ctrl_c_the_moment_the_temporary_file_is_made_leaves_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "result.npz"
    target.write_text("old")
    make = os.open

    def make_then_interrupt(path: str | os.PathLike[str], flags: int, mode: int = 0o777) -> int:
        descriptor = make(path, flags, mode)
        if Path(path).name.startswith(".tmp-"):  # SIGINT lands as the file comes to exist
            os.close(descriptor)
            raise KeyboardInterrupt
        return descriptor

    monkeypatch.setattr(os, "open", make_then_interrupt)
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as temporary:
        temporary.write_text("new")
    assert target.read_text() == "old" and _leftovers(tmp_path) == []


def test_a_temporary_name_another_file_has_is_passed_over(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "result.json"
    taken = tmp_path / f".tmp-{'0' * 16}-result.json"
    taken.write_text("another writer's")
    names = iter(["0" * 16, "1" * 16])
    monkeypatch.setattr("qpbench.atomic.secrets.token_hex", lambda _: next(names))
    with atomic_path(target) as temporary:
        assert temporary.name == f".tmp-{'1' * 16}-result.json"
        temporary.write_text("{}")
    assert target.read_text() == "{}" and taken.read_text() == "another writer's"
