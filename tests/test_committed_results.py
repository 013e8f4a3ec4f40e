"""The committed results belong to the committed code: the default problem set, rebuilt here,
has exactly the problems stored in results/bench.parquet, with their fingerprints, and every
row was made with the committed package lock. Stale results fail here instead of misleading a
new user.

A problem captured from a scene (family ``scene:...``) comes out of a simulation of up to
hundreds of steps, whose trajectory the CPU's rounding moves in the last bits (OpenBLAS and
numpy pick other kernels on other CPUs), so its numbers are compared only on the CPU model that
made the results; on another, `qpbench run` solves such problems again when it resumes."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from qpbench.bench.lock import lock_hash
from qpbench.bench.problem_sets import build
from qpbench.bench.provenance import cpu_model
from qpbench.bench.runner import fingerprint
from qpbench.problem import files

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "bench.parquet"
DEFAULT_SET = ROOT / "problems" / "default.toml"


@pytest.fixture(scope="module")
def stored() -> pd.DataFrame:
    return pd.read_parquet(RESULTS, columns=["problem", "family", "problem_hash", "lock_hash",
                                             "cpu_model"])


@pytest.mark.slow
def test_the_default_set_rebuilds_to_the_stored_fingerprints(stored: pd.DataFrame,
                                                              tmp_path: Path) -> None:
    rebuilt = {path.stem: fingerprint(files.load(path)) for path in build(DEFAULT_SET, tmp_path)}
    recorded = stored.groupby("problem")["problem_hash"].unique()
    assert set(recorded.index) == set(rebuilt), "the default set and the results differ"
    same_cpu = set(stored["cpu_model"].astype(str)) == {cpu_model()}
    captured = set(stored.loc[stored["family"].astype(str).str.startswith("scene:"), "problem"])
    compared = {name for name in recorded.index if same_cpu or name not in captured}
    assert set(recorded.index) - captured, "no problem built without a simulation to compare"
    stale = {name: (list(recorded[name]), rebuilt[name]) for name in compared
             if list(recorded[name]) != [rebuilt[name]]}
    assert not stale, f"results made from other problem numbers (re-run make bench): {stale}"


def test_every_stored_row_names_the_committed_lock(stored: pd.DataFrame) -> None:
    assert set(stored["lock_hash"].astype(str)) == {lock_hash()}
