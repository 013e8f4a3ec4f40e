"""Problem files: one ``.npz`` per problem, no pickle.

Arrays are stored by name; G as its CSC parts; metadata as UTF-8 JSON bytes.
Files are written to a temporary name and renamed, so a reader never sees half
a file.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.atomic import atomic_path
from qpbench.errors import InputError
from qpbench.problem.impact import ImpactProblem, Reference

SUFFIX = ".npz"
FORMAT_VERSION = 1
_REFERENCE_ARRAYS = ("v_plus", "impulses", "v_plus_check")


def _json_bytes(value: Any) -> np.ndarray:
    return np.frombuffer(json.dumps(value, sort_keys=True).encode(), dtype=np.uint8)


def save(problem: ImpactProblem, path: str | os.PathLike[str]) -> Path:
    """Writes ``problem`` to ``path`` atomically and returns the path."""
    path = Path(path)
    if path.suffix != SUFFIX:
        path = path.with_name(path.name + SUFFIX)
    G = sp.csc_matrix(problem.G)
    arrays: dict[str, np.ndarray] = {
        "G_data": G.data,
        "G_indices": G.indices,
        "G_indptr": G.indptr,
        "G_shape": np.asarray(G.shape, dtype=np.int64),
        "m_inv": problem.m_inv,
        "v_minus": problem.v_minus,
        "restitution": problem.restitution,
        "n_rel": problem.n_rel,
    }
    header: dict[str, Any] = {
        "format": FORMAT_VERSION,
        "name": problem.name,
        "family": problem.family,
        "source": problem.source,
        "dofs_per_body": problem.dofs_per_body,
        "metadata": problem.metadata,
        "data": sorted(problem.data),
    }
    for key, value in problem.data.items():
        arrays[f"data_{key}"] = np.asarray(value)
    if problem.reference is not None:
        ref = problem.reference
        for key in _REFERENCE_ARRAYS:
            arrays[f"ref_{key}"] = getattr(ref, key)
        header["reference"] = {
            "method": ref.method,
            "check_method": ref.check_method,
            "agreement": ref.agreement,
            "tolerance": ref.tolerance,
        }
    arrays["header_json"] = _json_bytes(header)
    with atomic_path(path) as temporary, open(temporary, "wb") as stream:
        np.savez_compressed(stream, **arrays)
    return path


def load(path: str | os.PathLike[str]) -> ImpactProblem:
    """Reads a problem file written by :func:`save`; raises InputError on a bad file."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
    except FileNotFoundError as error:
        raise InputError(str(path), "no such problem file") from error
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as error:
        raise InputError(str(path), f"not a qpbench problem file ({error})") from error
    try:
        header = json.loads(arrays.pop("header_json").tobytes().decode())
        G = sp.csc_matrix(
            (arrays["G_data"], arrays["G_indices"], arrays["G_indptr"]),
            shape=tuple(int(s) for s in arrays["G_shape"]),
        )
    except KeyError as error:
        raise InputError(str(path), "missing array", attribute=str(error.args[0])) from error
    except (ValueError, json.JSONDecodeError) as error:
        raise InputError(str(path), f"corrupt problem file ({error})") from error
    _check_header(header, path)
    reference = None
    if "reference" in header:
        reference = Reference(
            **{key: arrays[f"ref_{key}"] for key in _REFERENCE_ARRAYS}, **header["reference"]
        )
    problem = ImpactProblem(
        name=header["name"],
        G=G,
        m_inv=arrays["m_inv"],
        v_minus=arrays["v_minus"],
        restitution=arrays["restitution"],
        n_rel=arrays["n_rel"],
        family=header.get("family", ""),
        source=header.get("source", ""),
        dofs_per_body=int(header.get("dofs_per_body", 2)),
        metadata=header.get("metadata", {}),
        data={key: arrays[f"data_{key}"] for key in header.get("data", [])},
        reference=reference,
    )
    problem.validate(str(path))
    return problem


def _check_header(header: Any, path: Path) -> None:
    """InputError naming the file and the field when the header is not one :func:`save` writes:
    a format version other than FORMAT_VERSION, or no name."""
    if not isinstance(header, dict):
        raise InputError(str(path), "corrupt problem file (the header is not a JSON object)")
    version = header.get("format")
    if version != FORMAT_VERSION:
        found = "missing" if version is None else f"is {version!r}"
        raise InputError(str(path), f"format version {found}; this qpbench reads version "
                         f"{FORMAT_VERSION}", attribute="format")
    if not isinstance(header.get("name"), str) or not header["name"]:
        raise InputError(str(path), "missing: every problem file names its problem",
                         attribute="name")


def find(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """Problem files named directly or found (recursively, sorted) in the folders named."""
    found: list[Path] = []
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            found.extend(sorted(p for p in entry.rglob(f"*{SUFFIX}") if not p.name.startswith(".")))
        elif entry.exists():
            found.append(entry)
        else:
            raise InputError(str(entry), "no such problem file or folder")
    return found


def load_all(paths: Iterable[str | os.PathLike[str]]) -> Iterator[ImpactProblem]:
    """Loads every problem file named or found in the folders named."""
    for path in find(paths):
        yield load(path)
