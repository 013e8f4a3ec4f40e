"""The frictional impact problem of one collision event (docs/design.md section 8).

Per contact k: normal n_k (column k of G, as in :class:`ImpactProblem`), tangent
``t_k = (-n_y, n_x)`` (column k of T; a rigid body's rotation row carries the arm term
``r x t``), friction coefficient ``mu_k``, restitution ``e_k``, and the kinematic velocities
``n_rel_k`` (normal) and ``d_rel_k`` (tangential). With ``H = [G T]`` and ``r = (l_N, l_T)``:

* ``W = H^T M^-1 H`` (2n x 2n, symmetric positive semi-definite);
* ``q = (q_N, q_T)``, ``q_N = (1 + e)(G^T v- + n_rel)`` (the frictionless ``b``) and
  ``q_T = T^T v- + d_rel`` (no tangential restitution);
* ``u = W r + q`` and ``v+ = v- + M^-1 (G l_N + T l_T)``.

The law (2D Coulomb with Newton restitution), per contact:
``0 <= l_N  _|_  u_N >= 0``, ``|l_T| <= mu l_N``, stick (``u_T = 0``) while
``|l_T| < mu l_N``, and ``l_T = -mu l_N sign(u_T)`` when sliding.

A :class:`FrictionalProblem` holds the frictionless problem of its normals (``normal``, an
:class:`ImpactProblem`: G, M^-1, v-, e, n_rel) and adds T, mu and d_rel. Impulses are one
vector ``r = (l_N, l_T)`` of 2n entries. Derived views give the problems that frictionless
solvers take unchanged: :meth:`FrictionalProblem.relaxed` (Anitescu's convex relaxation, in
2D an ordinary ``z >= 0`` impact problem), :meth:`FrictionalProblem.normal_given` (the normal
QP of staggered projections for a fixed l_T) and :meth:`FrictionalProblem.friction_box` (its
friction QP for a fixed l_N).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError
from qpbench.problem.impact import ImpactProblem, check_entries, check_vector
from qpbench.problem.metrics import vector_scale

KIND = "frictional"
MODELS = ("coulomb", "ccp")  # the exact law, and Anitescu's relaxation (sliding separates)


def model_of(formulation: str) -> str:
    """The model a frictional formulation's answers are judged by.

    Parameters
    ----------
    formulation : str
        A frictional formulation (``qpbench.problem.formulations.FRICTIONAL_FORMULATIONS``).

    Returns
    -------
    str
        ``ccp`` (Anitescu's relaxation) for ``ccp``; ``coulomb`` (the exact law) for every
        other: ``staggered``, ``lcp``, ``nsgs`` and ``fc2d`` solve the same law.
    """
    return "ccp" if formulation == "ccp" else "coulomb"


@dataclass
class FrictionalReference:
    """The verified answer of a frictional problem.

    ``impulses`` (r = (l_N, l_T)) comes from ``method`` and reaches a Coulomb residual of
    ``residual``; ``unique`` says whether the enumeration of contact states found exactly one
    solution (``None`` where it was not run), and only then is ``v_plus`` comparable: v+ of
    a frictional problem need not be unique. ``solvable`` is False where no solution exists
    (a wedged contact with e > 0), which no solver is charged for.
    """

    impulses: np.ndarray
    v_plus: np.ndarray
    method: str
    residual: float
    unique: bool | None
    solvable: bool = True

    @property
    def verified(self) -> bool:
        """A solution to 1e-12 that is the only one: v_error can be computed against it."""
        return bool(self.solvable and self.unique and self.residual <= REFERENCE_RESIDUAL)


REFERENCE_RESIDUAL = 1e-12


@dataclass
class FrictionalProblem:
    """One frictional impact event: the normal problem plus tangents, mu and d_rel."""

    normal: ImpactProblem
    T: sp.csc_matrix
    mu: np.ndarray
    d_rel: np.ndarray
    reference: FrictionalReference | None = None
    posed: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, name: str, G: Any, T: Any, m_inv: Any, v_minus: Any, mu: float | Any,
              restitution: float | Any = 0.0, n_rel: Any | None = None,
              d_rel: Any | None = None, **kwargs: Any) -> FrictionalProblem:
        """Builds a problem, broadcasting scalars and missing kinematic terms to n contacts.

        Scalars (mu, restitution) and missing kinematic terms (n_rel, d_rel) are broadcast to n
        contacts; InputError names the field at fault.

        Parameters
        ----------
        name : str
            The problem's name.
        G, T : array_like or sparse matrix
            Contact normals and tangents, each d x n (rotation rows carry the arm terms).
        m_inv : array_like
            Diagonal of M^-1, d entries (0 for a kinematic degree of freedom).
        v_minus : array_like
            Velocities before impact, d entries.
        mu : float or array_like
            Friction coefficients, one for all contacts or n, each >= 0.
        restitution : float or array_like, optional
            Coefficients of restitution e, one or n; 0 by default.
        n_rel, d_rel : array_like or None, optional
            Normal and tangential velocities of moving boundaries, n entries each; None (the
            default) for zeros.
        **kwargs
            Further fields of the normal :class:`ImpactProblem` (family, source, ...).

        Returns
        -------
        FrictionalProblem
            The validated problem.

        Raises
        ------
        InputError
            When :meth:`validate` refuses it.
        """
        normal = ImpactProblem.build(name, G, m_inv, v_minus, restitution, n_rel, **kwargs)
        n = normal.n_contacts
        problem = cls(
            normal=normal,
            T=sp.csc_matrix(T, dtype=float),
            mu=np.broadcast_to(np.asarray(mu, dtype=float), (n,)).copy(),
            d_rel=np.zeros(n) if d_rel is None else np.asarray(d_rel, dtype=float).reshape(n),
        )
        problem.validate()
        return problem

    def validate(self, file: str | None = None) -> None:
        """The normal problem's checks, plus checks of T, mu, d_rel and the reference.

        T must have G's shape with entries as G's, mu must be >= 0 and d_rel of one entry per
        contact, and a reference must have the problem's shapes.

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
        self.normal.validate(file)
        where = file or self.normal.source or self.normal.name
        if self.T.shape != self.normal.G.shape:
            raise InputError(where, f"shape {self.T.shape} does not match G {self.normal.G.shape}",
                             attribute="T")
        check_entries(where, "T", self.T.data)
        d, n = self.normal.G.shape
        for label, vector, size in (("mu", self.mu, n), ("d_rel", self.d_rel, n)):
            check_vector(where, label, vector, size, self.normal.G.shape)
        if np.any(self.mu < 0):
            raise InputError(where, "friction coefficients must be >= 0", attribute="mu")
        if self.reference is not None:
            for label, vector, size in (("fref_impulses", self.reference.impulses, 2 * n),
                                        ("fref_v_plus", self.reference.v_plus, d)):
                check_vector(where, label, vector, size, self.normal.G.shape)

    # --- what it shares with the normal problem ------------------------------------------
    @property
    def name(self) -> str:
        return self.normal.name

    @property
    def family(self) -> str:
        return self.normal.family

    @property
    def source(self) -> str:
        return self.normal.source

    @property
    def metadata(self) -> dict[str, Any]:
        return self.normal.metadata

    @property
    def data(self) -> dict[str, np.ndarray]:
        return self.normal.data

    @property
    def n_contacts(self) -> int:
        return self.normal.n_contacts

    @property
    def n_bodies(self) -> int:
        return self.normal.n_bodies

    @property
    def G(self) -> sp.csc_matrix:
        return self.normal.G

    @property
    def m_inv(self) -> np.ndarray:
        return self.normal.m_inv

    @property
    def v_minus(self) -> np.ndarray:
        return self.normal.v_minus

    @property
    def restitution(self) -> np.ndarray:
        return self.normal.restitution

    @property
    def mu_max(self) -> float:
        return float(np.max(self.mu, initial=0.0))

    def contact_graph(self) -> sp.csr_matrix:
        """Contacts k, j are adjacent when a body of finite mass carries both.

        Then W's 2x2 block (k, j) may be nonzero.

        Returns
        -------
        sp.csr_matrix
            n x n, nonzero at (k, j) when contacts k and j are adjacent (the diagonal included
            for a contact on a body of finite mass).
        """
        pattern = (abs(self.normal.G) + abs(self.T)).tocsc()
        pattern.data[:] = 1.0
        moving = sp.diags((self.m_inv > 0).astype(float))
        return sp.csr_matrix(pattern.T @ moving @ pattern)

    def blind_copy(self) -> FrictionalProblem:
        """What a solver may see (as :meth:`ImpactProblem.blind_copy`).

        Fresh arrays, no reference, no stored data.

        Returns
        -------
        FrictionalProblem
            The copy.
        """
        return FrictionalProblem(normal=self.normal.blind_copy(), T=self.T.copy(),
                                 mu=self.mu.copy(), d_rel=self.d_rel.copy())

    def with_velocities_scaled(self, factor: float) -> FrictionalProblem:
        """The same contacts with v-, nrel and d_rel multiplied by ``factor`` > 0.

        See :meth:`ImpactProblem.with_velocities_scaled`. Coulomb's law is positively
        homogeneous, so the impulses become ``factor * r``.

        Parameters
        ----------
        factor : float
            The positive scale of the velocities.

        Returns
        -------
        FrictionalProblem
            The scaled problem, sharing T and mu.
        """
        return FrictionalProblem(normal=self.normal.with_velocities_scaled(factor), T=self.T,
                                 mu=self.mu, d_rel=factor * self.d_rel)

    @property
    def largest_velocity(self) -> float:
        """max(|v-|, |nrel|, |d_rel|), 0 when there are none."""
        return max(self.normal.largest_velocity, float(np.max(np.abs(self.d_rel), initial=0.0)))

    # --- derived matrices ----------------------------------------------------------------
    @cached_property
    def H(self) -> sp.csc_matrix:
        """H = [G T] (d x 2n): normals first, then tangents, in contact order."""
        return sp.csc_matrix(sp.hstack([self.normal.G, self.T]))

    @cached_property
    def M_inv_H(self) -> sp.csc_matrix:
        """M^-1 H."""
        return sp.csc_matrix(sp.diags(self.m_inv) @ self.H)

    @cached_property
    def W(self) -> sp.csc_matrix:
        """W = H^T M^-1 H, symmetrized (2n x 2n)."""
        W = sp.csc_matrix(self.H.T @ self.M_inv_H)
        W = sp.csc_matrix(0.5 * (W + W.T))
        W.sort_indices()
        return W

    @cached_property
    def W_TT(self) -> sp.csc_matrix:
        """W_TT = T^T M^-1 T, the tangential block of W (n x n): the friction QP's matrix,
        its indices sorted."""
        n = self.n_contacts
        W_TT = sp.csc_matrix(sp.csr_matrix(self.W)[n:, n:])
        W_TT.sort_indices()
        return W_TT

    @cached_property
    def W_NT(self) -> sp.csr_matrix:
        """W_NT = G^T M^-1 T, the block of W that couples l_T into the normal QP (n x n)."""
        n = self.n_contacts
        return sp.csr_matrix(self.W)[:n, n:]

    @cached_property
    def W_TN(self) -> sp.csr_matrix:
        """W_TN = T^T M^-1 G, the block of W that couples l_N into the friction QP (n x n)."""
        n = self.n_contacts
        return sp.csr_matrix(self.W)[n:, :n]

    @cached_property
    def q(self) -> np.ndarray:
        """q = ((1 + e)(G^T v- + n_rel), T^T v- + d_rel)."""
        return np.concatenate([self.normal.b, self.T.T @ self.v_minus + self.d_rel])

    @cached_property
    def diag_N(self) -> np.ndarray:
        """d = diag(W_NN) = diag(Q): the velocity-per-impulse of each contact's normal."""
        return self.normal.diag_Q

    @cached_property
    def scale(self) -> float:
        """max(||q_N||_inf, ||q_T||_inf over contacts with mu > 0, tiny): at mu = 0 it is the
        frictionless scale ``max(||b||_inf, tiny)``, so both residuals agree there."""
        n = self.n_contacts
        return vector_scale(np.concatenate([self.q[:n], self.q[n:][self.mu > 0]]))

    # --- maps of the impulses ----------------------------------------------------------------
    def split(self, impulses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(l_N, l_T) of r = (l_N, l_T).

        Parameters
        ----------
        impulses : np.ndarray
            r, shape (2n,).

        Returns
        -------
        l_N : np.ndarray
            The normal impulses, shape (n,).
        l_T : np.ndarray
            The tangential impulses, shape (n,).
        """
        n = self.n_contacts
        impulses = np.asarray(impulses, dtype=float)
        return impulses[:n], impulses[n:]

    def v_plus(self, impulses: np.ndarray) -> np.ndarray:
        """v+ = v- + M^-1 (G l_N + T l_T).

        Parameters
        ----------
        impulses : np.ndarray
            r = (l_N, l_T), shape (2n,).

        Returns
        -------
        np.ndarray
            The post-impact velocities, shape (d,).
        """
        return self.v_minus + self.M_inv_H @ np.asarray(impulses, dtype=float)

    def u(self, impulses: np.ndarray) -> np.ndarray:
        """u = W r + q.

        That is (u_N, u_T), the post-impact normal (with e u_N-) and tangential relative
        velocities.

        Parameters
        ----------
        impulses : np.ndarray
            r = (l_N, l_T), shape (2n,).

        Returns
        -------
        np.ndarray
            u = (u_N, u_T), shape (2n,).
        """
        return self.W @ np.asarray(impulses, dtype=float) + self.q

    def kinetic_energy(self, velocity: np.ndarray) -> float:
        """KE = 1/2 v^T M v over the degrees of freedom with finite mass (the normal problem's).

        Parameters
        ----------
        velocity : np.ndarray
            Velocities of the degrees of freedom, shape (d,).

        Returns
        -------
        float
            The kinetic energy.
        """
        return self.normal.kinetic_energy(velocity)

    def m_norm(self, velocity: np.ndarray) -> float:
        """||v||_M = sqrt(v^T M v) over the degrees of freedom with finite mass.

        Parameters
        ----------
        velocity : np.ndarray
            Velocities of the degrees of freedom, shape (d,).

        Returns
        -------
        float
            The mass norm of ``velocity``.
        """
        return self.normal.m_norm(velocity)

    # --- the views that frictionless solvers take ------------------------------------------------
    def relaxed(self) -> ImpactProblem:
        """Anitescu's relaxation as an impact problem in z = (z+, z-) >= 0 (2n contacts).

        Its columns are ``n + mu t`` and ``n - mu t``, so that ``l_N = z+ + z-``,
        ``l_T = mu (z+ - z-)`` and its ``b`` is ``q_N +- mu q_T``, written with the same
        restitution e and a shifted n_rel (:func:`relaxed_n_rel`). Built once.

        Returns
        -------
        ImpactProblem
            The relaxed problem, kept in ``posed["ccp"]``.
        """
        if "ccp" not in self.posed:
            G, T, mu = self.normal.G, self.T, self.mu
            columns = sp.hstack([G + T @ sp.diags(mu), G - T @ sp.diags(mu)], format="csc")
            e = self.restitution
            self.posed["ccp"] = ImpactProblem(
                name=self.name, G=sp.csc_matrix(columns), m_inv=self.m_inv,
                v_minus=self.v_minus, restitution=np.concatenate([e, e]),
                n_rel=relaxed_n_rel(self), dofs_per_body=self.normal.dofs_per_body)
        return self.posed["ccp"]

    def from_relaxed(self, z: np.ndarray) -> np.ndarray:
        """r = (z+ + z-, mu (z+ - z-)) from the relaxed problem's z.

        Parameters
        ----------
        z : np.ndarray
            The impulses of :meth:`relaxed`, (z+, z-), shape (2n,).

        Returns
        -------
        np.ndarray
            r = (l_N, l_T), shape (2n,).
        """
        n = self.n_contacts
        z = np.asarray(z, dtype=float)
        plus, minus = z[:n], z[n:]
        return np.concatenate([plus + minus, self.mu * (plus - minus)])

    def normal_given(self, tangential: np.ndarray) -> ImpactProblem:
        """The normal QP of staggered projections for a fixed l_T.

        The impact problem with ``b + W_NT l_T``, written as
        ``n_rel + (G^T M^-1 T l_T) / (1 + e)``; its ``b`` is formed as ``q_N + W_NT l_T``
        (``W_NT = G^T M^-1 T``, a block of W).

        Parameters
        ----------
        tangential : np.ndarray
            The fixed tangential impulses l_T, shape (n,).

        Returns
        -------
        ImpactProblem
            The normal problem with the shifted ``b``.
        """
        shift = self.W_NT @ tangential
        normal = self.normal
        sub = ImpactProblem(name=normal.name, G=normal.G, m_inv=normal.m_inv,
                            v_minus=normal.v_minus, restitution=normal.restitution,
                            n_rel=normal.n_rel + shift / (1.0 + normal.restitution),
                            dofs_per_body=normal.dofs_per_body)
        sub.__dict__["b"] = self.q[:self.n_contacts] + shift  # the cached property, set
        return sub

    def friction_box(self, normal_impulses: np.ndarray
                     ) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray, np.ndarray]:
        """The friction QP of staggered projections for a fixed l_N.

        ``min 1/2 l_T^T W_TT l_T + (q_T + W_TN l_N)^T l_T,  -mu l_N <= l_T <= mu l_N``, as
        (W_TT, linear term, lower, upper).

        Parameters
        ----------
        normal_impulses : np.ndarray
            The fixed normal impulses l_N, shape (n,); negative entries count as 0 in the bounds.

        Returns
        -------
        W_TT : sp.csc_matrix
            The QP's matrix, n x n.
        linear : np.ndarray
            ``q_T + W_TN l_N``, shape (n,).
        lower, upper : np.ndarray
            ``-mu max(l_N, 0)`` and ``mu max(l_N, 0)``, shape (n,) each.
        """
        n = self.n_contacts
        linear = self.q[n:] + self.W_TN @ normal_impulses
        bound = self.mu * np.maximum(normal_impulses, 0.0)
        return self.W_TT, np.asarray(linear, dtype=float), -bound, bound

    def stewart_trinkle(self) -> tuple[np.ndarray, np.ndarray]:
        """The exact 2D problem as one LCP (Stewart-Trinkle).

        ``z = (l_N, b+, b-, s) >= 0``, ``l_T = b+ - b-``, ``w = A z + c >= 0``, ``z^T w = 0``:
        rows ``u_N``, ``s + u_T``, ``s - u_T``, ``mu l_N - b+ - b-`` (dense A, 4n x 4n).

        Returns
        -------
        A : np.ndarray
            The LCP matrix, dense, 4n x 4n.
        c : np.ndarray
            The LCP vector ``(q_N, q_T, -q_T, 0)``, shape (4n,).
        """
        n = self.n_contacts
        W = self.W.toarray()
        NN, NT, TN, TT = W[:n, :n], W[:n, n:], W[n:, :n], W[n:, n:]
        identity, zero = np.eye(n), np.zeros((n, n))
        A = np.block([
            [NN, NT, -NT, zero],
            [TN, TT, -TT, identity],
            [-TN, -TT, TT, identity],
            [np.diag(self.mu), -identity, -identity, zero],
        ])
        q_N, q_T = self.split(self.q)
        c = np.concatenate([q_N, q_T, -q_T, np.zeros(n)])
        return A, c

    def from_stewart_trinkle(self, z: np.ndarray) -> np.ndarray:
        """r = (l_N, b+ - b-) from the Stewart-Trinkle unknowns.

        Parameters
        ----------
        z : np.ndarray
            The unknowns (l_N, b+, b-, s) of :meth:`stewart_trinkle`, shape (4n,).

        Returns
        -------
        np.ndarray
            r = (l_N, l_T), shape (2n,).
        """
        n = self.n_contacts
        return np.concatenate([z[:n], z[n:2 * n] - z[2 * n:3 * n]])

    def summary(self) -> dict[str, Any]:
        """The normal problem's summary, plus mu_max and the kind.

        Returns
        -------
        dict of str to Any
            The keys of :meth:`ImpactProblem.summary`, plus ``mu_max`` and ``kind``.
        """
        return {**self.normal.summary(), "mu_max": self.mu_max, "kind": KIND}


def relaxed_n_rel(problem: FrictionalProblem) -> np.ndarray:
    """The n_rel of the relaxed columns ``n +- mu t`` that gives them the right ``b``.

    Their ``b = (1 + e)((n +- mu t)^T v- + n_rel')`` equals ``q_N +- mu q_T`` with
    ``n_rel' = n_rel +- mu (d_rel - e t^T v-) / (1 + e)``.

    Parameters
    ----------
    problem : FrictionalProblem
        The problem being relaxed.

    Returns
    -------
    np.ndarray
        n_rel' of the ``n + mu t`` columns, then of the ``n - mu t`` columns, shape (2n,).
    """
    e = problem.restitution
    tangential = problem.T.T @ problem.v_minus
    shift = problem.mu * (problem.d_rel - e * tangential) / (1.0 + e)
    n_rel = problem.normal.n_rel
    return np.concatenate([n_rel + shift, n_rel - shift])


def kind_of(problem: ImpactProblem | FrictionalProblem) -> str:
    """``frictional`` or ``impact``: which solvers a problem is offered to (SolverSpec.kinds).

    Parameters
    ----------
    problem : ImpactProblem or FrictionalProblem
        The problem.

    Returns
    -------
    str
        ``frictional`` for a :class:`FrictionalProblem` (reduced ones too), else ``impact``.
    """
    return KIND if isinstance(problem, FrictionalProblem) else "impact"
