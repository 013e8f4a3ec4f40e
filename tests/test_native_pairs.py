"""Every backend called through its own Python API (backend ``native``) on the tiny problems
with known v+ (and l where it is unique, which checks the sign of the multipliers) and on the
shared SCISim dumps, judged against each problem's verified reference v+, beside its
qpsolvers twin's options."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from backend_cases import ALL_CASES, DUMP_FILES, Case, dump_problem
from known_defects import expect_described

from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import SolverSpec
from qpbench.solvers.defects import known_defect
from qpbench.solvers.native.common import BACKEND
from qpbench.solvers.qpsolvers_ import NOT_POSITIVE_DEFINITE
from qpbench.solvers.registry import all_solvers
from qpbench.solvers.run import call_solver, solve_and_judge

SPECS = [spec for spec in all_solvers() if spec.backend == BACKEND]
ACCURACY = 1e-8
# ECOS (a conic reformulation) stops near 1e-5 whatever the tolerance, so v+ is checked to
# 1e-4 on the tiny cases (a wrong sign or formulation is off by O(1)), 1e-5 on the dumps
V_TOLERANCE = 1e-4
DUMP_V_TOLERANCE = 1e-5
# the backends that factor Q and refuse a singular one by name
REFUSE_SINGULAR_DUAL = frozenset({"quadprog-native", "ecos-native"})
EXPECTED = {"daqp-native": {"dual", "primal"}, "piqp-native": {"dual", "primal", "dual-factored"},
            "piqp-dense-native": {"dual", "primal"},
            "osqp-native": {"dual", "primal", "dual-factored"},
            "clarabel-native": {"dual", "primal", "dual-factored"},
            "proxqp-native": {"dual", "primal", "dual-factored"},
            "proxqp-dense-native": {"dual", "primal"},
            "highs-native": {"dual", "primal", "dual-factored"},
            "quadprog-native": {"dual", "primal"},
            "scs-native": {"dual", "primal", "dual-factored"},
            "ecos-native": {"dual", "primal", "dual-factored"},
            "qpalm-native": {"dual", "primal", "dual-factored"}}


def usable(spec: SolverSpec) -> SolverSpec:
    if not spec.usable:
        pytest.skip(f"{spec.key}: {spec.reason}")
    return spec


def refuses_singular(spec: SolverSpec, problem: ImpactProblem) -> bool:
    return (spec.name in REFUSE_SINGULAR_DUAL and spec.formulation == "dual"
            and problem.rank_deficiency > 0)


def velocity_error(case: Case, impulses: np.ndarray) -> float:
    """||v+(l) - v+_known||_M / ||v-||_M."""
    problem = case.problem
    return problem.m_norm(problem.v_plus(impulses) - case.v_plus) / problem.m_norm(
        problem.v_minus)


def test_every_backend_with_its_own_api_has_its_pairs_and_its_twins_options() -> None:
    listed: dict[str, set[str]] = {}
    for spec in SPECS:
        if spec.usable:
            listed.setdefault(spec.name, set()).add(spec.formulation)
    assert listed == EXPECTED
    for native, twin in accuracy.NATIVE_TWINS.items():
        assert accuracy.options_for(native, 1e-6, 3.0) == accuracy.options_for(twin, 1e-6, 3.0)
    assert {spec.name for spec in SPECS if spec.warm_start} == {
        "daqp-native", "osqp-native", "proxqp-native", "proxqp-dense-native", "scs-native",
        "qpalm-native"}


@pytest.mark.parametrize("case_name", sorted(ALL_CASES))
@pytest.mark.parametrize("spec", SPECS, ids=lambda spec: spec.key)
def test_native_pair_finds_the_known_velocity(spec: SolverSpec, case_name: str) -> None:
    spec = usable(spec)
    case = ALL_CASES[case_name]
    problem = case.problem
    output = call_solver(spec, problem, ACCURACY)
    if refuses_singular(spec, problem):
        assert output.status == NOT_POSITIVE_DEFINITE
        assert output.claimed_success is False and output.impulses is None
        return
    assert output.impulses is not None, output.status
    assert output.impulses.shape == (problem.n_contacts,)
    assert velocity_error(case, output.impulses) <= V_TOLERANCE, output.status
    assert np.min(output.impulses) >= -V_TOLERANCE * max(1.0, float(np.max(output.impulses)))
    scale = float(np.max(np.abs(problem.b)))
    u_minus = problem.G.T @ problem.v_minus
    w_known = problem.G.T @ case.v_plus + problem.restitution * u_minus
    assert problem.w(output.impulses) == pytest.approx(w_known, abs=V_TOLERANCE * scale)
    if case.impulses is not None:  # unique l: value and sign of the multipliers
        assert output.impulses == pytest.approx(case.impulses, abs=V_TOLERANCE * 10)
    assert output.iterations is None or output.iterations >= 0


@pytest.mark.parametrize("spec", SPECS, ids=lambda spec: spec.key)
def test_native_pair_claims_success_on_an_easy_problem_in_its_own_words(
        spec: SolverSpec) -> None:
    output = call_solver(usable(spec), ALL_CASES["head-on"].problem, 1e-4)
    assert output.claimed_success, output.status
    assert output.status and not output.status.startswith("error")
    assert all(value >= 0.0 for value in output.backend_times.values())


@pytest.mark.parametrize("spec", [s for s in SPECS if s.warm_start], ids=lambda s: s.key)
def test_warm_start_from_a_solution_and_from_a_poor_guess(spec: SolverSpec) -> None:
    case = ALL_CASES["k3"]
    exact = np.array([0.0, 0.0, 2.0])  # one of the many solutions of the singular K3
    for start in (exact, np.ones(3)):
        output = call_solver(spec, case.problem, ACCURACY, warm_start=start)
        assert output.impulses is not None, output.status
        assert velocity_error(case, output.impulses) <= V_TOLERANCE


def test_a_singular_dual_is_refused_by_name_and_the_factored_form_is_not_needed() -> None:
    specs = {spec.key: spec for spec in SPECS}
    k3 = ALL_CASES["k3"]
    for name in REFUSE_SINGULAR_DUAL:
        row, output = solve_and_judge(usable(specs[f"{name}/dual"]), k3.problem, 1e-6)
        assert output.status == NOT_POSITIVE_DEFINITE
        assert row["claimed_success"] is False and row["status_honest"] is True
    assert specs["quadprog-native/dual-factored"].reason.startswith(NOT_POSITIVE_DEFINITE)
    factored = call_solver(usable(specs["ecos-native/dual-factored"]), k3.problem, 1e-6)
    assert factored.impulses is not None and velocity_error(k3, factored.impulses) <= 1e-4


def test_a_stopped_backend_claims_no_success_and_the_row_says_so(
        monkeypatch: pytest.MonkeyPatch) -> None:
    name = "osqp-native"
    monkeypatch.setitem(accuracy.OPTIONS, name, {**accuracy.OPTIONS[name], "max_iter": 1})
    spec = next(spec for spec in SPECS if spec.key == f"{name}/dual")
    row, output = solve_and_judge(usable(spec), ALL_CASES["k3"].problem, 1e-10)
    assert "maximum iterations" in output.status.lower()
    assert row["claimed_success"] is False and row["success"] is False
    assert row["status_honest"] is True


@pytest.mark.parametrize("path", DUMP_FILES, ids=lambda path: path.name)
@pytest.mark.parametrize("spec", SPECS, ids=lambda spec: spec.key)
def test_native_pair_matches_the_reference_on_a_dump(spec: SolverSpec, path: Path) -> None:
    spec = usable(spec)
    problem = dump_problem(path)
    row, output = solve_and_judge(spec, problem, ACCURACY)
    if refuses_singular(spec, problem):
        assert output.status == NOT_POSITIVE_DEFINITE
        assert row["claimed_success"] is False and row["success"] is False
        return
    defect = known_defect(spec.name, spec.formulation, problem.rank_deficiency)
    if defect is not None and not row["v_error"] <= DUMP_V_TOLERANCE:
        expect_described(defect, row, output.status)
    assert row["v_error"] <= DUMP_V_TOLERANCE, output.status
    assert row["energy_gain"] <= DUMP_V_TOLERANCE  # c = 1: no energy made
