"""qpbench against SCISim itself: the final states SCISim produced (problems/scisim_fidelity).

Every scene that has a SCISim record (circles and boxes, frictional and
frictionless, planar and Lees-Edwards portals, and the coincident-centre case of the
research fork), simulated for the
record's step count with the scene's own solver
mapping, must end within 1e-6 of SCISim's positions and 1e-6 x max(1, largest reference
speed) of its velocities (``problems/scisim_fidelity/README.md``; the rule is
``qpbench.bench.sim_precision.agrees_with_scisim``, which ``qpbench sim-precision`` applies
too). A scene that cannot agree would be listed in DISAGREES with the reason, and expected to
fail; today there is none.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from qpbench.bench import sim_precision
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import load_scene
from qpbench.simulation.stepper import Simulator

DATA = Path(__file__).resolve().parents[1] / "problems" / "scisim_fidelity"
RECORDS = [json.loads(line) for line in (DATA / "expected.jsonl").read_text().splitlines()]

# scene -> why qpbench cannot agree with SCISim there (an expected failure, stated as data)
DISAGREES: dict[str, str] = {}


def test_the_records_cover_friction_and_every_staggering() -> None:
    assert len(RECORDS) >= 60
    staggerings = {load_scene(DATA / "scenes" / record["scene"]).staggering
                   for record in RECORDS}
    assert staggerings == {"geometric", "stabilized", "symplectic_euler"}
    assert sum(load_scene(DATA / "scenes" / record["scene"]).frictional
               for record in RECORDS) >= 40


def final_state(record: dict) -> tuple[np.ndarray, np.ndarray, int]:
    """q, v (as SCISim lays them out) and the steps taken, simulated by qpbench."""
    scene = load_scene(DATA / "scenes" / record["scene"])
    result = Simulator(scene, choose_by_name(None)).run(max_steps=record["steps"])
    assert result.failure is None, result.failure
    return (*sim_precision.final_state(scene, result), result.steps)


@pytest.mark.parametrize("record", RECORDS, ids=[record["scene"] for record in RECORDS])
def test_qpbench_ends_where_scisim_ends(record: dict) -> None:
    if record["scene"] in DISAGREES:
        pytest.xfail(DISAGREES[record["scene"]])
    q, v, steps = final_state(record)
    q_ref, v_ref = np.array(record["q"]), np.array(record["v"])
    assert steps == record["steps"]
    assert sim_precision.agrees_with_scisim(q, v, q_ref, v_ref), (
        np.max(np.abs(q - q_ref)), np.max(np.abs(v - v_ref)))
