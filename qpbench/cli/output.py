"""Helpers shared by the subcommands: JSON output of numpy values, output paths checked
before any work."""

from __future__ import annotations

import errno
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from qpbench import SINGLE_THREAD_ENV
from qpbench.atomic import atomic_path, checked_target
from qpbench.errors import OutputError


def to_jsonable(value: Any) -> Any:
    """numpy arrays and scalars as lists and floats; NaN and infinity as null."""
    if isinstance(value, dict):
        return {str(key): to_jsonable(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(item) for item in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, np.generic):
        return to_jsonable(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def plain(value: Any, missing: str = "none", seconds: bool = False) -> str:
    """``value`` for a command's text output, in words and plain numbers: ``missing`` for
    None and NaN, yes/no for a flag, a duration in a readable unit when ``seconds``, other
    floats to 3 significant digits, and a list or a mapping item by item (never a Python
    repr)."""
    if isinstance(value, np.generic | np.ndarray):
        value = value.tolist()
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return missing
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, dict):
        return "; ".join(f"{key} {plain(item)}" for key, item in value.items()) or missing
    if isinstance(value, list | tuple):
        return ", ".join(plain(item, seconds=seconds) for item in value) or missing
    if seconds and isinstance(value, int | float):
        return duration(float(value))
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def duration(seconds: float) -> str:
    """``seconds`` in a readable unit: ``12.3 us``, ``4.56 ms``, ``7.89 s``."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def print_json(value: Any) -> None:
    """One JSON object on stdout."""
    print(json.dumps(to_jsonable(value)))


def write_json(path: str | os.PathLike[str], value: Any) -> Path:
    """Writes ``value`` as indented JSON atomically (a temporary file renamed over ``path``;
    OutputError, one line, when ``path`` is not a regular file or cannot be written)."""
    text = json.dumps(to_jsonable(value), indent=2) + "\n"
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return Path(path)


def writable_output(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path, checked before any work so that a measurement never runs for an
    output it cannot write: OutputError when it is a folder, a device, a FIFO, a socket or a
    symbolic link that is not followed (:func:`qpbench.atomic.checked_target`), or when its
    nearest existing folder is not writable."""
    output = Path(path)
    target = checked_target(output)
    existing = next(parent for parent in target.parents if parent.exists())
    if not existing.is_dir():
        raise OutputError(output, f"cannot write: {existing} is not a folder")
    if not os.access(existing, os.W_OK):
        read_only = os.statvfs(existing).f_flag & os.ST_RDONLY
        reason = os.strerror(errno.EROFS if read_only else errno.EACCES)
        raise OutputError(output, f"cannot write: {reason}")
    return output


def single_threaded_rerun(arguments: list[str]) -> int | None:
    """Timings depend on BLAS threads: when this process is not single-threaded
    (SINGLE_THREAD_ENV), runs ``python -m qpbench.cli ARGUMENTS`` in a child that is and
    returns its exit status; None when this process already is."""
    if all(os.environ.get(name) == "1" for name in SINGLE_THREAD_ENV):
        return None
    command = [sys.executable, "-m", "qpbench.cli", *arguments]
    return subprocess.run(command, env={**os.environ, **SINGLE_THREAD_ENV},
                          check=False).returncode
