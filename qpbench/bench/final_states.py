"""Final states of a simulation: their layout, their errors, and SCISim's own.

A state is laid out as SCISim writes it: with q the positions (x, y and, for rigid bodies,
the angle) and v the velocities of every body in file order, flattened. With W the masses
(m, m and the moment of inertia I), ``||z||_W = sqrt(sum W z^2)``:

* ``position_error = ||q - q_ref||_W / max(||q_ref||_W, ||reach||_W)``, ``reach`` the bodies'
  radii (r, r, 1 radian per body), so that a body at the origin is measured against its size;
* ``velocity_error = ||v - v_ref||_W / max(||v_ref||_W, ||v_start||_W, |g| t sqrt(sum m),
  tiny)``, the third the speed free fall reaches in the simulated time t (the free bodies'
  masses), so that a body held at rest under gravity is measured against that speed;
* ``state_error = max(position_error, velocity_error)``.

SCISim's own final states are read from the committed records of
``problems/scisim_fidelity`` and, when present, the ``tight`` records of
``../shared/scisim/expected`` whose self-consistency is within :data:`SCISIM_CONSISTENT`;
a scene file is matched to a record by its bytes (SHA-256), so a copy anywhere is
recognised. The fidelity rule (:func:`agrees_with_scisim`) compares a state with SCISim's
coordinate by coordinate.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from qpbench.problem.metrics import TINY
from qpbench.scenes.model import Scene
from qpbench.simulation.stepper import SimulationResult

ROOT = Path(__file__).resolve().parents[2]
FIDELITY = ROOT / "problems" / "scisim_fidelity"
SHARED_SCISIM = ROOT.parent / "shared" / "scisim"
SCISIM_POSITION_TOLERANCE = 1e-6
SCISIM_VELOCITY_TOLERANCE = 1e-6  # times max(1, the largest SCISim speed)
# a shared ``tight`` record counts when it agrees with ``tighter`` this well (as the rule)
SCISIM_CONSISTENT = 1e-8


# --- states and their errors ---------------------------------------------------------------
def final_state(scene: Scene, result: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """Lay out the run's final state as SCISim does.

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    result : SimulationResult
        The run's result.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        q ``(x, y[, theta])`` and v ``(vx, vy[, omega])`` per body in file order, flattened.
    """
    q, v = [result.x_final], [result.v_final]
    if scene.bodies.rotates:
        assert result.theta_final is not None and result.omega_final is not None
        q.append(result.theta_final[:, None])
        v.append(result.omega_final[:, None])
    return np.hstack(q).ravel(), np.hstack(v).ravel()


def start_state(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Lay out the scene's state as written, as :func:`final_state` does.

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        q and v, flattened.
    """
    bodies = scene.bodies
    q, v = [bodies.positions], [bodies.velocities]
    if bodies.rotates:
        q.append(bodies.theta[:, None])
        v.append(bodies.omega[:, None])
    return np.hstack(q).ravel(), np.hstack(v).ravel()


