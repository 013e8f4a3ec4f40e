"""The 2,020-contact granular problem of Siconos' fc2d files, solved at 1e-6 and checked
independently: import -> nsgs at 1e-6 -> FCLIB export -> W, q, mu read back with h5py ->
2D Coulomb's law by a De Saxce natural map written here (Acary, Bremond and Huber)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.cli import main
from qpbench.problem import files
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "siconos" / "fc2d"
GRANULAR = sorted(SHARED.glob("fc2d_granularflowonwall_02020_*.dat")) if SHARED.is_dir() \
    else []
ACCURACY = 1e-6

pytestmark = [pytest.mark.shared, pytest.mark.slow,
              pytest.mark.skipif(not GRANULAR, reason="../shared/siconos/fc2d is missing")]


def fclib_local(path: Path) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """W, q and mu of an FCLIB file's ``/fclib_local``, read with h5py alone (W from FCLIB's
    compressed-column struct ``m n p i x``)."""
    with h5py.File(path, "r") as stream:
        local = stream["fclib_local"]
        assert int(local["spacedim"][0]) == 2
        m, n = int(local["W/m"][0]), int(local["W/n"][0])
        W = sp.csc_matrix((local["W/x"][()], local["W/i"][()], local["W/p"][()]), shape=(m, n))
        return W, local["vectors/q"][()], local["vectors/mu"][()]


def cone_projection(x_normal: np.ndarray, x_tangent: np.ndarray, mu: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The Euclidean projection on the 2D cone ``{|x_T| <= mu x_N}``: x itself inside, 0 in
    the polar cone ``{mu |x_T| <= -x_N}``, else the foot on the edge ``(1, mu sign x_T)``."""
    edge = np.array([np.ones_like(mu), mu]) / np.sqrt(1.0 + mu * mu)
    along = (x_normal * edge[0] + np.abs(x_tangent) * edge[1]).clip(min=0.0)
    inside = np.abs(x_tangent) <= mu * x_normal
    return (np.where(inside, x_normal, along * edge[0]),
            np.where(inside, x_tangent, along * edge[1] * np.sign(x_tangent)))


def de_saxce_map(W: sp.spmatrix, q: np.ndarray, mu: np.ndarray, r: np.ndarray,
                 weight: np.ndarray) -> np.ndarray:
    """Per contact (FCLIB's order, normal then tangent) ``w r - P_K(w r - u^)``: u = W r + q,
    De Saxce's ``u^ = (u_N + mu |u_T|, u_T)``, w a positive weight per contact. Its zeros are
    exactly the solutions of Coulomb's law."""
    u = W @ r + q
    r_normal, r_tangent = r[0::2], r[1::2]
    u_hat_normal, u_tangent = u[0::2] + mu * np.abs(u[1::2]), u[1::2]
    p_normal, p_tangent = cone_projection(weight * r_normal - u_hat_normal,
                                          weight * r_tangent - u_tangent, mu)
    F = np.empty_like(r)
    F[0::2], F[1::2] = weight * r_normal - p_normal, weight * r_tangent - p_tangent
    return F


def test_the_2020_contact_granular_problem_is_solved_at_1e_6_and_obeys_coulombs_law(
        tmp_path: Path) -> None:
    assert main(["import-siconos", str(GRANULAR[0]), "--no-reference",
                 "-o", str(tmp_path / "problems")]) == 0
    stored = tmp_path / "problems" / f"{GRANULAR[0].stem}.npz"
    problem = files.load(stored)
    assert problem.n_contacts == 2020
    row, output = solve_and_judge(get("nsgs", "frictional"), problem, ACCURACY)
    assert row["status"] == "solved" and row["coulomb_residual"] <= ACCURACY

    assert main(["export", str(stored), "--format", "fclib", "-o", str(tmp_path / "fclib")]) == 0
    W, q, mu = fclib_local(tmp_path / "fclib" / f"{GRANULAR[0].stem}.hdf5")
    n = mu.shape[0]
    r = np.empty(2 * n)  # qpbench's (l_N, l_T) to FCLIB's per-contact pairs
    r[0::2], r[1::2] = output.impulses[:n], output.impulses[n:]

    # FCLIB's MERIT_1: the unweighted map, ||F||_2 / (1 + ||q||_2)
    merit = np.linalg.norm(de_saxce_map(W, q, mu, r, np.ones(n))) / (1.0 + np.linalg.norm(q))
    assert merit <= ACCURACY
    # the accuracy asked, recomputed from the file: weights diag(W_NN), max norm over the
    # largest |q| (every mu > 0 here)
    assert np.all(mu > 0)
    weighted = de_saxce_map(W, q, mu, r, W.diagonal()[0::2])
    assert np.max(np.abs(weighted)) / np.max(np.abs(q)) <= ACCURACY
    # Coulomb's law itself, to the same accuracy: r in the cone, u_N >= 0, and a sliding
    # contact's impulse on the edge opposing the slip
    tolerance = ACCURACY * np.max(np.abs(q))
    u = W @ r + q
    assert np.min(r[0::2]) >= 0.0 and np.min(u[0::2]) >= -tolerance
    assert np.max(np.abs(r[1::2]) - mu * r[0::2]) <= tolerance / W.diagonal().min()
