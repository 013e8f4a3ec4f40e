"""Import of the LCP dumps printed by a research fork of SCISim at a scene's first impact.

Two layouts (docs/design.md section 5):

* JSON-like: an object with trailing commas whose matrix entries (``N``, ``Q``, ``Minv``,
  ``v0``, ``b``, ``ipopt_sol``, ``policy_sol``) are ``{"shape": [r, c], "data": [[i, j, value],
  ...]}``, plus ``*_converges`` flags and ``*_time`` integers;
* text: ``NAME:`` / ``size: r c`` / ``(i,j,value) ...`` blocks and ``NAME:`` / value pairs; no
  ``b`` (it is ``(1 + CoR) N^T v0``, CoR 1 unless told).

G = N, M^-1 = diag(Minv), v- = v0; the restitution comes from b where b is given. The dumped
solutions, Q, b, flags and times are kept as data: they are not references (the dumped IPOPT
answers are not all converged).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError
from qpbench.problem.impact import ImpactProblem

REQUIRED = ("N", "Minv", "v0")
_TRAILING_COMMA = re.compile(r",(\s*[}\]])")
_TRIPLET = re.compile(r"\(\s*([^,()]+),\s*([^,()]+),\s*([^,()]+)\)")


# the most rows or columns a dumped matrix may have (the shared dumps have at most a few
# hundred); the dumped Q is kept as a dense array, so at most LARGEST_DENSE entries
LARGEST_DIMENSION = 10_000_000
LARGEST_DENSE = 100_000_000


def _is_size(size: Any) -> bool:
    """A JSON integer or a text dump's run of digits (optionally signed)."""
    if isinstance(size, str):
        return re.fullmatch(r"[+-]?\d{1,12}", size.strip()) is not None
    return isinstance(size, int) and not isinstance(size, bool)


def _matrix(file: str, name: str, shape: Any, triplets: list) -> sp.coo_matrix:
    """A sparse matrix from its shape and (i, j, value) triplets, checked against the shape."""
    sizes = list(shape) if isinstance(shape, list | tuple) else []
    if len(sizes) != 2 or not all(_is_size(size) for size in sizes):
        raise InputError(file, f"shape must be two integers, got {shape!r}"[:200], name, "shape")
    rows, cols = (int(size) for size in sizes)
    if rows < 0 or cols < 0:
        raise InputError(file, f"negative shape {shape!r}", name, "shape")
    if max(rows, cols) > LARGEST_DIMENSION:
        raise InputError(file, f"shape {shape!r} is beyond {LARGEST_DIMENSION:,} rows or "
                         "columns", name, "shape")
    try:
        data = np.asarray(triplets, dtype=float).reshape(-1, 3)
    except (TypeError, ValueError) as error:
        raise InputError(file, "entries must be [i, j, value] triplets", name, "data") from error
    index = data[:, :2]
    if np.any(index != np.round(index)) or np.any(index < 0) or np.any(
        index >= np.array([rows, cols])
    ):
        raise InputError(file, f"an index lies outside shape [{rows}, {cols}]", name, "data")
    if not np.all(np.isfinite(data[:, 2])):
        raise InputError(file, "contains NaN or infinity", name, "data")
    row, col = data[:, 0].astype(int), data[:, 1].astype(int)
    flat = row * cols + col
    unique, counts = np.unique(flat, return_counts=True)
    if np.any(counts > 1):  # a sparse matrix would sum them silently
        twice = int(unique[np.argmax(counts > 1)])
        raise InputError(file, f"entry ({twice // cols}, {twice % cols}) appears more than once",
                         name, "data")
    return sp.coo_matrix((data[:, 2], (row, col)), shape=(rows, cols))


class _JsonObject(dict):
    """A JSON object, with the first key it names twice (json keeps the last one silently)."""

    repeated: str | None = None


def _unique_keys(pairs: list[tuple[str, Any]]) -> _JsonObject:
    """The object of ``pairs``, its first repeated key noted."""
    unique = _JsonObject()
    for key, value in pairs:
        if key in unique and unique.repeated is None:
            unique.repeated = key
        unique[key] = value
    return unique


