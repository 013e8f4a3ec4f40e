"""The impact problem of one collision event: G, M^-1, v-, restitution and nrel.

With n contacts and d degrees of freedom:

* ``G`` (d x n, sparse): column k is the gradient of the gap of contact k;
* ``m_inv`` (d): the diagonal of M^-1 (0 for a kinematic degree of freedom);
* ``v_minus`` (d): velocities before impact;
* ``restitution`` (n): coefficient of restitution c per contact;
* ``n_rel`` (n): normal velocity of moving boundaries (0 when none).

From them: ``Q = G^T M^-1 G`` and ``b = (1 + c) * (G^T v- + nrel)``; the impulses l
solve ``min 1/2 l^T Q l + b^T l, l >= 0`` and give ``v+ = v- + M^-1 G l``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError


@dataclass
class Reference:
    """The verified post-impact velocity of a problem.

    ``v_plus`` comes from ``method``; ``v_plus_check`` from an independent
    ``check_method``; ``agreement = ||v_a - v_b||_M / max(||v-||_M, tiny)``. A
    reference is ``verified`` only when the two agree within ``tolerance``.
    """

    v_plus: np.ndarray
    impulses: np.ndarray
    method: str
    v_plus_check: np.ndarray
    check_method: str
    agreement: float
    tolerance: float

    @property
    def verified(self) -> bool:
        return bool(np.isfinite(self.agreement) and self.agreement <= self.tolerance)


# the largest magnitude of an entry: Q = G^T M^-1 G, b and the energies are products of at
# most three entries (and sums of a few), so they stay inside floating-point range (about 1e308)
LARGEST_ENTRY = 1e90


def check_entries(where: str, label: str, values: np.ndarray) -> None:
    """InputError naming ``label`` unless every value is finite, ``|value| <= LARGEST_ENTRY``.

    Parameters
    ----------
    where : str
        The file (or problem) named in the message.
    label : str
        The field named in the message.
    values : np.ndarray
        The entries to check, of any shape.

    Raises
    ------
    InputError
        When an entry is NaN, infinite or larger in magnitude than LARGEST_ENTRY.
    """
    if not np.all(np.isfinite(values)):
        raise InputError(where, "contains NaN or infinity", attribute=label)
    if np.any(np.abs(values) > LARGEST_ENTRY):
        raise InputError(where, f"magnitudes above {LARGEST_ENTRY:g}", attribute=label)


def check_vector(where: str, label: str, vector: np.ndarray, size: int,
                 matrix_shape: tuple[int, ...]) -> None:
    """InputError naming ``label`` unless ``vector`` has shape (size,) and valid entries.

    The entries must be as :func:`check_entries` wants them; ``matrix_shape`` is G's, named in
    the message.

    Parameters
    ----------
    where : str
        The file (or problem) named in the message.
    label : str
        The field named in the message.
    vector : np.ndarray
        The vector to check.
    size : int
        Its expected length.
    matrix_shape : tuple of int
        The shape of G, quoted when the length does not match.

    Raises
    ------
    InputError
        When the shape is not ``(size,)`` or an entry is invalid.
    """
    if vector.shape != (size,):
        raise InputError(where, f"shape {vector.shape} does not match G {matrix_shape}",
                         attribute=label)
    check_entries(where, label, vector)


@dataclass
class ImpactProblem:
    """One impact event posed as the LCP/QP of simultaneous impact."""

    name: str
    G: sp.csc_matrix
    m_inv: np.ndarray
    v_minus: np.ndarray
    restitution: np.ndarray
    n_rel: np.ndarray
    family: str = ""
    source: str = ""
    dofs_per_body: int = 2
    metadata: dict[str, Any] = field(default_factory=dict)
    data: dict[str, np.ndarray] = field(default_factory=dict)
    reference: Reference | None = None
    # the matrices of each formulation, once built (qpbench.problem.formulations.pose)
    posed: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(
        cls,
        name: str,
        G: Any,
        m_inv: Any,
        v_minus: Any,
        restitution: float | Any = 1.0,
        n_rel: Any | None = None,
        **kwargs: Any,
    ) -> ImpactProblem:
        """Builds a problem, broadcasting a scalar restitution and a missing nrel to n contacts.

        Parameters
        ----------
        name : str
            The problem's name.
        G : array_like or sparse matrix
            Contact gradients, d x n.
        m_inv : array_like
            Diagonal of M^-1, d entries (0 for a kinematic degree of freedom).
        v_minus : array_like
            Velocities before impact, d entries.
        restitution : float or array_like, optional
            Coefficient of restitution, one for all contacts or n; 1 by default.
        n_rel : array_like or None, optional
            Normal velocities of moving boundaries, n entries; None (the default) for zeros.
        **kwargs
            Further fields of :class:`ImpactProblem` (family, source, dofs_per_body, ...).

        Returns
        -------
        ImpactProblem
            The validated problem.

        Raises
        ------
        InputError
            When :meth:`validate` refuses it.
        """
        G = sp.csc_matrix(G, dtype=float)
        n = G.shape[1]
        restitution = np.broadcast_to(np.asarray(restitution, dtype=float), (n,)).copy()
        n_rel = np.zeros(n) if n_rel is None else np.asarray(n_rel, dtype=float).reshape(n)
        problem = cls(
            name=name,
            G=G,
            m_inv=np.asarray(m_inv, dtype=float).ravel(),
            v_minus=np.asarray(v_minus, dtype=float).ravel(),
            restitution=restitution,
            n_rel=n_rel,
            **kwargs,
        )
        problem.validate()
        return problem

    def validate(self, file: str | None = None) -> None:
        """Checks shapes, finite entries and physical ranges; InputError names the field.

        Checks shapes, finite entries of magnitude at most LARGEST_ENTRY, positive inverse masses
        of at least 1 / LARGEST_ENTRY (or 0), 0 <= c <= 1, and a reference of the problem's
        shapes.

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
        d, n = self.G.shape
        check_entries(where, "G", self.G.data)
        for label, vector, size in (
            ("m_inv", self.m_inv, d),
            ("v_minus", self.v_minus, d),
            ("restitution", self.restitution, n),
            ("n_rel", self.n_rel, n),
        ):
            check_vector(where, label, vector, size, self.G.shape)
        if np.any(self.m_inv < 0):
            raise InputError(where, "inverse masses must be >= 0", attribute="m_inv")
        if np.any((self.m_inv > 0) & (self.m_inv < 1.0 / LARGEST_ENTRY)):
            raise InputError(where, f"positive inverse masses must be at least "
                             f"{1.0 / LARGEST_ENTRY:g}", attribute="m_inv")
        if np.any((self.restitution < 0) | (self.restitution > 1)):
            raise InputError(where, "restitution must lie in [0, 1]", attribute="restitution")
        if self.reference is not None:
            for label, vector, size in (("ref_v_plus", self.reference.v_plus, d),
                                        ("ref_impulses", self.reference.impulses, n),
                                        ("ref_v_plus_check", self.reference.v_plus_check, d)):
                check_vector(where, label, vector, size, self.G.shape)

    def blind_copy(self) -> ImpactProblem:
        """What a solver may see: fresh copies of G, M^-1, v-, c and nrel under the same name.

        No reference, no stored data (dumped answers, warm starts), no metadata or family.

        Returns
        -------
        ImpactProblem
            The copy.
        """
        return ImpactProblem(name=self.name, G=self.G.copy(), m_inv=self.m_inv.copy(),
                             v_minus=self.v_minus.copy(), restitution=self.restitution.copy(),
                             n_rel=self.n_rel.copy(), dofs_per_body=self.dofs_per_body)

    def with_velocities_scaled(self, factor: float) -> ImpactProblem:
        """The same contacts with v- and nrel multiplied by ``factor`` > 0.

        G, M^-1, c and the metadata are shared; there is no reference, stored data or posing,
        which belong to the velocities as they were. Q stays and b becomes ``factor * b``, so the
        impulses become ``factor * l`` and v+ becomes ``factor * v+``.

        Parameters
        ----------
        factor : float
            The positive scale of the velocities.

        Returns
        -------
        ImpactProblem
            The scaled problem.
        """
        return replace(self, v_minus=factor * self.v_minus, n_rel=factor * self.n_rel,
                       data={}, reference=None, posed={})

    @property
    def largest_velocity(self) -> float:
        """max(|v-|, |nrel|), 0 when there are none."""
        return float(max(np.max(np.abs(self.v_minus), initial=0.0),
                         np.max(np.abs(self.n_rel), initial=0.0)))

    # --- sizes -----------------------------------------------------------------
    @property
    def n_contacts(self) -> int:
        return int(self.G.shape[1])

    @property
    def n_dofs(self) -> int:
        return int(self.G.shape[0])

    @property
    def n_bodies(self) -> int:
        return self.n_dofs // max(self.dofs_per_body, 1)

    # --- derived matrices --------------------------------------------------------
    @cached_property
    def M_inv_G(self) -> sp.csc_matrix:
        """M^-1 G (d x n)."""
        return sp.csc_matrix(sp.diags(self.m_inv) @ self.G)

    @cached_property
    def Q(self) -> sp.csc_matrix:
        """Q = G^T M^-1 G, symmetric positive semi-definite (n x n)."""
        Q = sp.csc_matrix(self.G.T @ self.M_inv_G)
        Q = sp.csc_matrix(0.5 * (Q + Q.T))
        Q.sort_indices()
        return Q

    @cached_property
    def L(self) -> sp.csc_matrix:
        """L = M^-1/2 G, so that Q = L^T L."""
        return sp.csc_matrix(sp.diags(np.sqrt(self.m_inv)) @ self.G)

    @cached_property
    def b(self) -> np.ndarray:
        """b = (1 + c) * (G^T v- + nrel), elementwise in c."""
        return (1.0 + self.restitution) * (self.G.T @ self.v_minus + self.n_rel)

    @cached_property
    def diag_Q(self) -> np.ndarray:
        """D = diag(Q)."""
        return np.asarray(self.Q.diagonal()).ravel()

    @cached_property
    def mass(self) -> np.ndarray:
        """The diagonal of M (infinite where m_inv = 0)."""
        with np.errstate(divide="ignore"):
            return np.where(self.m_inv > 0, 1.0 / np.where(self.m_inv > 0, self.m_inv, 1.0), np.inf)

    # --- maps of the impulses --------------------------------------------------
    def v_plus(self, impulses: np.ndarray) -> np.ndarray:
        """v+ = v- + M^-1 G l.

        Parameters
        ----------
        impulses : np.ndarray
            The normal impulses l, shape (n,).

        Returns
        -------
        np.ndarray
            The post-impact velocities, shape (d,).
        """
        return self.v_minus + self.M_inv_G @ impulses

    def w(self, impulses: np.ndarray) -> np.ndarray:
        """w = Q l + b (the LCP slack: post-impact normal velocities, scaled).

        Parameters
        ----------
        impulses : np.ndarray
            The normal impulses l, shape (n,).

        Returns
        -------
        np.ndarray
            The slack w, shape (n,).
        """
        return self.Q @ impulses + self.b

    def kinetic_energy(self, velocity: np.ndarray) -> float:
        """KE = 1/2 v^T M v over the degrees of freedom with finite mass.

        Parameters
        ----------
        velocity : np.ndarray
            Velocities of the degrees of freedom, shape (d,).

        Returns
        -------
        float
            The kinetic energy.
        """
        finite = self.m_inv > 0
        return float(0.5 * np.sum(velocity[finite] ** 2 / self.m_inv[finite]))

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
        return float(np.sqrt(2.0 * self.kinetic_energy(velocity)))

    # --- structure -----------------------------------------------------------------
    @cached_property
    def rank_deficiency(self) -> int:
        """n - numerical rank of Q (from the singular values of L = M^-1/2 G); -1 if too large."""
        if self.n_contacts == 0:
            return 0
        if self.n_contacts > 2500:
            return -1
        singular = np.linalg.svd(self.L.toarray(), compute_uv=False)
        if singular.size == 0 or singular[0] == 0.0:
            return self.n_contacts
        tol = max(self.L.shape) * np.finfo(float).eps * singular[0]
        return int(self.n_contacts - np.count_nonzero(singular > tol))

    def summary(self) -> dict[str, Any]:
        """Name, family, source, bodies, contacts, nnz of Q and rank deficiency.

        Returns
        -------
        dict of str to Any
            Keys ``problem``, ``family``, ``source``, ``bodies``, ``contacts``, ``nnz`` and
            ``rank_deficiency``.
        """
        return {
            "problem": self.name,
            "family": self.family,
            "source": self.source,
            "bodies": self.n_bodies,
            "contacts": self.n_contacts,
            "nnz": int(self.Q.nnz),
            "rank_deficiency": self.rank_deficiency,
        }
