"""The committed results belong to the committed code: the default problem set, rebuilt here,
has exactly the problems and fingerprints stored in results/bench.parquet, and every row was
made with the committed package lock. Stale results fail here instead of failing a new user's
`make bench`."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from qpbench.bench.lock import lock_hash
from qpbench.bench.problem_sets import build
from qpbench.bench.runner import fingerprint
from qpbench.problem import files

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "bench.parquet"
DEFAULT_SET = ROOT / "problems" / "default.toml"


@pytest.fixture(scope="module")
def stored() -> pd.DataFrame:
    return pd.read_parquet(RESULTS, columns=["problem", "problem_hash", "lock_hash"])


@pytest.mark.slow
def test_the_default_set_rebuilds_to_the_stored_fingerprints(stored: pd.DataFrame,
                                                              tmp_path: Path) -> None:
    rebuilt = {path.stem: fingerprint(files.load(path)) for path in build(DEFAULT_SET, tmp_path)}
    recorded = stored.groupby("problem")["problem_hash"].unique()
    assert set(recorded.index) == set(rebuilt), "the default set and the results differ"
    stale = {name: (list(hashes), rebuilt[name]) for name, hashes in recorded.items()
             if list(hashes) != [rebuilt[name]]}
    assert not stale, f"results made from other problem numbers (re-run make bench): {stale}"


def test_every_stored_row_names_the_committed_lock(stored: pd.DataFrame) -> None:
    assert set(stored["lock_hash"].astype(str)) == {lock_hash()}
