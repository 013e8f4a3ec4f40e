"""The lock file that fixes every package version (``requirements.lock``), and its hash.

Every results row carries :func:`lock_label` as ``lock_hash``, so a table says which exact
set of packages produced it, and a run refuses to resume a table made with another set.
"""

from __future__ import annotations

import hashlib
import re
from functools import cache
from importlib import metadata
from pathlib import Path

LOCK_FILE = Path(__file__).resolve().parents[2] / "requirements.lock"
_PIN = re.compile(r"^([A-Za-z0-9_.\-]+)==([^\s;\\]+)")


def lock_hash(path: Path = LOCK_FILE) -> str:
    """Hash the lock file: the first 16 hex digits of its SHA-256.

    Parameters
    ----------
    path : pathlib.Path, optional
        The lock file; ``requirements.lock`` of the repository by default.

    Returns
    -------
    str
        The hash, or ``no-lock`` when the file cannot be read.
    """
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    except OSError:
        return "no-lock"


def pinned_versions(path: Path = LOCK_FILE) -> dict[str, str]:
    """Read the version the lock pins for each package.

    Parameters
    ----------
    path : pathlib.Path, optional
        The lock file; ``requirements.lock`` of the repository by default.

    Returns
    -------
    dict of str to str
        package name (normalized) -> the version the lock pins; empty without a lock file.
    """
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        return {}
    pins = (_PIN.match(line) for line in lines)
    return {_normalized(pin[1]): pin[2] for pin in pins if pin}


def deviations(path: Path = LOCK_FILE) -> list[str]:
    """List the locked packages installed at another version (or missing) in this environment.

    Parameters
    ----------
    path : pathlib.Path, optional
        The lock file; ``requirements.lock`` of the repository by default.

    Returns
    -------
    list of str
        ``name installed!=locked`` per deviating package, sorted by name.
    """
    found = []
    for name, locked in sorted(pinned_versions(path).items()):
        try:
            installed = metadata.version(name)
        except metadata.PackageNotFoundError:
            installed = "missing"
        if installed != locked:
            found.append(f"{name} {installed}!={locked}")
    return found


@cache
def lock_label() -> str:
    """Label this environment's package set: the lock's hash, marked when the venv differs.

    The hash is followed by ``+venv-differs(...)`` when the installed versions are not the
    locked ones, so results from such an environment never pass for locked ones.

    Returns
    -------
    str
        The label stored as ``lock_hash`` in every row (computed once per process).
    """
    differs = deviations()
    if not differs:
        return lock_hash()
    return f"{lock_hash()}+venv-differs({', '.join(differs)})"


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()
