"""Helpers shared by the subcommands: JSON output of numpy values."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np


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


def print_json(value: Any) -> None:
    """One JSON object on stdout."""
    print(json.dumps(to_jsonable(value)))


def write_json(path: str | os.PathLike[str], value: Any) -> Path:
    """Writes ``value`` as indented JSON atomically (a temporary file renamed over ``path``)."""
    from qpbench.atomic import atomic_path
    from qpbench.errors import InputError

    text = json.dumps(to_jsonable(value), indent=2) + "\n"
    try:
        with atomic_path(path) as temporary:
            temporary.write_text(text)
    except OSError as error:
        raise InputError(str(path), f"cannot write: {error.strerror or error}") from error
    return Path(path)
