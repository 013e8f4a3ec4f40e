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
    """Convert a value to what ``json.dumps`` writes as standard JSON.

    numpy arrays and scalars become lists and Python numbers; NaN and infinity become null;
    dicts (keys as strings), lists and tuples are converted item by item.

    Parameters
    ----------
    value : Any
        The value to convert.

    Returns
    -------
    Any
        The value made of dicts, lists, strings, finite numbers, booleans and None.
    """
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
    """Format ``value`` for a command's text output, in words and plain numbers.

    ``missing`` for None and NaN, yes/no for a flag, a duration in a readable unit when
    ``seconds``, other floats to 3 significant digits, and a list or a mapping item by item
    (never a Python repr).

    Parameters
    ----------
    value : Any
        The value to show; numpy scalars and arrays are read as Python values.
    missing : str, optional
        The text for None, NaN and infinity, and for an empty list or mapping; ``none`` by
        default.
    seconds : bool, optional
        Whether a number (or a list's numbers) is a duration in seconds; False by default.

    Returns
    -------
    str
        The text.
    """
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
    """Format ``seconds`` in a readable unit: ``12.3 us``, ``4.56 ms``, ``7.89 s``.

    Parameters
    ----------
    seconds : float
        The duration in seconds.

    Returns
    -------
    str
        The duration to 3 significant digits, in us below 1 ms, in ms below 1 s, else in s.
    """
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def print_json(value: Any) -> None:
    """Print one JSON object on stdout.

    Parameters
    ----------
    value : Any
        The value to print, converted by :func:`to_jsonable`.
    """
    print(json.dumps(to_jsonable(value)))


def write_json(path: str | os.PathLike[str], value: Any) -> Path:
    """Write ``value`` as indented JSON atomically (a temporary file renamed over ``path``).

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file to write.
    value : Any
        The value to write, converted by :func:`to_jsonable`.

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    OutputError
        One line, when ``path`` is not a regular file or cannot be written.
    """
    text = json.dumps(to_jsonable(value), indent=2) + "\n"
    with atomic_path(path) as temporary:
        temporary.write_text(text)
    return Path(path)


def writable_output(path: str | os.PathLike[str]) -> Path:
    """Check an output path before any work, so that a measurement never runs for nothing.

    Parameters
    ----------
    path : str or os.PathLike
        The file the command is to write.

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    OutputError
        When ``path`` is a folder, a device, a FIFO, a socket or a symbolic link that is not
        followed (:func:`qpbench.atomic.checked_target`), or when its nearest existing folder is
        not a folder or not writable.
    """
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
    """Rerun the command in a single-threaded child when this process is not single-threaded.

    Timings depend on BLAS threads: when this process is not single-threaded
    (SINGLE_THREAD_ENV), runs ``python -m qpbench.cli ARGUMENTS`` in a child that is.

    Parameters
    ----------
    arguments : list of str
        The command's arguments after ``qpbench``.

    Returns
    -------
    int or None
        The child's exit status; None when this process already is single-threaded (the
        caller then measures itself).
    """
    if all(os.environ.get(name) == "1" for name in SINGLE_THREAD_ENV):
        return None
    command = [sys.executable, "-m", "qpbench.cli", *arguments]
    return subprocess.run(command, env={**os.environ, **SINGLE_THREAD_ENV},
                          check=False).returncode