def _repeated_within(value: Any) -> str | None:
    """The first key that an object in ``value`` (itself, or within its values or items)
    names twice; None when there is none."""
    if isinstance(value, _JsonObject):
        if value.repeated is not None:
            return value.repeated
        value = list(value.values())
    if isinstance(value, list):
        for item in value:
            if isinstance(item, (list, dict)):
                repeated = _repeated_within(item)
                if repeated is not None:
                    return repeated
    return None


def _parse_json(file: str, text: str) -> tuple[dict[str, sp.coo_matrix], dict[str, Any]]:
    try:
        raw = json.loads(_TRAILING_COMMA.sub(r"\1", text), object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as error:
        raise InputError(file, f"malformed dump: {error.msg} at line {error.lineno}") from error
    except RecursionError as error:  # json's own limit on nested arrays and objects
        raise InputError(file, "malformed dump: arrays or objects nested too deeply") from error
    if not isinstance(raw, dict):
        raise InputError(file, "malformed dump: expected an object")
    if raw.repeated is not None:
        raise InputError(file, "appears more than once", raw.repeated)
    matrices: dict[str, sp.coo_matrix] = {}
    scalars: dict[str, Any] = {}
    for name, value in raw.items():
        repeated = _repeated_within(value)
        if repeated is not None:
            raise InputError(file, "appears more than once", name, repeated)
        if isinstance(value, dict):
            if "shape" not in value or "data" not in value:
                missing = "shape" if "shape" not in value else "data"
                raise InputError(file, "missing", name, missing)
            matrices[name] = _matrix(file, name, value["shape"], value["data"])
        else:
            scalars[name] = value
    return matrices, scalars


def _triplets(file: str, name: str, body: str) -> list[list[float]]:
    """The ``(i,j,value)`` triplets of a text block's body line; InputError naming the entry
    when anything else stands there or a part is not a number."""
    leftover = _TRIPLET.sub(" ", body).strip()
    if leftover:
        raise InputError(file, f"not an (i,j,value) triplet: {leftover[:40]!r}", name, "data")
    try:
        return [[float(part) for part in triplet] for triplet in _TRIPLET.findall(body)]
    except ValueError as error:
        raise InputError(file, f"a triplet part is not a number ({error})", name,
                         "data") from error


def _parse_text(file: str, text: str) -> tuple[dict[str, sp.coo_matrix], dict[str, Any]]:
    matrices: dict[str, sp.coo_matrix] = {}
    scalars: dict[str, Any] = {}
    lines = [line.strip() for line in text.splitlines()]
    index = 0
    while index < len(lines):
        line = lines[index]
        index += 1
        if not line:
            continue
        if ":" not in line:
            raise InputError(file, f"malformed dump: line {index} ({line[:40]!r}) is neither "
                             "NAME: nor the body of one")
        name, _, rest = line.partition(":")
        name, rest = name.strip(), rest.strip()
        if name in matrices or name in scalars:
            raise InputError(file, "appears more than once", name)
        if rest:  # "solve status: 0"
            scalars[name] = rest
            continue
        following = lines[index] if index < len(lines) else ""
        if following.startswith("size:"):
            shape = following.split(":", 1)[1].split()
            body = lines[index + 1] if index + 1 < len(lines) else ""
            matrices[name] = _matrix(file, name, shape, _triplets(file, name, body))
            index += 2
        else:
            scalars[name] = following
            index += 1
    if not matrices:
        raise InputError(file, "malformed dump: no NAME: / size: / (i,j,value) blocks found")
    return matrices, scalars


def _scalar(value: Any) -> Any:
    if isinstance(value, str):
        for cast in (int, float):
            try:
                return cast(value)
            except ValueError:
                pass
    return value


def _dense(file: str, matrices: dict[str, sp.coo_matrix], name: str,
           expected: tuple[int, int]) -> np.ndarray:
    """Entry ``name`` as a dense array, once its shape is ``expected`` and it has at most
    LARGEST_DENSE entries; InputError naming the entry otherwise."""
    shape = matrices[name].shape
    if shape != expected:
        raise InputError(file, f"is {shape}, expected {expected}", name, "shape")
    if shape[0] * shape[1] > LARGEST_DENSE:
        raise InputError(file, f"too large to keep ({shape[0]} x {shape[1]} entries); leave "
                         "it out of the dump", name, "shape")
    return matrices[name].toarray()


def import_dump(path: str | Path, restitution: float | None = None) -> ImpactProblem:
    """The ImpactProblem of one dump file; InputError names the file, entry and field at fault.

    Parameters
    ----------
    path : str or Path
        The dump, in either layout (module docstring); its stem names the problem.
    restitution : float or None, optional
        The coefficient of restitution of every contact. None (the default) reads it from
        ``b`` as the median of ``b / (N^T v0) - 1`` over the moving contacts, or takes 1 when
        the dump has no ``b``.

    Returns
    -------
    ImpactProblem
        The problem of family ``dump``, with ``Q``, ``b`` and the dumped solutions in
        ``data`` and the dump's flags and times in ``metadata``.

    Raises
    ------
    InputError
        When the file cannot be read, an entry is missing or malformed, ``Minv`` is not
        diagonal, ``b`` is not ``(1 + CoR) N^T v0`` for one CoR in [0, 1], or the problem is
        invalid (:meth:`ImpactProblem.validate`).
    """
    file = str(path)
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(file, f"cannot read dump ({error})") from error
    layout = "json" if text.lstrip().startswith("{") else "text"
    matrices, scalars = (_parse_json if layout == "json" else _parse_text)(file, text)
    for name in REQUIRED:
        if name not in matrices:
            raise InputError(file, "missing entry", name)
    G = sp.csc_matrix(matrices["N"])
    dofs, contacts = G.shape
    m_inv_matrix = matrices["Minv"].tocsr()
    if m_inv_matrix.shape != (dofs, dofs):
        raise InputError(file, f"is {m_inv_matrix.shape}, N has {dofs} rows", "Minv", "shape")
    if sp.triu(m_inv_matrix, 1).nnz or sp.tril(m_inv_matrix, -1).nnz:
        raise InputError(file, "must be diagonal", "Minv", "data")
    v_minus = _dense(file, matrices, "v0", (dofs, 1)).ravel()
    u_minus = G.T @ v_minus
    kept: dict[str, np.ndarray] = {}
    if "b" in matrices:
        kept["b"] = _dense(file, matrices, "b", (contacts, 1)).ravel()
    if restitution is None:
        restitution = 1.0
        if "b" in kept:
            moving = np.abs(u_minus) > 1e-6 * max(float(np.max(np.abs(u_minus))), 1e-300)
            if np.any(moving):
                restitution = float(np.median(kept["b"][moving] / u_minus[moving] - 1.0))
                if -1e-8 <= restitution <= 1.0 + 1e-8:  # printed digits only
                    restitution = min(max(restitution, 0.0), 1.0)
            mismatch = np.max(np.abs(kept["b"] - (1.0 + restitution) * u_minus), initial=0.0)
            if mismatch > 1e-8 * max(float(np.max(np.abs(kept["b"]))), 1.0) or not (
                0.0 <= restitution <= 1.0
            ):
                raise InputError(file, "is not (1 + CoR) N^T v0 for one CoR in [0, 1]", "b")
    if "Q" in matrices:
        kept["Q"] = _dense(file, matrices, "Q", (contacts, contacts))
    for name in ("ipopt_sol", "policy_sol"):
        if name in matrices:
            kept[name] = _dense(file, matrices, name, (contacts, 1)).ravel()
    m_inv = m_inv_matrix.diagonal()
    rotation_rows = np.arange(2, dofs, 3)
    dofs_per_body = 3 if dofs % 3 == 0 and G[rotation_rows].nnz == 0 else 2
    problem = ImpactProblem(
        name=Path(path).stem,
        G=G,
        m_inv=np.asarray(m_inv, dtype=float),
        v_minus=v_minus,
        restitution=np.full(contacts, float(restitution)),
        n_rel=np.zeros(contacts),
        family="dump",
        source=file,
        dofs_per_body=dofs_per_body,
        metadata={"layout": layout, **{k: _scalar(v) for k, v in scalars.items()}},
        data=kept,
    )
    problem.validate(file)
    return problem
