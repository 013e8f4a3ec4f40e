"""FCLIB's HDF5 layout out (``export --format fclib``) and in (``import-fclib``)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from qpbench.bench.reduced_reference import attach
from qpbench.cli import main
from qpbench.errors import InputError
from qpbench.problem import fclib, files
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.friction_generate import generate as generate_frictional
from qpbench.problem.friction_metrics import fclib_merit, project_on_cone
from qpbench.problem.reduced import ReducedFrictionalProblem
from qpbench.problem.siconos_import import import_siconos

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "siconos"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/siconos is missing")
# fclib.h: struct fclib_matrix's fields, and the groups fclib.c writes
MATRIX_FIELDS = {"nzmax", "m", "n", "nz", "p", "i", "x"}


def coulomb_map(W: np.ndarray, q: np.ndarray, mu: np.ndarray, r: np.ndarray) -> float:
    """An independent check, in FCLIB's per-contact order (N, T pairs): the largest
    |r_k - P_K(r_k - u^_k)| over contacts, u = W r + q, u^ = (u_N + mu |u_T|, u_T)."""
    u = W @ r + q
    normal, tangential = r[0::2], r[1::2]
    u_normal, u_tangential = u[0::2] + mu * np.abs(u[1::2]), u[1::2]
    pn, pt = project_on_cone(normal - u_normal, tangential - u_tangential, mu)
    return float(max(np.max(np.abs(normal - pn)), np.max(np.abs(tangential - pt))))


def small_reduced() -> ReducedFrictionalProblem:
    return ReducedFrictionalProblem.from_local(
        "small", np.array([[2.0, 0.1, 0.5, 0.0], [0.1, 2.0, 0.0, 0.4],
                           [0.5, 0.0, 1.0, 0.0], [0.0, 0.4, 0.0, 1.0]]),
        np.array([-1.0, -0.5, 0.3, -0.6]), np.array([0.5, 0.2]))


def test_a_reduced_problem_is_written_in_fclibs_layout_and_read_back(tmp_path: Path) -> None:
    problem = attach(small_reduced())
    path = fclib.write(problem, tmp_path / "small.hdf5")
    with h5py.File(path, "r") as stream:
        local = stream["fclib_local"]
        assert int(local["spacedim"][0]) == 2
        assert set(local["W"]) == MATRIX_FIELDS and int(local["W/nz"][0]) == -1
        assert set(local["vectors"]) == {"q", "mu"}
        assert set(local["info"]) == {"title", "description", "math_info"}
        W = np.zeros((4, 4))
        p, i, x = local["W/p"][()], local["W/i"][()], local["W/x"][()]
        for column in range(4):
            W[i[p[column]:p[column + 1]], column] = x[p[column]:p[column + 1]]
        q, mu = local["vectors/q"][()], local["vectors/mu"][()]
        r = stream["solution/r"][()]
    # (N, T) pairs: contact 0's normal, then its tangent
    assert W[0, 1] == pytest.approx(0.5) and q[1] == pytest.approx(0.3)
    assert coulomb_map(W, q, mu, r) <= 1e-10
    back = fclib.read(path)
    np.testing.assert_allclose(back.W.toarray(), problem.W.toarray())
    np.testing.assert_allclose(back.q, problem.q)
    assert fclib_merit(back, problem.reference.impulses) <= 1e-10


def test_a_global_frictional_problem_round_trips(tmp_path: Path) -> None:
    problem = next(iter(generate_frictional("incline", count=1, seed=0)))
    problem.normal.restitution[:] = 0.0
    path = fclib.write(problem, tmp_path / "incline.hdf5")
    back = fclib.read(path)
    assert isinstance(back, FrictionalProblem) and "fclib_global" in h5py.File(path, "r")
    np.testing.assert_allclose(back.W.toarray(), problem.W.toarray(), atol=1e-12)
    np.testing.assert_allclose(back.q, problem.q, atol=1e-12)


def test_3d_and_files_without_fclib_groups_are_refused(tmp_path: Path) -> None:
    path = fclib.write(small_reduced(), tmp_path / "three.hdf5")
    with h5py.File(path, "a") as stream:
        stream["fclib_local/spacedim"][0] = 3
    with pytest.raises(InputError, match="spacedim.*2D"):
        fclib.read(path)
    other = tmp_path / "other.hdf5"
    with h5py.File(other, "w") as stream:
        stream.create_dataset("x", data=np.zeros(2))
    with pytest.raises(InputError, match="neither /fclib_local nor /fclib_global"):
        fclib.read(other)
    text = tmp_path / "text.hdf5"
    text.write_text("not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        fclib.read(text)


def test_a_nan_in_an_fclib_file_names_the_dataset(tmp_path: Path) -> None:
    path = fclib.write(small_reduced(), tmp_path / "nan.hdf5")
    with h5py.File(path, "a") as stream:
        stream["fclib_local/vectors/q"][0] = np.nan
    with pytest.raises(InputError, match="/fclib_local/vectors/q"):
        fclib.read(path)


def test_export_and_import_fclib_commands_round_trip(tmp_path: Path) -> None:
    files.save(small_reduced(), tmp_path / "in" / "small")
    assert main(["export", str(tmp_path / "in"), "--format", "fclib",
                 "-o", str(tmp_path / "fc")]) == 0
    assert main(["import-fclib", str(tmp_path / "fc" / "small.hdf5"), "--no-reference",
                 "-o", str(tmp_path / "back")]) == 0
    back = files.load(tmp_path / "back" / "small.npz")
    np.testing.assert_allclose(back.W.toarray(), small_reduced().W.toarray())


def test_import_fclib_of_a_bad_file_writes_nothing(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    bad = tmp_path / "bad.hdf5"
    with h5py.File(bad, "w") as stream:
        stream.create_group("fclib_local").create_dataset("spacedim", data=[2])
    assert main(["import-fclib", str(bad), "-o", str(tmp_path / "out")]) == 2
    assert "/fclib_local/W" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@needs_shared
@pytest.mark.shared
def test_shared_fc2d_problems_round_trip_through_fclib(tmp_path: Path) -> None:
    for path in sorted((SHARED / "fc2d").glob("*.dat")):
        if "07002" in path.name:
            continue
        problem = import_siconos(path)
        back = fclib.read(fclib.write(problem, tmp_path / f"{problem.name}.hdf5"))
        np.testing.assert_allclose(back.W.toarray(), problem.W.toarray(), atol=1e-12)
        np.testing.assert_allclose(back.q, problem.q, atol=1e-12)
        np.testing.assert_array_equal(back.mu, problem.mu)
