"""Problem files: one ``.npz`` per problem, no pickle.

Arrays are stored by name; G (and T) as CSC parts; metadata as UTF-8 JSON bytes.
Files are written to a temporary name and renamed, so a reader never sees half
a file. Format 2 adds the problem's ``kind``: ``impact`` (as format 1) or
``frictional`` (a :class:`FrictionalProblem`: T, mu, d_rel and its reference beside the
normal problem's arrays) or ``frictional-reduced`` (a :class:`ReducedFrictionalProblem`: W as
CSC parts, q, mu and its reference). Both versions are read.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.atomic import atomic_path
from qpbench.errors import InputError, shown
from qpbench.interrupts import interrupts_held
from qpbench.problem.friction import KIND as FRICTIONAL
from qpbench.problem.friction import FrictionalProblem, FrictionalReference
from qpbench.problem.impact import ImpactProblem, Reference, check_vector
from qpbench.problem.reduced import KIND as REDUCED
from qpbench.problem.reduced import ReducedFrictionalProblem

SUFFIX = ".npz"
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
IMPACT = "impact"
_REFERENCE_ARRAYS = ("v_plus", "impulses", "v_plus_check")
_FRICTIONAL_REFERENCE_ARRAYS = ("impulses", "v_plus")
# the header's fields beside format, kind and name, with the JSON types they take: the optional
# fields of every file, and the fields of the two kinds of reference (all required but
# ``solvable``, which files written before it existed lack)
_REAL = (int, float)
_HEADER_FIELDS: dict[str, tuple[type, ...]] = {
    "family": (str,), "source": (str,), "dofs_per_body": (int,), "metadata": (dict,),
    "data": (list,), "reference": (dict,), "frictional_reference": (dict,)}
_REFERENCE_FIELDS: dict[str, tuple[type, ...]] = {
    "method": (str,), "check_method": (str,), "agreement": _REAL, "tolerance": _REAL}
_FRICTIONAL_REFERENCE_FIELDS: dict[str, tuple[type, ...]] = {
    "method": (str,), "residual": _REAL, "unique": (bool, type(None)), "solvable": (bool,)}
_OPTIONAL_REFERENCE_FIELDS = ("solvable",)
NPY_SIGNATURE = b"\x93NUMPY"  # the start of a single .npy array
ZIP_SIGNATURES = (b"PK\x03\x04", b"PK\x05\x06")  # a zip archive's first entry, or an empty one
# the most that deflate can expand its input (a run of one byte), rounded up
DEFLATE_RATIO = 1100
_NPY_HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0,
                       (2, 0): np.lib.format.read_array_header_2_0}

AnyProblem = ImpactProblem | FrictionalProblem


def _json_bytes(value: Any) -> np.ndarray:
    return np.frombuffer(json.dumps(value, sort_keys=True).encode(), dtype=np.uint8)


def _csc_arrays(label: str, matrix: sp.spmatrix) -> dict[str, np.ndarray]:
    matrix = sp.csc_matrix(matrix)
    return {f"{label}_data": matrix.data, f"{label}_indices": matrix.indices,
            f"{label}_indptr": matrix.indptr,
            f"{label}_shape": np.asarray(matrix.shape, dtype=np.int64)}


def _array(arrays: dict[str, np.ndarray], key: str, path: Path) -> np.ndarray:
    """The array stored as ``key``; InputError naming it when the file has none."""
    if key not in arrays:
        raise InputError(str(path), "missing array", attribute=key)
    return arrays[key]


def _integers(arrays: dict[str, np.ndarray], key: str, path: Path) -> np.ndarray:
    """The one-dimensional integer array stored as ``key``; InputError naming it otherwise."""
    values = _array(arrays, key, path)
    if values.dtype.kind not in "iu" or values.ndim != 1:
        raise InputError(str(path), f"must be a one-dimensional integer array, got "
                         f"{values.dtype} of shape {values.shape}", attribute=key)
    return values


def _vector(arrays: dict[str, np.ndarray], key: str, path: Path) -> np.ndarray:
    """The one-dimensional real array stored as ``key``, as float64; InputError naming it
    otherwise (its values are checked by the problem's ``validate``)."""
    values = _array(arrays, key, path)
    if values.dtype.kind not in "iuf" or values.ndim != 1:
        raise InputError(str(path), f"must be a one-dimensional real array, got "
                         f"{values.dtype} of shape {values.shape}", attribute=key)
    return values.astype(float)


def _csc_of(label: str, arrays: dict[str, np.ndarray], path: Path) -> sp.csc_matrix:
    """The CSC matrix stored as ``label_data``, ``label_indices``, ``label_indptr`` and
    ``label_shape``; InputError naming ``label`` unless it is one :func:`save` writes:
    column pointers from 0 that never decrease and end at the number of entries, row
    indices inside the shape, sorted within each column and never repeated."""
    shape = _integers(arrays, f"{label}_shape", path)
    if shape.shape != (2,) or np.any(shape < 0):
        raise InputError(str(path), f"must be two sizes >= 0, got {shape.tolist()}",
                         attribute=f"{label}_shape")
    data = _vector(arrays, f"{label}_data", path)
    indices = _integers(arrays, f"{label}_indices", path)
    indptr = _integers(arrays, f"{label}_indptr", path)
    try:
        matrix = sp.csc_matrix((data, indices, indptr), shape=(int(shape[0]), int(shape[1])))
        matrix.check_format(full_check=True)
    except ValueError as error:
        raise InputError(str(path), f"not a valid sparse matrix ({error})",
                         attribute=label) from error
    if not matrix.has_canonical_format:
        raise InputError(str(path), "row indices are unsorted or repeated within a column",
                         attribute=f"{label}_indices")
    return matrix


def save(problem: AnyProblem, path: str | os.PathLike[str]) -> Path:
    """Writes ``problem`` (impact or frictional) to ``path`` atomically; returns the path.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem, with its reference and stored data (a reduced one as W, q and mu).
    path : str or os.PathLike
        The file to write; ``.npz`` is appended when it has another suffix.

    Returns
    -------
    Path
        The path written, ending in ``.npz``.

    Raises
    ------
    OutputError
        When the path cannot be written (:func:`~qpbench.atomic.atomic_path`).
    """
    path = Path(path)
    if path.suffix != SUFFIX:
        path = path.with_name(path.name + SUFFIX)
    if isinstance(problem, ReducedFrictionalProblem):
        return _save_reduced(problem, path)
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
            header["frictional_reference"] = _frictional_reference_fields(fref)
    return _write(path, arrays, header)


def _frictional_reference_fields(fref: FrictionalReference) -> dict[str, Any]:
    """The header's fields of a frictional reference (its arrays are stored beside)."""
    return {"method": fref.method, "residual": fref.residual, "unique": fref.unique,
            "solvable": fref.solvable}


def _write(path: Path, arrays: dict[str, np.ndarray], header: dict[str, Any]) -> Path:
    """Writes ``arrays`` and ``header`` (as ``header_json``) to the .npz at ``path``,
    atomically; returns ``path``. Ctrl-C is held off while NumPy writes the zip archive
    (:func:`~qpbench.interrupts.interrupts_held`; a few milliseconds): cut short between the
    opening of a member and the block that closes it, the archive would be left with that
    member open, which the garbage collector then closes, failing on our closed file or on
    the archive, after the interrupt's one line."""
    arrays["header_json"] = _json_bytes(header)
    with atomic_path(path) as temporary, open(temporary, "wb") as stream, interrupts_held():
        np.savez_compressed(stream, **arrays)
    return path


def _save_reduced(problem: ReducedFrictionalProblem, path: Path) -> Path:
    """Writes a reduced problem: W (CSC parts), q, mu, its reference and the header."""
    arrays: dict[str, np.ndarray] = {**_csc_arrays("W", problem.W), "q": problem.q,
                                     "mu": problem.mu}
    header: dict[str, Any] = {"format": FORMAT_VERSION, "kind": REDUCED, "name": problem.name,
                              "family": problem.family, "source": problem.source,
                              "metadata": problem.metadata, "data": sorted(problem.data)}
    for key, value in problem.data.items():
        arrays[f"data_{key}"] = np.asarray(value)
    if problem.reference is not None:
        fref = problem.reference
        arrays["fref_impulses"] = fref.impulses
        header["frictional_reference"] = _frictional_reference_fields(fref)
    return _write(path, arrays, header)


def _load_reduced(header: dict[str, Any], arrays: dict[str, np.ndarray], path: Path
                  ) -> ReducedFrictionalProblem:
    reference = None
    if "frictional_reference" in header:
        reference = FrictionalReference(
            impulses=_vector(arrays, "fref_impulses", path), v_plus=np.zeros(0),
            **{key: value for key, value in header["frictional_reference"].items()
               if key in _FRICTIONAL_REFERENCE_FIELDS})
    W = _csc_of("W", arrays, path)
    problem = ReducedFrictionalProblem.from_local(
        header["name"], W, _vector(arrays, "q", path), _vector(arrays, "mu", path),
        family=header.get("family", ""), source=header.get("source", ""),
        metadata=header.get("metadata", {}), reference=reference, where=str(path))
    problem.normal.data.update(
        {key: _array(arrays, f"data_{key}", path) for key in header.get("data", [])})
    problem.validate(str(path))
    return problem


def load(path: str | os.PathLike[str]) -> AnyProblem:
    """Reads a problem file written by :func:`save`; raises InputError on a bad file.

    The file gives an :class:`ImpactProblem` or a :class:`FrictionalProblem` (reduced or not),
    by its kind.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.npz`` file.

    Returns
    -------
    ImpactProblem or FrictionalProblem
        The validated problem, with its reference and stored data.

    Raises
    ------
    InputError
        When the file is missing, unreadable, not such an archive, or its header, an array
        or the problem it describes is invalid.
    """
    path = Path(path)
    arrays = read_arrays(path)
    try:
        header = json.loads(_array(arrays, "header_json", path).tobytes().decode())
    except (ValueError, RecursionError) as error:  # JSON, UTF-8, nesting beyond json's limit
        raise InputError(str(path), f"corrupt problem file header ({error})",
                         attribute="header_json") from error
    _check_header(header, path)
    if header.get("kind") == REDUCED:
        reduced = _load_reduced(header, arrays, path)
        _check_carried(reduced, arrays, path)
        return reduced
    reference = None
    if "reference" in header:
        reference = Reference(
            **{key: _vector(arrays, f"ref_{key}", path) for key in _REFERENCE_ARRAYS},
            **{key: header["reference"][key] for key in _REFERENCE_FIELDS})
    problem = ImpactProblem(
        name=header["name"],
        G=_csc_of("G", arrays, path),
        m_inv=_vector(arrays, "m_inv", path),
        v_minus=_vector(arrays, "v_minus", path),
        restitution=_vector(arrays, "restitution", path),
        n_rel=_vector(arrays, "n_rel", path),
        family=header.get("family", ""),
        source=header.get("source", ""),
        dofs_per_body=header.get("dofs_per_body", 2),
        metadata=header.get("metadata", {}),
        data={key: _array(arrays, f"data_{key}", path) for key in header.get("data", [])},
        reference=reference,
    )
    loaded: AnyProblem = problem
    if header.get("kind", IMPACT) == FRICTIONAL:
        loaded = _frictional(problem, header, arrays, path)
    else:
        problem.validate(str(path))
    _check_carried(loaded, arrays, path)
    return loaded


def read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` archive at ``path``, by name, read without pickle.

    InputError naming the file (and the array, where one is at fault) and saying what is wrong
    when it is no such archive: a single ``.npy`` array, not a zip archive at all, a damaged or
    truncated one, a member that is not a ``.npy`` array, or an array of Python objects.

    Parameters
    ----------
    path : Path
        The archive.

    Returns
    -------
    dict of str to np.ndarray
        The arrays by member name without ``.npy``.

    Raises
    ------
    InputError
        When the file is missing, a folder, unreadable or not such an archive.
    """
    try:
        with open(path, "rb") as stream:
            signature = stream.read(len(NPY_SIGNATURE))
    except FileNotFoundError as error:
        raise InputError(str(path), "no such problem file") from error
    except IsADirectoryError as error:
        raise InputError(str(path), "is a folder, not a problem file") from error
    except OSError as error:
        raise InputError(str(path), f"cannot read: {error.strerror or error}") from error
    if signature.startswith(NPY_SIGNATURE):
        raise InputError(str(path), "a single NumPy array (.npy), not a problem file (a .npz "
                         "archive of arrays)")
    if not signature.startswith(ZIP_SIGNATURES):
        raise InputError(str(path), "not a problem file: not a .npz (zip) archive")
    try:
        with zipfile.ZipFile(path) as archive:
            return {member.removesuffix(".npy"): _member_array(archive, member, path)
                    for member in archive.namelist()}
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, RuntimeError,
            NotImplementedError) as error:  # RuntimeError: encrypted; NotImplementedError:
        # a compression method zipfile does not read
        raise InputError(str(path), f"a damaged or truncated .npz archive ({error})") from error


def _member_array(archive: zipfile.ZipFile, member: str, path: Path) -> np.ndarray:
    """The array stored as ``member`` of ``archive``; InputError naming it when it is not a
    ``.npy`` array of numbers, or is cut short or damaged."""
    key = member.removesuffix(".npy")
    try:
        with archive.open(member) as stream:
            version = np.lib.format.read_magic(stream)
            if version not in _NPY_HEADER_READERS:
                raise InputError(str(path), f".npy format version {version} is not one "
                                 "problem files use", attribute=key)
            shape, _, dtype = _NPY_HEADER_READERS[version](stream)
            if dtype.hasobject:
                raise InputError(str(path), f"holds Python objects ({dtype}); a problem file "
                                 "holds arrays of numbers only", attribute=key)
            _check_declared_size(archive.getinfo(member), stream.tell(), shape, dtype, path,
                                 key)
        with archive.open(member) as stream:
            return np.lib.format.read_array(stream, allow_pickle=False)
    except (zipfile.BadZipFile, zlib.error, EOFError, ValueError) as error:
        raise InputError(str(path), f"not a readable .npy array ({error})",
                         attribute=key) from error


def _check_declared_size(member: zipfile.ZipInfo, header_bytes: int, shape: tuple[int, ...],
                         dtype: np.dtype, path: Path, key: str) -> None:
    """InputError, before anything is allocated, when an array's header declares more bytes
    than its member can hold: more than the member's uncompressed size after the header, or
    than :data:`DEFLATE_RATIO` times its compressed size (no deflate stream expands further),
    or a compressed size larger than the file itself."""
    declared = math.prod(shape) * dtype.itemsize
    if member.compress_size > path.stat().st_size:
        raise InputError(str(path), f"a damaged .npz archive: the member claims "
                         f"{member.compress_size} bytes, more than the file holds",
                         attribute=key)
    room = min(member.file_size - header_bytes, DEFLATE_RATIO * member.compress_size)
    if declared > room:
        raise InputError(str(path), f"declares a {'x'.join(map(str, shape)) or 'scalar'} "
                         f"array of {dtype} ({declared} bytes) but holds at most {max(room, 0)}",
                         attribute=key)


def _check_carried(problem: AnyProblem, arrays: dict[str, np.ndarray], path: Path) -> None:
    """InputError naming the array unless what a captured scene carries has one entry per
    contact: ``contact_keys`` integers, ``warm_start`` finite impulses (l, or r = (l_N, l_T)
    of a frictional problem)."""
    n = problem.n_contacts
    if "contact_keys" in problem.data:
        keys = _integers(arrays, "data_contact_keys", path)
        if keys.shape != (n,):
            raise InputError(str(path), f"shape {keys.shape} does not match G {problem.G.shape}",
                             attribute="data_contact_keys")
    if "warm_start" in problem.data:
        size = 2 * n if isinstance(problem, FrictionalProblem) else n
        check_vector(str(path), "data_warm_start", _vector(arrays, "data_warm_start", path),
                     size, problem.G.shape)


def _frictional(normal: ImpactProblem, header: dict[str, Any], arrays: dict[str, np.ndarray],
                path: Path) -> FrictionalProblem:
    reference = None
    if "frictional_reference" in header:
        reference = FrictionalReference(
            **{key: _vector(arrays, f"fref_{key}", path) for key in _FRICTIONAL_REFERENCE_ARRAYS},
            **{key: value for key, value in header["frictional_reference"].items()
               if key in _FRICTIONAL_REFERENCE_FIELDS})
    problem = FrictionalProblem(normal=normal, T=_csc_of("T", arrays, path),
                                mu=_vector(arrays, "mu", path),
                                d_rel=_vector(arrays, "d_rel", path), reference=reference)
    problem.validate(str(path))
    return problem


def _check_header(header: Any, path: Path) -> None:
    """InputError naming the file and the field when the header is not one :func:`save` writes:
    a format version it cannot read, an unknown kind, no name, or a field of another type."""
    if not isinstance(header, dict):
        raise InputError(str(path), "corrupt problem file (the header is not a JSON object)")
    version = header.get("format")
    if version not in READABLE_VERSIONS or isinstance(version, bool):
        found = "missing" if version is None else \
            f"is {shown(version) if isinstance(version, str) else shown(repr(version))}"
        readable = " and ".join(str(v) for v in READABLE_VERSIONS)
        raise InputError(str(path), f"format version {found}; this qpbench reads versions "
                         f"{readable}", attribute="format")
    if header.get("kind", IMPACT) not in (IMPACT, FRICTIONAL, REDUCED):
        raise InputError(str(path), f"unknown kind {shown(str(header.get('kind')))} "
                         f"(known: {IMPACT}, {FRICTIONAL}, {REDUCED})", attribute="kind")
    if not isinstance(header.get("name"), str) or not header["name"]:
        raise InputError(str(path), "missing: every problem file names its problem",
                         attribute="name")
    _check_fields(header, _HEADER_FIELDS, path, optional=tuple(_HEADER_FIELDS))
    if header.get("dofs_per_body", 1) < 1:
        raise InputError(str(path), f"must be at least 1, got {header['dofs_per_body']}",
                         attribute="dofs_per_body")
    if not all(isinstance(key, str) for key in header.get("data", [])):
        raise InputError(str(path), "must list the names of the stored data arrays",
                         attribute="data")
    if "reference" in header:
        _check_fields(header["reference"], _REFERENCE_FIELDS, path, prefix="reference.")
    if "frictional_reference" in header:
        _check_fields(header["frictional_reference"], _FRICTIONAL_REFERENCE_FIELDS, path,
                      prefix="frictional_reference.", optional=_OPTIONAL_REFERENCE_FIELDS)


def _check_fields(fields: dict[str, Any], types: dict[str, tuple[type, ...]], path: Path,
                  prefix: str = "", optional: tuple[str, ...] = ()) -> None:
    """InputError naming the first field of ``types`` that ``fields`` lacks (unless it is
    ``optional``) or holds with another JSON type (true and false are not numbers);
    fields that ``types`` does not name are left alone."""
    for key, allowed in types.items():
        if key not in fields:
            if key in optional:
                continue
            raise InputError(str(path), "missing", attribute=prefix + key)
        value = fields[key]
        if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
            expected = " or ".join("null" if kind is type(None) else kind.__name__
                                   for kind in allowed)
            raise InputError(str(path), f"must be {expected}, got {value!r}"[:200],
                             attribute=prefix + key)


def find(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """Problem files named directly or found (recursively, sorted) in the folders named.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Files and folders; hidden files in the folders are skipped.

    Returns
    -------
    list of Path
        The files, in the order named, each folder's ``.npz`` files sorted.

    Raises
    ------
    InputError
        When a path does not exist.
    """
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
    """Loads every problem file named or found in the folders named.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Files and folders, as :func:`find` takes them.

    Yields
    ------
    ImpactProblem or FrictionalProblem
        Each problem, as :func:`load` reads it.

    Raises
    ------
    InputError
        When a path does not exist or a file is bad.
    """
    for path in find(paths):
        yield load(path)
