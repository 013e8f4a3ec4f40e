"""The table of known solver defects is data: every row names a pair that exists, its version
range parses, and a malformed row is one clear error naming the row and the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from qpbench.errors import InputError
from qpbench.solvers import defects
from qpbench.solvers.registry import all_solvers

PAIRS = {(spec.name, spec.formulation) for spec in all_solvers()}


@pytest.mark.parametrize("defect", defects.defects(), ids=lambda d: f"{d.solver}/{d.formulation}")
def test_every_row_names_a_registered_pair(defect: defects.Defect) -> None:
    formulations = {formulation for name, formulation in PAIRS if name == defect.solver}
    assert formulations, f"no solver named {defect.solver}"
    assert defect.formulation == "*" or defect.formulation in formulations


def test_a_row_applies_by_version_and_by_kind_of_problem(tmp_path: Path) -> None:
    table = tmp_path / "defects.toml"
    table.write_text('[[defect]]\nsolver = "osqp"\nformulation = "dual"\npackage = "osqp"\n'
                     'versions = ">=0"\nproblems = "singular"\neffect = "inaccurate"\n'
                     'what = "an example"\n'
                     '[[defect]]\nsolver = "osqp"\nformulation = "*"\npackage = "osqp"\n'
                     'versions = "<0.0.1"\nproblems = "any"\neffect = "fails"\n'
                     'what = "fixed long ago"\n', encoding="utf-8")
    current, fixed = defects.defects(table)
    assert current.hits("osqp", "dual", rank_deficiency=1)
    assert not current.hits("osqp", "dual", rank_deficiency=0)
    assert not current.hits("osqp", "primal", rank_deficiency=1)
    assert not fixed.applies_here() and not fixed.hits("osqp", "dual", rank_deficiency=1)


@pytest.mark.parametrize("change, field", [
    (('problems = "singular"', 'problems = "sometimes"'), "problems"),
    (('effect = "fails"', 'effect = "bad"'), "effect"),
    (('what = "x"\n', ''), "what"),
])
def test_a_malformed_row_names_its_field(tmp_path: Path, change: tuple[str, str],
                                         field: str) -> None:
    row = ('[[defect]]\nsolver = "osqp"\nformulation = "dual"\npackage = "osqp"\n'
           'versions = ">=1"\nproblems = "singular"\neffect = "fails"\nwhat = "x"\n')
    table = tmp_path / "defects.toml"
    table.write_text(row.replace(*change), encoding="utf-8")
    with pytest.raises(InputError, match=f"<defect 1> attribute '{field}'"):
        defects.defects(table)


def test_a_debian_package_row_reads_dpkgs_version() -> None:
    """``debian:NAME`` rows take the version dpkg records (``4.4.0+dfsg-2`` is a PEP 440 local
    version, so ``>=4.4`` holds), and a package that is not installed applies nowhere."""
    row = {"solver": "siconos-lemke", "formulation": "fc2d", "versions": ">=4.4",
           "problems": "any", "effect": "fails", "what": "an example"}
    missing = defects.Defect(package="debian:no-such-package-here", **row)
    assert missing.installed_version() is None and not missing.applies_here()
    dpkg = defects.debian_version("dpkg")
    if dpkg is None:
        pytest.skip("no dpkg on this machine")
    present = defects.Defect(package="debian:dpkg", **{**row, "versions": ">=1.0"})
    assert present.installed_version() == dpkg and present.applies_here()
