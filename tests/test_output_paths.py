"""Output paths: qpbench writes regular files only, never replaces a device, a FIFO, a folder
or a symbolic link (unless asked to write through links), and a read-only or full disk is one
line and exit 2 with nothing half-written."""

from __future__ import annotations

import errno
import gc
import os
import shutil
import signal
import stat
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from bench_problems import write_tiny_problems

import qpbench.cli.export as export_command
from qpbench.atomic import FOLLOW_SYMLINKS_ENV
from qpbench.cli import main, os_error_line
from qpbench.cli.output import writable_output
from qpbench.errors import OutputError
from qpbench.problem import files
from qpbench.problem.generate import generate

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "problems" / "scenes" / "scisim" / "ball_ball_ccd_00.xml"  # impacts at once
DUMP = ROOT / "problems" / "dumps" / "grid5_itr_0.out"


@pytest.fixture(scope="module")
def problems(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("problems")
    write_tiny_problems(folder, count=1)
    return folder


def _commands(problems: Path, output: Path) -> dict[str, list[str]]:
    """One invocation per command that writes, each with ``output`` as what it writes."""
    return {
        "speed": ["speed", "--sizes", "10", "-o", str(output)],
        "export": ["export", str(problems), "-o", str(output)],
        "export-mat": ["export", str(problems), "--format", "mat", "-o", str(output)],
        "generate": ["generate", "k3", "--no-reference", "-o", str(output)],
        "import-dump": ["import-dump", str(DUMP), "--no-reference", "-o", str(output)],
        "run": ["run", str(problems), "--solvers", "osqp/dual", "--accuracy", "1e-4",
                "--no-progress", "-o", str(output)],
        "render": ["render", str(SCENE), "--steps", "3", "-o", str(output)],
        "simulate": ["simulate", str(SCENE), "--steps", "3", "--capture", str(output)],
        "scaling": ["scaling", "--sizes", "10,20", "--steps", "1", "--no-piles",
                    "-o", str(output)],
    }


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    """The one error line on stderr (beside any ``note:`` lines about the input)."""
    lines = [line for line in capsys.readouterr().err.splitlines() if ": note: " not in line]
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.parametrize("command", ["speed", "export", "export-mat", "generate",
                                     "import-dump", "run", "render", "simulate", "scaling"])
def test_a_fifo_is_never_an_output(command: str, problems: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "out.png"  # a name every command takes (render: .png or .gif)
    os.mkfifo(fifo)
    code = main(_commands(problems, fifo)[command])
    name = command.split("-mat")[0]
    assert code == 2
    assert _one_line(capsys) == (f"qpbench {name}: {fifo}: is a FIFO (named pipe), not a file "
                                 "qpbench can write")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and os.listdir(tmp_path) == ["out.png"]


@pytest.fixture
def character_device(tmp_path: Path) -> Path:
    """A character device node of our own in tmp_path (the null device's numbers), made only
    where this process may (as root); the test is skipped elsewhere."""
    device = tmp_path / "n.png"
    try:
        os.mknod(device, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    except OSError as error:
        pytest.skip(f"cannot create a device node here: {error}")
    return device


@pytest.mark.parametrize("command", ["speed", "export", "generate", "run"])
def test_a_character_device_output_stays_a_device(
        command: str, problems: Path, character_device: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    code = main(_commands(problems, character_device)[command])
    assert code == 2 and f"{character_device}: is a character device" in _one_line(capsys)
    assert stat.S_ISCHR(os.lstat(character_device).st_mode)
    assert os.listdir(character_device.parent) == ["n.png"]


def test_a_file_output_that_is_a_folder_is_refused_up_front(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=f"^{tmp_path}: is a folder, not a file"):
        writable_output(tmp_path)


@pytest.mark.parametrize("command", ["run", "render", "speed"])
def test_a_command_that_writes_a_file_refuses_a_folder_before_any_work(
        command: str, problems: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(_commands(problems, tmp_path)[command]) == 2
    assert _one_line(capsys) == f"qpbench {command}: {tmp_path}: is a folder, not a file " \
        "qpbench can write"
    assert list(tmp_path.iterdir()) == []


def test_an_output_symbolic_link_is_refused_unless_links_are_followed(
        problems: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    real = tmp_path / "real.parquet"
    real.write_text("old")
    link = tmp_path / "link.parquet"
    link.symlink_to(real)
    assert main(["export", str(problems), "-o", str(link)]) == 2
    line = _one_line(capsys)
    assert f"{link}: is a symbolic link (to {real})" in line and FOLLOW_SYMLINKS_ENV in line
    assert real.read_text() == "old"

    monkeypatch.setenv(FOLLOW_SYMLINKS_ENV, "1")
    assert main(["export", str(problems), "-o", str(link)]) == 0
    assert link.is_symlink() and real.read_bytes().startswith(b"PAR1")
    assert sorted(os.listdir(tmp_path)) == ["link.parquet", "real.parquet"]


def test_an_output_folder_may_be_a_symbolic_link_to_a_folder(
        problems: Path, tmp_path: Path) -> None:
    (tmp_path / "store").mkdir()
    (tmp_path / "mat").symlink_to(tmp_path / "store")
    assert main(["export", str(problems), "--format", "mat", "-o", str(tmp_path / "mat")]) == 0
    assert os.listdir(tmp_path / "store") == ["row3.mat"]


@pytest.fixture
def read_only_folder(tmp_path: Path) -> Iterator[Path]:
    """A folder mounted read-only (a bind mount of an empty folder, as root; skipped where
    mounting is not permitted). Root ignores permission bits, not a read-only mount."""
    source, mounted = tmp_path / "source", tmp_path / "read-only"
    source.mkdir()
    mounted.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a read-only bind mount needs root")
    bind = subprocess.run(["mount", "--bind", str(source), str(mounted)], capture_output=True)
    if bind.returncode:
        pytest.skip(f"mount --bind is not permitted here: {bind.stderr.decode().strip()}")
    try:
        remount = subprocess.run(["mount", "-o", "remount,bind,ro", str(mounted)],
                                 capture_output=True)
        if remount.returncode:
            pytest.skip(f"a read-only remount is not permitted: {remount.stderr.decode()}")
        yield mounted
    finally:
        subprocess.run(["umount", str(mounted)], check=True)


@pytest.mark.parametrize("command", ["export", "export-mat", "generate", "import-dump", "run",
                                     "render", "simulate", "scaling"])
def test_a_read_only_disk_is_one_line_and_exit_2(
        command: str, problems: Path, read_only_folder: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    output = read_only_folder / "out.png"
    code = main(_commands(problems, output)[command])
    line = _one_line(capsys)
    name = command.split("-mat")[0]
    assert code == 2
    assert line.startswith(f"qpbench {name}: {output}")
    assert line.endswith(": cannot write: Read-only file system")
    assert os.listdir(read_only_folder) == []


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC])
def test_a_disk_that_refuses_the_rename_leaves_no_temporary_file(
        code: int, problems: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def refuse(source: object, destination: object) -> None:
        raise OSError(code, os.strerror(code), str(destination))

    monkeypatch.setattr(os, "replace", refuse)
    output = tmp_path / "problems.parquet"
    assert main(["export", str(problems), "-o", str(output)]) == 2
    assert _one_line(capsys) == f"qpbench export: {output}: cannot write: {os.strerror(code)}"
    assert os.listdir(tmp_path) == []


def test_a_disk_that_fills_while_a_problem_is_written_leaves_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def fill(stream: object, **arrays: np.ndarray) -> None:
        stream.write(b"PK\x03\x04 half an archive")  # type: ignore[attr-defined]
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(np, "savez_compressed", fill)
    output = tmp_path / "k3"
    assert main(["generate", "k3", "--no-reference", "-o", str(output)]) == 2
    assert _one_line(capsys) == (f"qpbench generate: {output}/k3-3-s0.npz: cannot write: "
                                 "No space left on device")
    assert os.listdir(output) == []



def test_ctrl_c_while_a_problem_file_is_written_leaves_no_file_and_no_broken_archive(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGINT as NumPy opens a member of the archive: the write ends first, then the interrupt
    is raised, the temporary file goes, and the garbage collector finds no archive left with
    a member open (closing it later fails, after the interrupt's one line)."""
    reported: list[BaseException | None] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: reported.append(
        unraisable.exc_value))
    opened = zipfile.ZipFile.open

    def open_then_interrupt(self: zipfile.ZipFile, name: str, mode: str = "r",
                            **options: object) -> object:
        member = opened(self, name, mode, **options)  # type: ignore[arg-type]
        if mode == "w":
            os.kill(os.getpid(), signal.SIGINT)
        return member

    monkeypatch.setattr(zipfile.ZipFile, "open", open_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        files.save(generate("k3", None, seed=0)[0], tmp_path / "k3.npz")
    gc.collect()
    assert reported == [] and list(tmp_path.iterdir()) == []

def test_an_os_error_that_names_its_file_is_one_line_and_exit_2(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def refuse(*arguments: object) -> int:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(tmp_path / "x"))

    monkeypatch.setattr(export_command, "export", refuse)
    assert main(["export", str(tmp_path), "-o", str(tmp_path / "x")]) == 2
    assert _one_line(capsys) == f"qpbench export: {tmp_path / 'x'}: cannot write: " \
                                "Read-only file system"


def test_os_error_lines() -> None:
    assert os_error_line(OSError(errno.ENOSPC, "No space left on device", "a.json")) == \
        "a.json: cannot write: No space left on device"
    assert os_error_line(OSError(errno.ENOSPC, "No space left on device")) == \
        "cannot write: No space left on device"
    assert os_error_line(PermissionError(errno.EACCES, "Permission denied", "b")) == \
        "b: Permission denied"
    assert os_error_line(OSError(errno.EIO, "Input/output error")) is None  # internal