def weights(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Give the mass norm's weights and the reach that scales positions.

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        The weights (m, m[, I]) and the reach (r, r[, 1]) per body, each laid out as
        :func:`final_state`.
    """
    bodies = scene.bodies
    mass = [bodies.masses, bodies.masses]
    reach = [bodies.radii, bodies.radii]
    if bodies.rotates:
        mass.append(bodies.inertia)
        reach.append(np.ones(bodies.count))
    return np.stack(mass, axis=1).ravel(), np.stack(reach, axis=1).ravel()


def _norm(values: np.ndarray, weight: np.ndarray) -> float:
    return math.sqrt(float(np.sum(weight * values * values)))


def falling_speed(scene: Scene, elapsed: float) -> float:
    """Compute ``|g| t sqrt(sum m)`` over the free bodies.

    It is the mass norm of the velocities gravity alone gives them in ``elapsed`` seconds.

    Parameters
    ----------
    scene : Scene
        The scene.
    elapsed : float
        The simulated time t in seconds.

    Returns
    -------
    float
        The speed in the mass norm; 0 without gravity.
    """
    if scene.gravity is None:
        return 0.0
    free = ~scene.bodies.fixed
    mass = float(np.sum(scene.bodies.masses[free]))
    return float(np.hypot(*scene.gravity)) * elapsed * math.sqrt(mass)


def state_errors(scene: Scene, q: np.ndarray, v: np.ndarray, q_ref: np.ndarray,
                 v_ref: np.ndarray, elapsed: float) -> dict[str, float]:
    """Measure (q, v) against (q_ref, v_ref) in the mass norm (module docstring).

    Parameters
    ----------
    scene : Scene
        The scene simulated.
    q, v : numpy.ndarray
        The final state, laid out as :func:`final_state`.
    q_ref, v_ref : numpy.ndarray
        The reference's final state, laid out alike.
    elapsed : float
        The simulated time in seconds (:func:`falling_speed`).

    Returns
    -------
    dict of str to float
        ``position_error``, ``velocity_error`` and ``state_error`` (their maximum).
    """
    weight, reach = weights(scene)
    v_start = start_state(scene)[1]
    position = _norm(q - q_ref, weight) / max(_norm(q_ref, weight), _norm(reach, weight), TINY)
    velocity = _norm(v - v_ref, weight) / max(_norm(v_ref, weight), _norm(v_start, weight),
                                              falling_speed(scene, elapsed), TINY)
    return {"position_error": position, "velocity_error": velocity,
            "state_error": max(position, velocity)}


def agrees_with_scisim(q: np.ndarray, v: np.ndarray, q_scisim: np.ndarray,
                       v_scisim: np.ndarray) -> bool:
    """Apply the fidelity rule, coordinate by coordinate.

    Positions within SCISIM_POSITION_TOLERANCE, velocities within SCISIM_VELOCITY_TOLERANCE x
    max(1, the largest SCISim speed).

    Parameters
    ----------
    q, v : numpy.ndarray
        The final state, laid out as :func:`final_state`.
    q_scisim, v_scisim : numpy.ndarray
        SCISim's final state, laid out alike.

    Returns
    -------
    bool
        Whether every coordinate is within its tolerance.
    """
    scale = max(1.0, float(np.max(np.abs(v_scisim)))) if v_scisim.size else 1.0
    return bool(np.max(np.abs(q - q_scisim), initial=0.0) <= SCISIM_POSITION_TOLERANCE
                and np.max(np.abs(v - v_scisim), initial=0.0)
                <= SCISIM_VELOCITY_TOLERANCE * scale)


# --- SCISim's records ----------------------------------------------------------------------
@dataclass(frozen=True)
class ScisimState:
    """SCISim's final state of one scene after ``steps`` steps, and where it was read."""

    steps: int
    q: np.ndarray
    v: np.ndarray
    source: str


def scene_digest(path: Path) -> str | None:
    """Hash a scene file's bytes, which match it to SCISim's records wherever it lies.

    Parameters
    ----------
    path : pathlib.Path
        The scene file.

    Returns
    -------
    str or None
        The SHA-256 hex digest; None when the file cannot be read.
    """
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _consistent(record: dict[str, Any]) -> bool:
    """A shared ``tight`` record whose run agrees with ``tighter`` within SCISIM_CONSISTENT."""
    check = record.get("self_consistency") or {}
    speed = max([1.0, *(abs(value) for value in record.get("v") or [])])
    dq, dv = check.get("max_dq"), check.get("max_dv")
    return (dq is not None and dv is not None and dq <= SCISIM_CONSISTENT
            and dv <= SCISIM_CONSISTENT * speed)


def _records() -> Iterable[tuple[Path, dict[str, Any], str]]:
    """(scene file, record, source) of every usable SCISim record found."""
    committed = FIDELITY / "expected.jsonl"
    if committed.is_file():
        for line in committed.read_text().splitlines():
            record = json.loads(line)
            yield FIDELITY / "scenes" / record["scene"], record, str(committed)
    expected = SHARED_SCISIM / "expected"
    for name in ("ball2d.jsonl", "rigidbody2d.jsonl", "fork.jsonl.gz"):
        path = expected / name
        if not path.is_file():
            continue
        text = (gzip.decompress(path.read_bytes()).decode() if name.endswith(".gz")
                else path.read_text())
        for line in text.splitlines():
            record = json.loads(line)
            if (record.get("variant") == "tight" and record.get("ok")
                    and record.get("q") is not None and _consistent(record)):
                yield SHARED_SCISIM / record["scene"], record, str(path)


def scisim_states(steps: int) -> dict[str, ScisimState]:
    """Collect SCISim's final states after ``steps`` steps, keyed by the scene file's SHA-256.

    The committed records come first; a scene file that cannot be read is left out.

    Parameters
    ----------
    steps : int
        The step count the records must have.

    Returns
    -------
    dict of str to ScisimState
        SHA-256 of the scene file -> SCISim's state.
    """
    states: dict[str, ScisimState] = {}
    digests: dict[Path, str | None] = {}
    for scene, record, source in _records():
        if record.get("steps") != steps:
            continue
        if scene not in digests:
            digests[scene] = scene_digest(scene)
        digest = digests[scene]
        if digest is not None and digest not in states:
            states[digest] = ScisimState(steps, np.array(record["q"], dtype=float),
                                         np.array(record["v"], dtype=float), source)
    return states
