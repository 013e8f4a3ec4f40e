"""Siconos' problems (qpbench.problem.siconos_files) as qpbench problems.

* ``fc2d`` (W, q, mu) -> :class:`ReducedFrictionalProblem`, W and q permuted from Siconos'
  per-contact order ``(N_0, T_0, N_1, ...)`` to ``(l_N, l_T)``;
* ``gfc2d`` (M, H, q, b, mu; ``M v = q + H r``, ``u = H^T v + b``) -> :class:`FrictionalProblem`
  with ``M^-1 = diag(M)^-1`` (M must be diagonal), ``G = H``'s normal columns, ``T`` its
  tangent columns, ``v- = M^-1 q`` (the free velocity), restitution 0, ``n_rel = b_N`` and
  ``d_rel = b_T``: then ``q_N = G^T v- + b_N`` and ``q_T = T^T v- + b_T`` as Siconos' local
  velocity, and ``v+ = v- + M^-1 H r`` is its v;
* ``lcp`` (M, q) -> an :class:`ImpactProblem` with ``Q = M`` when M is symmetric positive
  semi-definite: ``G = diag(sqrt(lambda)) V^T`` over M's nonzero eigenpairs, unit masses,
  ``v-`` the least-squares solution of ``G^T v- = q`` and ``n_rel = q - G^T v-`` (so
  ``b = q``), restitution 0. Any other M is a general LCP, refused in one line
  (:class:`UnsupportedError`) saying why: qpbench has no problem kind for it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError, UnsupportedError
from qpbench.problem import siconos_files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import ReducedFrictionalProblem, interleaved_order

AnyImported = ImpactProblem | FrictionalProblem
FAMILY = "siconos"
# relative tolerances of the PSD test of an LCP's M (of max |M_ij|)
SYMMETRY_TOLERANCE = 1e-12
EIGENVALUE_TOLERANCE = 1e-10


def local_problem(name: str, W: sp.spmatrix, q: np.ndarray, mu: np.ndarray, source: str,
                  family: str = FAMILY) -> ReducedFrictionalProblem:
    """The reduced problem of W, q (Siconos' and FCLIB's per-contact order) and mu.

    Parameters
    ----------
    name : str
        The problem's name.
    W : sp.spmatrix
        The Delassus matrix, 2n x 2n, in the order ``(N_0, T_0, N_1, ...)``.
    q : np.ndarray
        The free velocity, 2n entries in the same order.
    mu : np.ndarray
        Friction coefficients, n entries.
    source : str
        The file, named in errors and kept as the problem's source.
    family : str, optional
        The problem's family; :data:`FAMILY` by default.

    Returns
    -------
    ReducedFrictionalProblem
        The problem in qpbench's order ``(l_N, l_T)``.

    Raises
    ------
    InputError
        When the sizes do not fit n contacts, or as
        :meth:`ReducedFrictionalProblem.from_local`.
    """
    n = mu.shape[0]
    if W.shape[0] != 2 * n or q.shape[0] != W.shape[0]:
        raise InputError(source, f"W is {W.shape[0]} x {W.shape[1]} and q has {q.shape[0]} "
                         f"entries, expected {2 * n} for {n} contacts", attribute="W")
    order = interleaved_order(n)
    W = sp.csr_matrix(W)[order][:, order]
    return ReducedFrictionalProblem.from_local(
        name, W, q[order], mu, family=family, source=source,
        metadata={"format": "reduced", "origin": family}, where=source)


def global_problem(name: str, M: sp.spmatrix, H: sp.spmatrix, q: np.ndarray, b: np.ndarray,
                   mu: np.ndarray, source: str, family: str = FAMILY) -> FrictionalProblem:
    """The frictional problem of ``M v = q + H r``, ``u = H^T v + b`` (module docstring).

    Parameters
    ----------
    name : str
        The problem's name.
    M : sp.spmatrix
        The mass matrix, diagonal with positive entries, dofs x dofs.
    H : sp.spmatrix
        dofs x 2n, columns in the per-contact order ``(N_0, T_0, N_1, ...)``.
    q : np.ndarray
        The momentum term, dofs entries (``v- = M^-1 q``).
    b : np.ndarray
        The local velocity offset, 2n entries in per-contact order.
    mu : np.ndarray
        Friction coefficients, n entries.
    source : str
        The file, named in errors and kept as the problem's source.
    family : str, optional
        The problem's family; :data:`FAMILY` by default.

    Returns
    -------
    FrictionalProblem
        The problem with restitution 0, ``n_rel = b_N`` and ``d_rel = b_T``.

    Raises
    ------
    InputError
        When M is not diagonal or has a non-positive diagonal entry, or the problem is invalid.
    """
    M = sp.csc_matrix(M)
    if sp.triu(M, 1).nnz or sp.tril(M, -1).nnz:
        off = sp.csr_matrix(M - sp.diags(M.diagonal()))
        off.eliminate_zeros()
        if off.nnz:
            raise InputError(source, "must be diagonal (qpbench's masses are a diagonal M)",
                             attribute="M")
    diagonal = M.diagonal()
    if np.any(diagonal <= 0):
        raise InputError(source, "must have positive diagonal entries", attribute="M")
    H = sp.csc_matrix(H)
    m_inv = 1.0 / diagonal
    dofs = M.shape[0]
    return FrictionalProblem.build(
        name, H[:, 0::2], H[:, 1::2], m_inv, m_inv * q, mu, 0.0, b[0::2], b[1::2],
        family=family, source=source, dofs_per_body=3 if dofs % 3 == 0 else 2,
        metadata={"format": "global", "origin": family})


def lcp_problem(name: str, M: np.ndarray, q: np.ndarray, source: str,
                family: str = FAMILY) -> ImpactProblem:
    """The impact problem with ``Q = M``, ``b = q`` (module docstring).

    UnsupportedError naming the file when M is not symmetric positive semi-definite.

    Parameters
    ----------
    name : str
        The problem's name.
    M : np.ndarray
        The LCP's matrix, dense, n x n.
    q : np.ndarray
        The LCP's vector, n entries.
    source : str
        The file, named in errors and kept as the problem's source.
    family : str, optional
        The problem's family; :data:`FAMILY` by default.

    Returns
    -------
    ImpactProblem
        The problem, with M and q kept in ``data`` and the size and rank in ``metadata``.

    Raises
    ------
    UnsupportedError
        When M is not symmetric (within SYMMETRY_TOLERANCE) or has a negative eigenvalue
        (beyond EIGENVALUE_TOLERANCE), relative to max |M_ij|.
    """
    largest = max(float(np.max(np.abs(M), initial=0.0)), 1e-300)
    asymmetry = float(np.max(np.abs(M - M.T), initial=0.0)) / largest
    if asymmetry > SYMMETRY_TOLERANCE:
        raise UnsupportedError(f"{source}: M is not symmetric (max |M - M^T| / max |M| = "
                               f"{asymmetry:.1e}): a general LCP, not an impact QP; qpbench "
                               "has no problem kind for general LCPs")
    symmetric = 0.5 * (M + M.T)
    eigenvalues, vectors = np.linalg.eigh(symmetric)
    if eigenvalues.size and eigenvalues[0] < -EIGENVALUE_TOLERANCE * largest:
        raise UnsupportedError(f"{source}: M is not positive semi-definite (smallest "
                               f"eigenvalue {eigenvalues[0]:.3g}): a general LCP, not an "
                               "impact QP; qpbench has no problem kind for general LCPs")
    kept = eigenvalues > EIGENVALUE_TOLERANCE * largest
    G = sp.csc_matrix(np.sqrt(eigenvalues[kept])[:, None] * vectors[:, kept].T)
    G.data[np.abs(G.data) < 1e-300] = 0.0
    G.eliminate_zeros()
    n = q.shape[0]
    v_minus = np.linalg.lstsq(G.T.toarray(), q, rcond=None)[0] if G.shape[0] else np.zeros(0)
    n_rel = q - G.T @ v_minus
    problem = ImpactProblem.build(name, G, np.ones(G.shape[0]), v_minus, 0.0, n_rel,
                                  family=family, source=source, dofs_per_body=1,
                                  metadata={"format": "lcp", "origin": family,
                                            "lcp_size": n, "rank": int(kept.sum())})
    problem.data["M"] = np.asarray(M, dtype=float)
    problem.data["q"] = np.asarray(q, dtype=float)
    return problem


def import_siconos(path: str | Path, kind: str | None = None) -> AnyImported:
    """The qpbench problem of one Siconos file; its kind from ``kind`` or the file name.

    Parameters
    ----------
    path : str or Path
        The file; its stem names the problem.
    kind : str or None, optional
        ``fc2d``, ``gfc2d`` or ``lcp``; None (the default) tells it from the file name
        (:func:`~qpbench.problem.siconos_files.kind_of_file`).

    Returns
    -------
    ImpactProblem or FrictionalProblem
        A reduced frictional problem for ``fc2d``, a frictional one for ``gfc2d``, an impact
        problem for ``lcp``.

    Raises
    ------
    InputError
        When the kind is unknown or the file is malformed.
    UnsupportedError
        When an LCP's M is not symmetric positive semi-definite.
    """
    source = str(path)
    kind = kind or siconos_files.kind_of_file(path)
    name = Path(path).stem
    if kind == "fc2d":
        local = siconos_files.read_local(path)
        return local_problem(name, local.W, local.q, local.mu, source)
    if kind == "gfc2d":
        data = siconos_files.read_global(path)
        return global_problem(name, data.M, data.H, data.q, data.b, data.mu, source)
    if kind == "lcp":
        lcp = siconos_files.read_lcp(path)
        return lcp_problem(name, lcp.M, lcp.q, source)
    raise InputError(source, f"unknown kind {kind!r} (known: {', '.join(siconos_files.KINDS)})")
