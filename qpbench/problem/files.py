"""Problem files: one ``.npz`` per problem, no pickle.

Arrays are stored by name; G (and T) as CSC parts; metadata as UTF-8 JSON bytes.
Files are written to a temporary name and renamed, so a reader never sees half
a file. Format 2 adds the problem's ``kind``: ``impact`` (as format 1) or
``frictional`` (a :class:`FrictionalProblem`: T, mu, d_rel and its reference beside the
normal problem's arrays). Both versions are read.
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
from qpbench.problem.friction import KIND as FRICTIONAL
from qpbench.problem.friction import FrictionalProblem, FrictionalReference
from qpbench.problem.impact import ImpactProblem, Reference

SUFFIX = ".npz"
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
IMPACT = "impact"
_REFERENCE_ARRAYS = ("v_plus", "impulses", "v_plus_check")
_FRICTIONAL_REFERENCE_ARRAYS = ("impulses", "v_plus")

AnyProblem = ImpactProblem | FrictionalProblem


def _json_bytes(value: Any) -> np.ndarray:
    return np.frombuffer(json.dumps(value, sort_keys=True).encode(), dtype=np.uint8)


def _csc_arrays(label: str, matrix: sp.spmatrix) -> dict[str, np.ndarray]:
    matrix = sp.csc_matrix(matrix)
    return {f"{label}_data": matrix.data, f"{label}_indices": matrix.indices,
            f"{label}_indptr": matrix.indptr,
            f"{label}_shape": np.asarray(matrix.shape, dtype=np.int64)}


def _csc_of(label: str, arrays: dict[str, np.ndarray]) -> sp.csc_matrix:
    return sp.csc_matrix(
        (arrays[f"{label}_data"], arrays[f"{label}_indices"], arrays[f"{label}_indptr"]),
        shape=tuple(int(s) for s in arrays[f"{label}_shape"]))


def save(problem: AnyProblem, path: str | os.PathLike[str]) -> Path:
    """Writes ``problem`` (impact or frictional) to ``path`` atomically; returns the path."""
    path = Path(path)
    if path.suffix != SUFFIX:
        path = path.with_name(path.name + SUFFIX)
    frictional = problem if isinstance(problem, FrictionalProblem) else None
    if frictional is not None:
        problem = frictional.normal
    arrays: dict[str, np.ndarray] = {
        **_csc_arrays("G", problem.G),
        "m_inv": problem.m_inv,
        "v_minus": problem.v_minus,
        "restitution": problem.restitution,
        "n_rel": problem.n_rel,
    }
    header: dict[str, Any] = {
        "format": FORMAT_VERSION,
        "kind": FRICTIONAL if frictional is not None else IMPACT,
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
    if frictional is not None:
        arrays.update(_csc_arrays("T", frictional.T), mu=frictional.mu, d_rel=frictional.d_rel)
        if frictional.reference is not None:
            fref = frictional.reference
            for key in _FRICTIONAL_REFERENCE_ARRAYS:
                arrays[f"fref_{key}"] = getattr(fref, key)
            header["frictional_reference"] = {"method": fref.method, "residual": fref.residual,
                                              "unique": fref.unique, "solvable": fref.solvable}
    arrays["header_json"] = _json_bytes(header)
    with atomic_path(path) as temporary, open(temporary, "wb") as stream:
        np.savez_compressed(stream, **arrays)
    return path


def load(path: str | os.PathLike[str]) -> AnyProblem:
    """Reads a problem file written by :func:`save` (an :class:`ImpactProblem` or a
    :class:`FrictionalProblem`, by its kind); raises InputError on a bad file."""
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
        G = _csc_of("G", arrays)
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
    if header.get("kind", IMPACT) == FRICTIONAL:
        return _frictional(problem, header, arrays, path)
    problem.validate(str(path))
    return problem


def _frictional(normal: ImpactProblem, header: dict[str, Any], arrays: dict[str, np.ndarray],
                path: Path) -> FrictionalProblem:
    try:
        T = _csc_of("T", arrays)
        reference = None
        if "frictional_reference" in header:
            reference = FrictionalReference(
                **{key: arrays[f"fref_{key}"] for key in _FRICTIONAL_REFERENCE_ARRAYS},
                **header["frictional_reference"])
        problem = FrictionalProblem(normal=normal, T=T, mu=arrays["mu"], d_rel=arrays["d_rel"],
                                    reference=reference)
    except KeyError as error:
        raise InputError(str(path), "missing array", attribute=str(error.args[0])) from error
    except (ValueError, TypeError) as error:
        raise InputError(str(path), f"corrupt problem file ({error})") from error
    problem.validate(str(path))
    return problem


def _check_header(header: Any, path: Path) -> None:
    """InputError naming the file and the field when the header is not one :func:`save` writes:
    a format version it cannot read, an unknown kind, or no name."""
    if not isinstance(header, dict):
        raise InputError(str(path), "corrupt problem file (the header is not a JSON object)")
    version = header.get("format")
    if version not in READABLE_VERSIONS or isinstance(version, bool):
        found = "missing" if version is None else f"is {version!r}"
        readable = " and ".join(str(v) for v in READABLE_VERSIONS)
        raise InputError(str(path), f"format version {found}; this qpbench reads versions "
                         f"{readable}", attribute="format")
    if header.get("kind", IMPACT) not in (IMPACT, FRICTIONAL):
        raise InputError(str(path), f"unknown kind {header.get('kind')!r} (known: {IMPACT}, "
                         f"{FRICTIONAL})", attribute="kind")
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


def load_all(paths: Iterable[str | os.PathLike[str]]) -> Iterator[AnyProblem]:
    """Loads every problem file named or found in the folders named."""
    for path in find(paths):
        yield load(path)
