"""The reduced ("local") form of a 2D frictional problem: W, q and mu, without bodies.

Siconos' ``fc2d`` files and FCLIB's ``/fclib_local`` give a frictional contact problem by its
Delassus matrix ``W`` (2n x 2n), free velocity ``q`` and friction coefficients ``mu``; the
bodies, masses and Jacobians that made ``W`` are gone. A
:class:`ReducedFrictionalProblem` is a :class:`FrictionalProblem` whose ``W`` and ``q`` are
given instead of formed from ``H^T M^-1 H``, in qpbench's order ``r = (l_N, l_T)``. Every
formulation that needs only W runs on it unchanged: ``nsgs`` and ``fc2d`` read W and q,
``lcp`` builds Stewart-Trinkle's LCP from W, and the QPs of ``ccp`` and ``staggered`` are
posed as :class:`GivenQP` (``Q``, ``b`` given): ``ccp``'s ``Q = E^T W E``, ``b = E^T q`` with
``r = E z``, ``E = [[I, I], [diag(mu), -diag(mu)]]``; ``staggered``'s normal QP
``Q = W_NN``, ``b = q_N + W_NT l_T``.

It has no degrees of freedom: ``v+`` is empty, the kinetic energy is not known
(``energy_gain`` is NaN) and no ``v_error`` is computed. Its normal problem (``normal``) is an
:class:`ImpactProblem` with no rows: ``G^T v- = 0`` and ``n_rel = q_N`` (so ``b = q_N``), its
``Q`` set to ``W_NN``; the tangents carry ``d_rel = q_T``. Its problem files have the kind
``frictional-reduced``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError
from qpbench.problem.friction import KIND as FULL_KIND
from qpbench.problem.friction import FrictionalProblem, FrictionalReference
from qpbench.problem.impact import ImpactProblem, check_entries, check_vector

KIND = "frictional-reduced"
# the ``kind`` of a frictional problem in a results table: full (bodies, H, M) or reduced
FRICTIONAL_KINDS = (FULL_KIND, KIND)
# W is symmetrized on import; a larger asymmetry than this (relative to max |W_ij|) is not a
# Delassus matrix printed with rounding but another operator, and is refused
ASYMMETRY_LIMIT = 1e-3


@dataclass
class GivenQP:
    """An impact QP known only by ``Q`` (symmetric PSD, n x n) and ``b``: the problem that the
    frictionless solvers of ``dual`` and ``lcp`` take (they read Q, b and diag(Q)). It has no
    bodies (no G, M^-1 or v-), so no solver can take a factored or velocity-space path."""

    name: str
    Q: sp.csc_matrix
    b: np.ndarray
    posed: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    data: dict[str, np.ndarray] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    reference: None = None

    @property
    def n_contacts(self) -> int:
        return int(self.b.shape[0])

    @cached_property
    def diag_Q(self) -> np.ndarray:
        return np.asarray(self.Q.diagonal()).ravel()

    def w(self, impulses: np.ndarray) -> np.ndarray:
        """w = Q l + b.

        Parameters
        ----------
        impulses : np.ndarray
            The impulses l, shape (n,).

        Returns
        -------
        np.ndarray
            The slack w, shape (n,).
        """
        return self.Q @ impulses + self.b

    def blind_copy(self) -> GivenQP:
        """What a solver may see: fresh copies of Q and b under the same name, nothing stored.

        Returns
        -------
        GivenQP
            The copy.
        """
        return GivenQP(name=self.name, Q=self.Q.copy(), b=self.b.copy())


def _no_bodies(name: str, W_NN: sp.csc_matrix, q_normal: np.ndarray, **fields: Any
               ) -> ImpactProblem:
    """The normal problem of a reduced one: no rows, ``n_rel = q_N`` and ``Q`` set to W_NN."""
    n = q_normal.shape[0]
    normal = ImpactProblem(name=name, G=sp.csc_matrix((0, n)), m_inv=np.zeros(0),
                           v_minus=np.zeros(0), restitution=np.zeros(n),
                           n_rel=np.asarray(q_normal, dtype=float), **fields)
    W_NN = sp.csc_matrix(W_NN)
    W_NN.sort_indices()
    normal.__dict__["Q"] = W_NN  # the cached property, set: Q = W_NN, not G^T M^-1 G
    return normal


@dataclass
class ReducedFrictionalProblem(FrictionalProblem):
    """A frictional problem given by W (2n x 2n, order ``(l_N, l_T)``), q (2n) and mu (n)."""

    given_W: sp.csc_matrix = field(default_factory=lambda: sp.csc_matrix((0, 0)))

    @classmethod
    def from_local(cls, name: str, W: Any, q: Any, mu: Any, family: str = "",
                   source: str = "", metadata: dict[str, Any] | None = None,
                   reference: FrictionalReference | None = None,
                   where: str | None = None) -> ReducedFrictionalProblem:
        """The problem of ``W``, ``q``, ``mu`` (qpbench's order).

        W is symmetrized (its asymmetry ``max|W - W^T| / max|W|`` kept in the metadata as
        ``w_asymmetry``). InputError names ``where`` (the file) and the field at fault.

        Parameters
        ----------
        name : str
            The problem's name.
        W : array_like or sparse matrix
            The Delassus matrix, 2n x 2n, in the order ``(l_N, l_T)``.
        q : array_like
            The free velocity (q_N, q_T), 2n entries.
        mu : array_like
            Friction coefficients, n entries, each >= 0.
        family, source : str, optional
            The problem's family and the file it came from; empty by default.
        metadata : dict of str to Any or None, optional
            Further facts to keep; None (the default) for none.
        reference : FrictionalReference or None, optional
            A known answer; None by default.
        where : str or None, optional
            The file named in a message; None (the default) names ``source``, else ``name``.

        Returns
        -------
        ReducedFrictionalProblem
            The problem.

        Raises
        ------
        InputError
            When W is not square of even size, has a non-finite or too large entry, is not
            symmetric within ASYMMETRY_LIMIT or has a negative diagonal entry, or when q or mu
            has the wrong size or mu a negative entry.
        """
        where = where or source or name
        W = sp.csc_matrix(W, dtype=float)
        q = np.asarray(q, dtype=float).ravel()
        mu = np.asarray(mu, dtype=float).ravel()
        if W.shape[0] != W.shape[1]:
            raise InputError(where, f"must be square, got {W.shape[0]} x {W.shape[1]}",
                             attribute="W")
        if W.shape[0] % 2:
            raise InputError(where, f"size {W.shape[0]} is not 2 per contact", attribute="W")
        check_entries(where, "W", W.data)
        n = W.shape[0] // 2
        check_vector(where, "q", q, 2 * n, W.shape)
        check_vector(where, "mu", mu, n, W.shape)
        if np.any(mu < 0):
            raise InputError(where, "friction coefficients must be >= 0", attribute="mu")
        largest = float(np.max(np.abs(W.data), initial=0.0))
        asymmetry = float(np.max(np.abs((W - W.T).data), initial=0.0)) / max(largest, 1e-300)
        if asymmetry > ASYMMETRY_LIMIT:
            raise InputError(where, f"is not symmetric (max |W - W^T| / max |W| = "
                             f"{asymmetry:.1e}): not a Delassus matrix", attribute="W")
        W = sp.csc_matrix(0.5 * (W + W.T))
        W.sort_indices()
        diagonal = W.diagonal()
        if np.any(diagonal < 0):
            raise InputError(where, "has a negative diagonal entry: not positive "
                             "semi-definite", attribute="W")
        info = dict(metadata or {})
        info["w_asymmetry"] = max(asymmetry, float(info.get("w_asymmetry", 0.0)))
        normal = _no_bodies(name, W[:n, :n], q[:n], family=family, source=source,
                            metadata=info)
        return cls(normal=normal, T=sp.csc_matrix((0, n)), mu=mu, d_rel=q[n:].copy(),
                   reference=reference, given_W=W)

    def validate(self, file: str | None = None) -> None:
        """W square of 2n, finite; q of 2n, mu of n, mu >= 0; a reference of 2n impulses.

        Parameters
        ----------
        file : str or None, optional
            The file named in a message; None (the default) names the problem's source, else its
            name.

        Raises
        ------
        InputError
            When a check fails.
        """
        where = file or self.source or self.name
        n = self.n_contacts
        if self.given_W.shape != (2 * n, 2 * n):
            raise InputError(where, f"shape {self.given_W.shape} does not match {n} contacts",
                             attribute="W")
        check_entries(where, "W", self.given_W.data)
        check_vector(where, "q", self.q, 2 * n, self.given_W.shape)
        check_vector(where, "mu", self.mu, n, self.given_W.shape)
        if np.any(self.mu < 0):
            raise InputError(where, "friction coefficients must be >= 0", attribute="mu")
        if self.reference is not None:
            check_vector(where, "fref_impulses", self.reference.impulses, 2 * n,
                         self.given_W.shape)

    @property
    def n_contacts(self) -> int:
        return int(self.mu.shape[0])

    @property
    def n_bodies(self) -> int:
        return 0

    @cached_property
    def W(self) -> sp.csc_matrix:
        return self.given_W

    @cached_property
    def q(self) -> np.ndarray:
        return np.concatenate([self.normal.n_rel, self.d_rel])

    @property
    def H(self) -> sp.csc_matrix:  # type: ignore[override]
        raise AttributeError("a reduced frictional problem has no H (only W, q, mu)")

    @property
    def M_inv_H(self) -> sp.csc_matrix:  # type: ignore[override]
        raise AttributeError("a reduced frictional problem has no M^-1 H (only W, q, mu)")

    def v_plus(self, impulses: np.ndarray) -> np.ndarray:
        """Empty: the problem has no degrees of freedom.

        Parameters
        ----------
        impulses : np.ndarray
            r = (l_N, l_T), unused.

        Returns
        -------
        np.ndarray
            An empty array.
        """
        return np.zeros(0)

    def kinetic_energy(self, velocity: np.ndarray) -> float:
        """0: without bodies the kinetic energy is not known.

        Parameters
        ----------
        velocity : np.ndarray
            Unused (v+ is empty).

        Returns
        -------
        float
            0.0.
        """
        return 0.0

    def m_norm(self, velocity: np.ndarray) -> float:
        """0: without bodies there is no mass norm.

        Parameters
        ----------
        velocity : np.ndarray
            Unused (v+ is empty).

        Returns
        -------
        float
            0.0.
        """
        return 0.0

    @property
    def largest_velocity(self) -> float:
        """max |q|."""
        return float(np.max(np.abs(self.q), initial=0.0))

    def contact_graph(self) -> sp.csr_matrix:
        """Contacts k, j are adjacent when W's 2x2 block (k, j) has an entry.

        Returns
        -------
        sp.csr_matrix
            n x n, nonzero at (k, j) when contacts k and j are adjacent.
        """
        n = self.n_contacts
        W = sp.coo_matrix(self.W)
        return sp.csr_matrix((np.ones(W.nnz), (W.row % n, W.col % n)), shape=(n, n))

    def blind_copy(self) -> ReducedFrictionalProblem:
        """What a solver may see: the problem of W, q and mu alone, no reference or stored data.

        Returns
        -------
        ReducedFrictionalProblem
            The copy, with fresh arrays.
        """
        return ReducedFrictionalProblem.from_local(self.name, self.W.copy(), self.q.copy(),
                                                   self.mu.copy())

    def with_velocities_scaled(self, factor: float) -> ReducedFrictionalProblem:
        """The same W with q multiplied by ``factor`` > 0: the impulses become ``factor r``.

        Parameters
        ----------
        factor : float
            The positive scale of q.

        Returns
        -------
        ReducedFrictionalProblem
            The scaled problem (no reference).
        """
        return ReducedFrictionalProblem.from_local(self.name, self.W, factor * self.q, self.mu,
                                                   self.family, self.source,
                                                   dict(self.metadata))

    def relaxed(self) -> GivenQP:  # type: ignore[override]
        """Anitescu's relaxation in z = (z+, z-): ``Q = E^T W E``, ``b = E^T q``.

        See the module docstring. Built once.

        Returns
        -------
        GivenQP
            The relaxed QP (2n unknowns), kept in ``posed["ccp"]``.
        """
        if "ccp" not in self.posed:
            n = self.n_contacts
            identity, friction = sp.identity(n, format="csc"), sp.diags(self.mu)
            E = sp.csc_matrix(sp.bmat([[identity, identity], [friction, -friction]]))
            Q = sp.csc_matrix(E.T @ self.W @ E)
            Q = sp.csc_matrix(0.5 * (Q + Q.T))
            Q.sort_indices()
            self.posed["ccp"] = GivenQP(name=self.name, Q=Q, b=E.T @ self.q)
        return self.posed["ccp"]

    def normal_given(self, tangential: np.ndarray) -> GivenQP:  # type: ignore[override]
        """Staggered projections' normal QP for a fixed l_T: ``Q = W_NN``, ``b = q_N + W_NT l_T``.

        Parameters
        ----------
        tangential : np.ndarray
            The fixed tangential impulses l_T, shape (n,).

        Returns
        -------
        GivenQP
            The normal QP.
        """
        n = self.n_contacts
        return GivenQP(name=self.name, Q=self.normal.Q, b=self.q[:n] + self.W_NT @ tangential)

    def summary(self) -> dict[str, Any]:
        """Name, family, source, contacts, nnz of W, mu_max and the kind.

        Returns
        -------
        dict of str to Any
            Keys ``problem``, ``family``, ``source``, ``bodies`` (0), ``contacts``, ``nnz``,
            ``mu_max`` and ``kind``.
        """
        return {"problem": self.name, "family": self.family, "source": self.source,
                "bodies": 0, "contacts": self.n_contacts, "nnz": int(self.W.nnz),
                "mu_max": self.mu_max, "kind": KIND}


def reduced_subproblem(problem: ReducedFrictionalProblem, contacts: np.ndarray
                       ) -> ReducedFrictionalProblem:
    """The contacts ``contacts`` of ``problem`` alone.

    W's rows and columns of their normals and tangents, q's entries and their mu.

    Parameters
    ----------
    problem : ReducedFrictionalProblem
        The whole problem.
    contacts : np.ndarray
        Indices of the contacts to keep, integers in increasing order, not empty.

    Returns
    -------
    ReducedFrictionalProblem
        The subproblem, named ``NAME[FIRST..]``.
    """
    n = problem.n_contacts
    rows = np.concatenate([contacts, n + contacts])
    W = sp.csr_matrix(problem.W)[rows][:, rows]
    return ReducedFrictionalProblem.from_local(f"{problem.name}[{contacts[0]}..]", W,
                                               problem.q[rows], problem.mu[contacts])


def interleaved_order(n: int) -> np.ndarray:
    """The permutation from Siconos' and FCLIB's per-contact order to qpbench's.

    From ``(N_0, T_0, N_1, T_1, ...)`` to ``(N_0..N_n-1, T_0..T_n-1)``: qpbench's entry k is
    their entry order[k].

    Parameters
    ----------
    n : int
        The number of contacts.

    Returns
    -------
    np.ndarray
        ``order``, integers of shape (2n,).
    """
    return np.concatenate([2 * np.arange(n), 2 * np.arange(n) + 1])
