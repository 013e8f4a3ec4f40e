"""Siconos' LCP and 2D friction solvers (run by /usr/bin/python3 behind a pipe), judged by
qpbench's metrics on known answers, the repository's dumps and the research fork's 50 dumps.

Siconos' known defects are rows of qpbench/solvers/defects.toml (package
``debian:python3-siconos``, whose version dpkg records)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from backend_cases import ALL_CASES, DUMP_FILES, dump_problem
from friction_cases import ball_on_floor, pair_on_floor
from known_defects import expect_described

from qpbench.problem import friction_reference
from qpbench.problem.dumps import import_dump
from qpbench.problem.friction_generate import generate
from qpbench.solvers import siconos_
from qpbench.solvers.base import OWN_TIME, ROUND_TRIP_TIME, SolverSpec
from qpbench.solvers.defects import known_defect
from qpbench.solvers.registry import all_solvers
from qpbench.solvers.run import call_solver, solve_and_judge

SPECS = [spec for spec in all_solvers() if spec.backend == siconos_.BACKEND]
USABLE = [spec for spec in SPECS if spec.usable]
LCP_SPECS = [spec for spec in USABLE if spec.formulation == "lcp"]
FC2D_SPECS = [spec for spec in USABLE if spec.formulation == "fc2d"]
SICONOS_MISSING = next((spec.reason for spec in SPECS if spec.formulation == "lcp"
                        and spec.name == "siconos-lemke" and not spec.usable), "")
pytestmark = pytest.mark.skipif(bool(SICONOS_MISSING), reason=SICONOS_MISSING or "")

FORK_DUMPS = (Path(__file__).resolve().parents[2] / "shared" / "scisim" / "forks"
              / "IsaiahWitzke_scisim" / "ura_research" / "old_simulation_outputs"
              / "5_by_5_grid")
ACCURACY = 1e-8
V_TOLERANCE = 1e-5


def test_make_setup_gives_six_frictionless_and_two_frictional_pairs() -> None:
    assert len(LCP_SPECS) >= 6 and len(FC2D_SPECS) >= 2
    assert {"siconos-lemke", "siconos-pgs", "siconos-psor", "siconos-newton-min",
            "siconos-newton-fb", "siconos-enum", "siconos-pivot", "siconos-murty"} <= \
        {spec.name for spec in LCP_SPECS}
    assert {spec.name for spec in FC2D_SPECS} == {"siconos-nsgs", "siconos-lemke",
                                                  "siconos-cpg", "siconos-enum"}
    assert all(spec.kinds == ("frictional",) for spec in FC2D_SPECS)


def test_a_solver_missing_from_the_build_is_unusable_with_its_reason() -> None:
    nsqp = next(spec for spec in SPECS if spec.name == "siconos-nsqp")
    assert nsqp.usable or "ql0001" in nsqp.reason


def test_time_s_is_the_servers_own_time_and_the_round_trip_is_kept_apart() -> None:
    spec = next(spec for spec in LCP_SPECS if spec.name == "siconos-lemke")
    output = call_solver(spec, ALL_CASES["head-on"].problem, ACCURACY)
    assert spec.reports_own_time and output.time_s == output.info[OWN_TIME]
    assert output.info[ROUND_TRIP_TIME] >= output.time_s > 0.0
    assert set(output.backend_times) == {"backend_setup_time_s", "backend_solve_time_s"}


def test_one_server_per_process_serves_every_solve() -> None:
    siconos_.prepare()
    first = siconos_.server()
    for spec in LCP_SPECS[:3]:
        call_solver(spec, ALL_CASES["k3"].problem, ACCURACY)
    assert siconos_.server() is first and first.alive()


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity here")
def test_each_solve_runs_on_the_cpu_of_the_process_that_asks() -> None:
    # as a library called in-process would, the server finds the caches as the client's
    # other work left them, not as its own last solve did on a core of its own
    spec = next(spec for spec in LCP_SPECS if spec.name == "siconos-lemke")
    allowed = os.sched_getaffinity(0)
    try:
        for cpu in sorted(allowed)[-2:]:
            os.sched_setaffinity(0, {cpu})
            call_solver(spec, ALL_CASES["k3"].problem, ACCURACY)
            assert os.sched_getaffinity(siconos_.server().process.pid) == {cpu}
    finally:
        os.sched_setaffinity(0, allowed)


@pytest.mark.parametrize("name", sorted(ALL_CASES))
@pytest.mark.parametrize("spec", LCP_SPECS, ids=lambda spec: spec.key)
def test_lcp_pair_finds_the_known_post_impact_velocity(spec: SolverSpec, name: str) -> None:
    case = ALL_CASES[name]
    row, output = solve_and_judge(spec, case.problem, ACCURACY)
    rank_deficiency = 1 if case.impulses is None else 0
    defect = known_defect(spec.name, spec.formulation, rank_deficiency)
    if defect is not None and row["status"] != "solved":
        expect_described(defect, row, output.status)
    assert row["status"] == "solved" and row["claimed_success"], output.status
    np.testing.assert_allclose(case.problem.v_plus(output.impulses), case.v_plus, atol=1e-6)


@pytest.mark.parametrize("path", DUMP_FILES, ids=lambda path: path.name)
@pytest.mark.parametrize("spec", LCP_SPECS, ids=lambda spec: spec.key)
def test_lcp_pair_matches_the_reference_on_a_dump(spec: SolverSpec, path: Path) -> None:
    problem = dump_problem(path)
    row, output = solve_and_judge(spec, problem, ACCURACY)
    if output.status.startswith("declined"):  # above the size limit of the accuracy table
        assert problem.n_contacts > 16 and spec.name == "siconos-enum"
        return
    defect = known_defect(spec.name, spec.formulation, problem.rank_deficiency)
    if defect is not None and not row["v_error"] <= V_TOLERANCE:
        expect_described(defect, row, output.status)
    assert row["v_error"] <= V_TOLERANCE, output.status
    assert row["energy_gain"] <= V_TOLERANCE  # c = 1: no energy made


@pytest.mark.parametrize("spec", FC2D_SPECS, ids=lambda spec: spec.key)
@pytest.mark.parametrize("u_normal, u_tangential, mu",
                         [(-2.0, 0.6, 0.5), (-2.0, 1.5, 0.5), (-1.0, -3.0, 0.5)])
def test_fc2d_pair_finds_the_hand_answer_of_a_ball_on_the_floor(
        spec: SolverSpec, u_normal: float, u_tangential: float, mu: float) -> None:
    """It sticks iff |u_T-| <= mu (1 + e) |u_N-|, else slides with l_T = -mu l_N sign(u_T-)."""
    problem = ball_on_floor(u_normal, u_tangential, mu, restitution=0.5, mass=2.0)
    row, output = solve_and_judge(spec, problem, ACCURACY)
    normal = 2.0 * 1.5 * -u_normal
    sticks = abs(u_tangential) <= mu * normal / 2.0
    tangential = -2.0 * u_tangential if sticks else -mu * normal * np.sign(u_tangential)
    assert row["status"] == "solved"
    np.testing.assert_allclose(output.impulses, [normal, tangential], atol=1e-10)
    if not row["claimed_success"]:
        defect = known_defect(spec.name, spec.formulation, 0)
        assert defect is not None and defect.effect == "fails", output.status


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("spec", FC2D_SPECS, ids=lambda spec: spec.key)
def test_fc2d_pair_solves_three_coupled_contacts_of_one_mu(spec: SolverSpec, seed: int) -> None:
    problem = friction_reference.attach_reference(pair_on_floor(mu=0.6, seed=seed))
    row, output = solve_and_judge(spec, problem, ACCURACY)
    assert row["status"] == "solved" and row["claimed_success"], output.status
    assert row["v_error"] <= V_TOLERANCE


def test_fc2d_lemke_claims_success_on_other_mus_as_the_defects_table_says() -> None:
    """fc2d_tolcp takes the row contact's mu for a column: a rough box whose contacts have
    different mu gets a wrong answer called converged; the same box with one mu is exact."""
    spec = next(spec for spec in FC2D_SPECS if spec.name == "siconos-lemke")
    defect = known_defect(spec.name, spec.formulation, 0)
    assert defect is not None and defect.effect == "wrong-claim"
    mixed = generate("rough-box", seed=0)[0]
    row, _ = solve_and_judge(spec, mixed, ACCURACY)
    assert row["claimed_success"] is True and row["status"] == "inaccurate"
    uniform = generate("rough-box", seed=0, mu=0.4)[0]
    row, _ = solve_and_judge(spec, uniform, ACCURACY)
    assert row["status"] == "solved" and row["claimed_success"] is True


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.skipif(not FORK_DUMPS.is_dir(), reason=f"needs ../shared: {FORK_DUMPS}")
def test_siconos_lemke_solves_all_50_fork_dumps_from_shared_at_1e_8() -> None:
    paths = sorted(FORK_DUMPS.glob("itr_*.xml.out"))
    assert len(paths) == 50
    spec = next(spec for spec in LCP_SPECS if spec.name == "siconos-lemke")
    statuses = {path.name: solve_and_judge(spec, import_dump(path), ACCURACY)[0]["status"]
                for path in paths}
    assert set(statuses.values()) == {"solved"}, statuses
