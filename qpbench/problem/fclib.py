"""FCLIB's HDF5 files of frictional contact problems, written and read with h5py.

The layout is FCLIB's (FrictionalContactLibrary/fclib, ``fclib.h`` and ``fclib.c``):

* ``/fclib_local``: ``spacedim`` (int, 2 here), ``W`` as FCLIB's sparse struct (a group of
  one-element int datasets ``nzmax``, ``m``, ``n``, ``nz`` — ``-1`` for compressed columns —
  and the arrays ``p`` (n + 1 column pointers), ``i`` (row indices) and ``x`` (values)),
  ``vectors/q`` and ``vectors/mu``, and ``info/title``, ``info/description``,
  ``info/math_info`` (strings);
* ``/fclib_global``: ``spacedim``, ``M`` and ``H`` as sparse structs, ``vectors/f``,
  ``vectors/w``, ``vectors/mu`` and ``info``, for ``M v = H r + f``, ``u = H^T v + w``;
* ``/solution``: ``r`` and ``u`` (and ``v`` for a global problem), written only for a
  reference that solves the problem to a Coulomb residual of 1e-12.

Contacts are ``(N, T)`` pairs side by side, as in Siconos. A frictionless problem is written
as a global one with mu = 0 and zero tangent columns. Reading takes compressed-column and
triplet matrices (``nz >= 0``); ``spacedim = 3`` is refused (qpbench is 2D), and so is a file
without either group. Every fault names the file and the dataset.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError
from qpbench.problem.friction import REFERENCE_RESIDUAL, FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import ReducedFrictionalProblem, interleaved_order
from qpbench.problem.siconos_import import global_problem, local_problem

SUFFIX = ".hdf5"
FAMILY = "fclib"
AnyProblem = ImpactProblem | FrictionalProblem


def _h5py() -> Any:
    import h5py  # an optional third-party backend: imported where it is used

    return h5py


# --- writing -----------------------------------------------------------------------------------
def _write_matrix(group: Any, matrix: sp.spmatrix) -> None:
    csc = sp.csc_matrix(matrix)
    csc.sort_indices()
    for key, value in (("nzmax", csc.nnz), ("m", csc.shape[0]), ("n", csc.shape[1]),
                       ("nz", -1)):
        group.create_dataset(key, data=np.array([value], dtype=np.int32))
    group.create_dataset("p", data=csc.indptr.astype(np.int32))
    group.create_dataset("i", data=csc.indices.astype(np.int32))
    group.create_dataset("x", data=csc.data.astype(np.float64))


def _write_info(group: Any, problem: AnyProblem, math_info: str) -> None:
    info = group.create_group("info")
    info.create_dataset("title", data=problem.name)
    info.create_dataset("description", data=f"qpbench {problem.family or 'problem'} "
                        f"{problem.name} (source: {problem.source or 'generated'})")
    info.create_dataset("math_info", data=math_info)


def _interleaved(n: int) -> np.ndarray:
    """qpbench's entry k goes to FCLIB's entry inverse[k]."""
    return np.argsort(interleaved_order(n))


def local_arrays(problem: FrictionalProblem) -> tuple[sp.csc_matrix, np.ndarray]:
    """W and q in FCLIB's per-contact order.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem, in qpbench's order ``(l_N, l_T)``.

    Returns
    -------
    W : sp.csc_matrix
        The Delassus matrix permuted to ``(N_0, T_0, N_1, ...)``, 2n x 2n.
    q : np.ndarray
        The free velocity in that order, shape (2n,).
    """
    order = interleaved_order(problem.n_contacts)
    back = np.argsort(order)
    W = sp.csr_matrix(problem.W)[back][:, back]
    return sp.csc_matrix(W), problem.q[back]


def _reference_solution(problem: AnyProblem) -> np.ndarray | None:
    """The reference impulses r (qpbench's order) when they solve the problem to 1e-12."""
    reference = problem.reference
    if isinstance(problem, FrictionalProblem):
        if reference is not None and reference.solvable and \
                reference.residual <= REFERENCE_RESIDUAL:
            return reference.impulses
        return None
    if reference is not None and reference.verified:
        return np.concatenate([reference.impulses, np.zeros(problem.n_contacts)])
    return None


def _math_info(problem: AnyProblem) -> str:
    reference = problem.reference
    if reference is None:
        return "no reference"
    if isinstance(problem, FrictionalProblem):
        unique = {True: "unique", False: "not unique", None: "uniqueness not proven"}
        return (f"reference by {reference.method}: Coulomb residual {reference.residual:.1e}, "
                f"{unique[reference.unique]}")
    return f"reference by {reference.method} (verified: {reference.verified})"


def write(problem: AnyProblem, path: str | os.PathLike[str]) -> Path:
    """Writes ``problem`` to ``path`` in FCLIB's layout (module docstring).

    A reduced problem is written as ``/fclib_local``; a frictional or frictionless one with
    bodies as ``/fclib_global``.

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem; one with bodies must have finite masses and restitution 0.
    path : str or os.PathLike
        The HDF5 file to create (replaced if it exists).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        When a problem with bodies has a kinematic degree of freedom (m_inv = 0) or a nonzero
        restitution, which FCLIB's global form cannot hold.
    """
    h5py = _h5py()
    path = Path(path)
    solution = _reference_solution(problem)
    with h5py.File(path, "w") as stream:
        if isinstance(problem, ReducedFrictionalProblem):
            top = stream.create_group("fclib_local")
            top.create_dataset("spacedim", data=np.array([2], dtype=np.int32))
            W, q = local_arrays(problem)
            _write_matrix(top.create_group("W"), W)
            vectors = top.create_group("vectors")
            vectors.create_dataset("q", data=q)
            vectors.create_dataset("mu", data=problem.mu)
            _write_info(top, problem, _math_info(problem))
            if solution is not None:
                back = np.argsort(interleaved_order(problem.n_contacts))
                group = stream.create_group("solution")
                group.create_dataset("r", data=solution[back])
                group.create_dataset("u", data=problem.u(solution)[back])
            return path
        frictional = problem if isinstance(problem, FrictionalProblem) else None
        normal = frictional.normal if frictional is not None else problem
        n = normal.n_contacts
        T = frictional.T if frictional is not None else sp.csc_matrix(normal.G.shape)
        mu = frictional.mu if frictional is not None else np.zeros(n)
        d_rel = frictional.d_rel if frictional is not None else np.zeros(n)
        back = np.argsort(interleaved_order(n))
        H = sp.csc_matrix(sp.hstack([normal.G, T]))[:, back]
        if np.any(normal.m_inv <= 0):
            raise InputError(normal.source or normal.name, "a kinematic degree of freedom "
                             "(m_inv = 0) has no finite mass for FCLIB's M", attribute="m_inv")
        mass = 1.0 / normal.m_inv
        # u = H^T v + w with w_N = b / (1 + e) - G^T v- ... written for e = 0 only
        if np.any(normal.restitution != 0):
            raise InputError(normal.source or normal.name, "FCLIB's u = H^T v + w has no "
                             "restitution; only problems with restitution 0 are written",
                             attribute="restitution")
        top = stream.create_group("fclib_global")
        top.create_dataset("spacedim", data=np.array([2], dtype=np.int32))
        _write_matrix(top.create_group("M"), sp.diags(mass))
        _write_matrix(top.create_group("H"), H)
        vectors = top.create_group("vectors")
        vectors.create_dataset("f", data=mass * normal.v_minus)
        vectors.create_dataset("w", data=np.concatenate([normal.n_rel, d_rel])[back])
        vectors.create_dataset("mu", data=mu)
        _write_info(top, problem, _math_info(problem))
        if solution is not None:
            group = stream.create_group("solution")
            impulses = np.asarray(solution, dtype=float)
            v = normal.v_minus + normal.m_inv * (H[:, interleaved_order(n)] @ impulses)
            group.create_dataset("v", data=v)
            group.create_dataset("r", data=impulses[back])
            group.create_dataset("u", data=(H.T @ v) + np.concatenate([normal.n_rel,
                                                                        d_rel])[back])
    return path


# --- reading -----------------------------------------------------------------------------------
def _dataset(file: str, group: Any, key: str, prefix: str) -> np.ndarray:
    if key not in group:
        raise InputError(file, "missing", attribute=f"{prefix}/{key}")
    try:
        values = np.asarray(group[key][()])
    except (TypeError, ValueError, OSError) as error:
        raise InputError(file, f"unreadable dataset ({error})",
                         attribute=f"{prefix}/{key}") from error
    if values.dtype.kind not in "iuf":
        raise InputError(file, f"must be numbers, got {values.dtype}",
                         attribute=f"{prefix}/{key}")
    return values.ravel()


def _integer(file: str, group: Any, key: str, prefix: str) -> int:
    values = _dataset(file, group, key, prefix)
    if values.size != 1 or values.dtype.kind not in "iu":
        raise InputError(file, "must be one integer", attribute=f"{prefix}/{key}")
    return int(values[0])


def _read_matrix(file: str, group: Any, prefix: str) -> sp.csc_matrix:
    """FCLIB's sparse struct (compressed columns, rows, or a triplet) as CSC."""
    m, n = _integer(file, group, "m", prefix), _integer(file, group, "n", prefix)
    nz, nzmax = _integer(file, group, "nz", prefix), _integer(file, group, "nzmax", prefix)
    if min(m, n, nzmax) < 0 or nz < -2:
        raise InputError(file, f"sizes m={m}, n={n}, nzmax={nzmax}, nz={nz} out of range",
                         attribute=prefix)
    p = _dataset(file, group, "p", prefix).astype(np.int64)
    i = _dataset(file, group, "i", prefix).astype(np.int64)
    x = _dataset(file, group, "x", prefix).astype(float)
    if not np.all(np.isfinite(x)):
        raise InputError(file, "contains NaN or infinity", attribute=f"{prefix}/x")
    try:
        if nz >= 0:
            if p.size < nz or i.size < nz or x.size < nz:
                raise ValueError(f"fewer than nz = {nz} triplets")
            matrix = sp.csc_matrix(sp.coo_matrix((x[:nz], (p[:nz], i[:nz])), shape=(m, n)))
        else:
            outer = n if nz == -1 else m
            if p.size != outer + 1 or p[-1] > min(i.size, x.size):
                raise ValueError(f"{p.size} pointers for {outer} vectors and {i.size} indices")
            count = int(p[-1])
            kind = sp.csc_matrix if nz == -1 else sp.csr_matrix
            matrix = sp.csc_matrix(kind((x[:count], i[:count], p), shape=(m, n)))
            matrix.check_format(full_check=True)
    except ValueError as error:
        raise InputError(file, f"not a valid sparse matrix ({error})", attribute=prefix) from error
    return matrix


def _spacedim(file: str, top: Any, prefix: str) -> None:
    dimension = _integer(file, top, "spacedim", prefix)
    if dimension != 2:
        raise InputError(file, f"is {dimension}; qpbench reads 2D problems only (spacedim 2)",
                         attribute=f"{prefix}/spacedim")


def read(path: str | os.PathLike[str]) -> AnyProblem:
    """The problem of an FCLIB file.

    ``/fclib_local`` gives a reduced problem, ``/fclib_global`` a frictional one
    (qpbench.problem.siconos_import's mappings, with FCLIB's ``f`` as Siconos' ``q`` and ``w``
    as its ``b``).

    Parameters
    ----------
    path : str or os.PathLike
        The HDF5 file; its stem names the problem.

    Returns
    -------
    ImpactProblem or FrictionalProblem
        A :class:`ReducedFrictionalProblem` or a :class:`FrictionalProblem` of family
        :data:`FAMILY`.

    Raises
    ------
    InputError
        When the file is missing or not HDF5, has neither group, is not 2D, or a dataset is
        missing, malformed, not finite or of a misfitting size.
    """
    h5py = _h5py()
    file, name = str(path), Path(path).stem
    try:
        stream = h5py.File(path, "r")
    except FileNotFoundError:
        raise InputError(file, "no such file") from None
    except (OSError, ValueError) as error:
        raise InputError(file, f"not an HDF5 file ({error})") from error
    with stream:
        if "fclib_local" in stream:
            top = stream["fclib_local"]
            _spacedim(file, top, "/fclib_local")
            W = _read_matrix(file, _group(file, top, "W", "/fclib_local"), "/fclib_local/W")
            vectors = _group(file, top, "vectors", "/fclib_local")
            q = _dataset(file, vectors, "q", "/fclib_local/vectors").astype(float)
            mu = _dataset(file, vectors, "mu", "/fclib_local/vectors").astype(float)
            _finite(file, "/fclib_local/vectors/q", q)
            _finite(file, "/fclib_local/vectors/mu", mu)
            return local_problem(name, W, q, mu, file, family=FAMILY)
        if "fclib_global" in stream:
            top = stream["fclib_global"]
            _spacedim(file, top, "/fclib_global")
            if "G" in top:
                raise InputError(file, "equality constraints (G, b) are not part of qpbench's "
                                 "model", attribute="/fclib_global/G")
            M = _read_matrix(file, _group(file, top, "M", "/fclib_global"), "/fclib_global/M")
            H = _read_matrix(file, _group(file, top, "H", "/fclib_global"), "/fclib_global/H")
            vectors = _group(file, top, "vectors", "/fclib_global")
            f = _dataset(file, vectors, "f", "/fclib_global/vectors").astype(float)
            w = _dataset(file, vectors, "w", "/fclib_global/vectors").astype(float)
            mu = _dataset(file, vectors, "mu", "/fclib_global/vectors").astype(float)
            for key, values in (("f", f), ("w", w), ("mu", mu)):
                _finite(file, f"/fclib_global/vectors/{key}", values)
            if M.shape[0] != M.shape[1] or H.shape[0] != M.shape[0] or \
                    H.shape[1] != 2 * mu.size or f.size != M.shape[0] or w.size != H.shape[1]:
                raise InputError(file, f"M {M.shape}, H {H.shape}, f {f.size}, w {w.size} and "
                                 f"mu {mu.size} do not fit together", attribute="/fclib_global")
            return global_problem(name, M, H, f, w, mu, file, family=FAMILY)
    raise InputError(file, "has neither /fclib_local nor /fclib_global: not an FCLIB file")


def _group(file: str, top: Any, key: str, prefix: str) -> Any:
    if key not in top or not hasattr(top[key], "keys"):
        raise InputError(file, "missing group", attribute=f"{prefix}/{key}")
    return top[key]


def _finite(file: str, field: str, values: np.ndarray) -> None:
    if not np.all(np.isfinite(values)):
        raise InputError(file, "contains NaN or infinity", attribute=field)


def read_solution(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """The datasets of ``/solution`` (empty when there is none), FCLIB's order.

    Parameters
    ----------
    path : str or os.PathLike
        The HDF5 file.

    Returns
    -------
    dict of str to np.ndarray
        ``r`` and ``u`` (and ``v`` for a global problem) by name.
    """
    h5py = _h5py()
    with h5py.File(path, "r") as stream:
        if "solution" not in stream:
            return {}
        return {key: np.asarray(stream["solution"][key][()]) for key in stream["solution"]}
