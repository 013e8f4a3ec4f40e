"""A file that is not a valid problem archive (.npz) is one line naming the file and what is
wrong, exit 2: never a traceback, never a hint to load it with pickle."""

from __future__ import annotations

import os
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from bench_problems import write_tiny_problems

from qpbench.cli import main
from qpbench.errors import InputError
from qpbench.problem import files


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """The bytes of a valid problem file."""
    (path,) = write_tiny_problems(tmp_path_factory.mktemp("good"), count=1)
    return path.read_bytes()


def _renamed_npy(path: Path, good: bytes) -> None:
    with open(path, "wb") as stream:
        np.save(stream, np.arange(3.0))


def _random_bytes(path: Path, good: bytes) -> None:
    path.write_bytes(np.random.default_rng(0).bytes(300))


def _truncated(path: Path, good: bytes) -> None:
    path.write_bytes(good[:len(good) // 2])


def _object_array(path: Path, good: bytes) -> None:
    np.savez(path, header_json=np.array([{"name": "x"}, 1], dtype=object))


def _member_not_an_array(path: Path, good: bytes) -> None:
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("header_json.npy", b"hello")


def _damaged_data(path: Path, good: bytes) -> None:
    damaged = bytearray(good)
    for index in range(200, 260):  # inside the first member's compressed data
        damaged[index] ^= 0xFF
    path.write_bytes(bytes(damaged))


def _huge_declared_shape(path: Path, good: bytes) -> None:
    """A member whose .npy header declares 2^40 doubles over a few bytes of data."""
    header = {"descr": "<f8", "fortran_order": False, "shape": (2**40,)}
    with (zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive,
          archive.open("header_json.npy", "w") as stream):
        np.lib.format.write_array_header_1_0(stream, header)
        stream.write(b"\0" * 64)


def _line_break_in_a_member_name(path: Path, good: bytes) -> None:
    """The central directory names m_inv's member 'm_i<line break>v.npy', its local header
    'm_inv.npy': the name and zipfile's message quote the line break."""
    damaged = bytearray(good)
    damaged[good.rfind(b"m_inv.npy") + 3] = ord("\n")
    path.write_bytes(bytes(damaged))


CASES = [
    (_renamed_npy, "a single NumPy array (.npy), not a problem file"),
    (_random_bytes, "not a problem file: not a .npz (zip) archive"),
    (_truncated, "a damaged or truncated .npz archive"),
    (_object_array, "attribute 'header_json': holds Python objects"),
    (_member_not_an_array, "attribute 'header_json': not a readable .npy array"),
    (_damaged_data, "not a readable .npy array"),
    (_huge_declared_shape, "attribute 'header_json': declares a 1099511627776 array of "
                           "float64 (8796093022208 bytes) but holds at most 64"),
    (_line_break_in_a_member_name, "not a readable .npy array"),
]


@pytest.mark.parametrize(("write", "message"), CASES, ids=[case.__name__ for case, _ in CASES])
def test_a_bad_archive_is_one_line_naming_the_file(
        write, message: str, good: bytes, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.npz"
    write(path, good)
    with pytest.raises(InputError, match=re.escape(message)):
        files.load(path)
    assert main(["solve", str(path), "--solver", "osqp"]) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"qpbench solve: {path}") and error.count("\n") == 1
    assert message in error and "pickle" not in error
    assert error.rstrip("\n").isprintable() and len(error) <= len(str(path)) + 900


def test_an_empty_file_and_a_folder_are_named_as_such(tmp_path: Path) -> None:
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(InputError, match="empty.npz: not a problem file"):
        files.load(tmp_path / "empty.npz")
    with pytest.raises(InputError, match="is a folder, not a problem file"):
        files.load(tmp_path)
    os.mkdir(tmp_path / "folder.npz")
    with pytest.raises(InputError, match="folder.npz: is a folder"):
        files.load(tmp_path / "folder.npz")
