"""Siconos' text files in: fc2d (W, q, mu), gfc2d (M, H, q, b, mu) and LCPs (n, M, q)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from qpbench.cli import main
from qpbench.errors import InputError, UnsupportedError
from qpbench.problem import files, friction_metrics
from qpbench.problem.description import describe
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.problem.reduced import ReducedFrictionalProblem
from qpbench.problem.siconos_import import import_siconos
from qpbench.solvers.registry import get
from qpbench.solvers.run import solve_and_judge

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "siconos"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/siconos is missing")

# one contact: W = [[2, 0.5], [0.5, 1]] in Siconos' (N, T) order, q = (-1, 0.3), mu = 0.5,
# written as a dense NumericsMatrix (column-major)
SMALL_FC2D = """2
1
0
2
2
2\t2
2 0.5
0.5 1
-1 0.3
0.5
"""

# the same W as a sparse (CSC) NumericsMatrix
SPARSE_FC2D = """2
1
2
2
2
1
CSparse Version 3.1.9, May 4, 2016.  Copyright (c) Timothy A. Davis, 2006-2016
2-by-2, nzmax: 4 nnz: 4, 1-norm: 2.5
    col 0 : locations 0 to 1
      0 : 2
      1 : 0.5
    col 1 : locations 2 to 3
      0 : 0.5
      1 : 1
-1 0.3
0.5
"""


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def test_a_dense_and_a_sparse_fc2d_file_give_the_same_reduced_problem(tmp_path: Path) -> None:
    dense = import_siconos(write(tmp_path, "fc2d_dense.dat", SMALL_FC2D))
    sparse = import_siconos(write(tmp_path, "fc2d_sparse.dat", SPARSE_FC2D))
    assert isinstance(dense, ReducedFrictionalProblem)
    np.testing.assert_array_equal(dense.W.toarray(), [[2, 0.5], [0.5, 1]])
    np.testing.assert_array_equal(dense.W.toarray(), sparse.W.toarray())
    np.testing.assert_array_equal(dense.q, [-1, 0.3])
    # its solution: stick would need |l_T| <= mu l_N; nsgs finds it, judged on W alone
    row, output = solve_and_judge(get("nsgs", "frictional"), dense, 1e-10)
    assert row["status"] == "solved"
    assert np.isnan(row["energy_gain"]) and np.isnan(row["v_error"])


def test_a_reduced_problem_runs_with_every_formulation_that_needs_only_W(tmp_path: Path
                                                                         ) -> None:
    problem = import_siconos(write(tmp_path, "fc2d_small.dat", SMALL_FC2D))
    for name in ("nsgs/nsgs", "lemke/lcp", "pgs/ccp", "pgs/staggered"):
        row, _ = solve_and_judge(get(name, "frictional"), problem, 1e-8)
        assert row["status"] == "solved", name


def test_a_reduced_problem_file_round_trips(tmp_path: Path) -> None:
    problem = import_siconos(write(tmp_path, "fc2d_small.dat", SMALL_FC2D))
    loaded = files.load(files.save(problem, tmp_path / "small"))
    assert isinstance(loaded, ReducedFrictionalProblem)
    np.testing.assert_array_equal(loaded.W.toarray(), problem.W.toarray())
    np.testing.assert_array_equal(loaded.q, problem.q)


@pytest.mark.parametrize(("text", "field"), [
    (SMALL_FC2D[:20], "W.entries"),                          # truncated in W
    (SMALL_FC2D[:-5], "mu"),                                 # truncated in mu
    (SMALL_FC2D.replace("2\n1\n0", "2\n2\n0", 1), "W"),       # wrong contact count
    (SMALL_FC2D.replace("-1 0.3", "nan 0.3"), "q"),          # NaN
    (SMALL_FC2D.replace("2\n2\n2\t2", "2\n3\n2\t3", 1), "W"),  # not square
    (SMALL_FC2D.replace("2\n1\n0", "3\n1\n0", 1), "dimension"),    # 3D
    (SPARSE_FC2D.replace("col 1", "col 2"), "W.col"),
])
def test_bad_fc2d_files_are_one_line_naming_the_field(tmp_path: Path, text: str,
                                                      field: str) -> None:
    with pytest.raises(InputError, match=f"'{field}"):
        import_siconos(write(tmp_path, "fc2d_bad.dat", text))


def test_a_psd_lcp_is_an_impact_problem_and_a_general_one_is_refused(tmp_path: Path) -> None:
    psd = import_siconos(write(tmp_path, "lcp_psd.dat", "2\n0\n2\n2\n2\t2\n2 1\n1 2\n-5 -6\n"))
    assert isinstance(psd, ImpactProblem)
    np.testing.assert_allclose(psd.Q.toarray(), [[2, 1], [1, 2]], atol=1e-12)
    np.testing.assert_allclose(psd.b, [-5, -6], atol=1e-12)
    with pytest.raises(UnsupportedError, match="not symmetric"):
        import_siconos(write(tmp_path, "lcp_general.dat", "2\n0\n2\n2\n2\t2\n1 2\n0 1\n-1 -1\n"))


def test_a_global_problem_maps_onto_bodies(tmp_path: Path) -> None:
    # one ball (2 dofs, mass 2) on the floor: M v = q + H r, u = H^T v + b
    text = ("2\n1\n0\n2\n2\n2\t2\n2 0\n0 2\n0\n2\n2\n2\t2\n0 1\n1 0\n"
            "0 -4\n0 0\n0.3\n")
    problem = import_siconos(write(tmp_path, "gfc2d_ball.dat", text))
    assert isinstance(problem, FrictionalProblem)
    np.testing.assert_allclose(problem.v_minus, [0, -2])
    np.testing.assert_allclose(problem.q, [-2, 0])  # u_N = -2 before the impact
    assert describe(problem)["density"] == 1.0


def test_import_siconos_refuses_a_bad_file_and_writes_nothing(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture
                                                                ) -> None:
    good = write(tmp_path, "fc2d_good.dat", SMALL_FC2D)
    bad = write(tmp_path, "fc2d_bad.dat", SMALL_FC2D[:20])
    status = main(["import-siconos", str(good), str(bad), "--no-reference",
                   "-o", str(tmp_path / "out")])
    assert status == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@needs_shared
@pytest.mark.shared
def test_shared_siconos_files_all_import_or_are_refused_in_one_line() -> None:
    imported = refused = 0
    for path in sorted((SHARED / "fc2d").glob("*.dat")) + sorted((SHARED / "lcp").glob("*")):
        try:
            problem = import_siconos(path)
        except UnsupportedError as error:
            assert "\n" not in str(error) and "general LCP" in str(error)
            refused += 1
            continue
        imported += 1
        assert problem.n_contacts >= 0
    assert imported >= 8 + 5 and imported + refused == 28


@needs_shared
@pytest.mark.shared
def test_shared_describe_gives_abh_columns() -> None:
    problem = import_siconos(SHARED / "fc2d" / "fc2d_granularflowonwall_00667_00000.dat")
    described = describe(problem)
    assert described["contacts"] == 667 and described["dofs"] is None
    assert described["rank_deficiency"] == 0 and 1 < described["cond"] < 1e3
    assert described["mu_max"] == 0.5
    assert sp.issparse(problem.W) and friction_metrics.residual(
        problem, np.zeros(2 * 667)) > 0
