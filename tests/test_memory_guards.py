"""Memory and interrupt guards of simulate, generate and build-set (and the memory cap of
sequence and head-to-head): a request too large for the memory cap is refused in one line
(exit 2) before it is allocated, a MemoryError under the cap becomes one line, and Ctrl-C
ends a long run with exit 130 within about a second, leaving no temporary or partial
file."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from qpbench.memory import OutOfMemory, out_of_memory_as_error, product_entries, require
from qpbench.problem import files

ROOT = Path(__file__).resolve().parents[1]
SMALL_CAP_MB = "300"
# an outer cap on the child's address space: a guard that let the huge request through would
# fail with MemoryError under it instead of reaching the machine's memory
OUTER_CAP_BYTES = 6 * 1024**3


def _outer_cap() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (OUTER_CAP_BYTES, OUTER_CAP_BYTES))


def qpbench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "qpbench.cli", *args], capture_output=True,
                          text=True, timeout=60, preexec_fn=_outer_cap, cwd=ROOT)


def nearly_coincident_scene(path: Path, balls: int) -> Path:
    """``balls`` balls of radius 1/2 within 1e-3 of the origin, moving at random: every pair
    overlaps, so the broad phase would pair them all (O(n^2) candidates and contacts)."""
    rng = np.random.default_rng(0)
    lines = ['<ball2d_scene>', '  <integrator type="verlet" dt="0.01"/>',
             '  <impact_operator type="lcp" CoR="1.0" v_tol="1.0e-9" cache_impulses="0">',
             '    <solver name="ipopt" linear_solvers="mumps" tol="1.0e-12"/>',
             '  </impact_operator>']
    for (x, y), (vx, vy) in zip(rng.uniform(-1e-3, 1e-3, (balls, 2)),
                                rng.uniform(-1.0, 1.0, (balls, 2)), strict=True):
        lines.append(f'  <ball x="{x}" y="{y}" vx="{vx}" vy="{vy}" m="1" r="0.5" fixed="0"/>')
    path.write_text("\n".join([*lines, "</ball2d_scene>", ""]))
    return path


def assert_one_line_refusal(done: subprocess.CompletedProcess, command: str, *names: str
                            ) -> None:
    """Exit 2 and one line on stderr from the size check (not a MemoryError), naming the
    size asked and the memory available."""
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"qpbench {command}: ")
    assert "needs at least" in lines[0] and "available" in lines[0]
    assert "--memory-limit" in lines[0]
    for name in names:
        assert name in lines[0]
    assert "Traceback" not in done.stderr


def test_simulate_refuses_the_pairs_of_thousands_of_nearly_coincident_balls(
        tmp_path: Path) -> None:
    scene = nearly_coincident_scene(tmp_path / "heap.xml", 6000)
    done = qpbench("simulate", str(scene), "--steps", "1", "--memory-limit", SMALL_CAP_MB)
    assert_one_line_refusal(done, "simulate", str(scene), "step 0", "17997000 candidate pairs")
    assert done.stdout == ""


def test_simulate_refuses_the_matrices_of_quadratically_many_contacts(tmp_path: Path) -> None:
    scene = nearly_coincident_scene(tmp_path / "heap.xml", 1000)
    done = qpbench("simulate", str(scene), "--steps", "1", "--memory-limit", SMALL_CAP_MB)
    assert_one_line_refusal(done, "simulate", str(scene), "contacts (Q = G^T M^-1 G)")


def test_generate_refuses_a_grid_of_ten_billion_balls(tmp_path: Path) -> None:
    done = qpbench("generate", "grid", "--size", "100000", "--memory-limit", SMALL_CAP_MB,
                   "-o", str(tmp_path / "grids"))
    assert_one_line_refusal(done, "generate", "'grid' at size 100000", "10000000000 balls")
    assert not (tmp_path / "grids").exists()


def test_build_set_refuses_a_huge_family_before_writing_anything(tmp_path: Path) -> None:
    set_file = tmp_path / "huge.toml"
    set_file.write_text("[families]\nk4 = { count = 1 }\ngrid = { sizes = [3, 100000] }\n")
    done = qpbench("build-set", str(set_file), "--memory-limit", SMALL_CAP_MB,
                   "-o", str(tmp_path / "built"))
    assert_one_line_refusal(done, "build-set", str(set_file), "'grid'", "size 100000")
    assert not (tmp_path / "built").exists()


def test_a_set_that_fits_builds_as_before_under_a_small_cap(tmp_path: Path) -> None:
    set_file = tmp_path / "small.toml"
    set_file.write_text("[families]\nk4 = { count = 2 }\ngrid = { sizes = [3] }\n")
    done = qpbench("build-set", str(set_file), "--memory-limit", SMALL_CAP_MB,
                   "-o", str(tmp_path / "built"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"3 problems written, 3 in {tmp_path / 'built'}"
    assert sorted(path.name for path in (tmp_path / "built").iterdir()) == [
        "grid-3-s0.npz", "k4-4-s0.npz", "k4-4-s1.npz"]


@pytest.mark.parametrize("command", [["generate", "k4"], ["sequence", "--solvers", "pi-robust"],
                                     ["head-to-head", str(ROOT), "--results", "unread.parquet"]])
def test_a_negative_memory_limit_is_one_line(command: list[str], tmp_path: Path) -> None:
    done = qpbench(*command, "--memory-limit", "-1", "-o", str(tmp_path / "unused"))
    assert done.returncode == 2
    assert done.stderr.strip() == (f"qpbench {command[0]}: --memory-limit must be at least 0, "
                                   "got -1")
    assert not (tmp_path / "unused").exists()


def test_a_memory_error_becomes_one_line_naming_what_was_built() -> None:
    refused = pytest.raises(OutOfMemory, match=r"^out of memory while building the test "
                                               r"\(Unable to allocate 1 TB\)")
    with refused, out_of_memory_as_error("building the test"):
        raise MemoryError("Unable to allocate 1 TB.")


def test_require_lets_what_fits_through_and_names_what_does_not() -> None:
    require(1024, "a kilobyte")
    with pytest.raises(OutOfMemory, match=r"^a yottabyte: needs at least .* available"):
        require(1e24, "a yottabyte")


def test_product_entries_is_what_scipy_reserves_for_g_transpose_g() -> None:
    # three contacts on one body's x and y rows and one more on another body's rows
    per_row = np.array([3, 3, 1, 1])
    assert product_entries(per_row) == 9 + 9 + 1 + 1


def test_ctrl_c_ends_a_long_simulation_with_130_and_whole_files(tmp_path: Path) -> None:
    capture = tmp_path / "capture"
    scene = ROOT / "problems" / "scenes" / "ura" / "balls_in_box_1000.xml"
    process = subprocess.Popen(
        [sys.executable, "-m", "qpbench.cli", "simulate", str(scene), "--steps", "100000",
         "--capture", str(capture), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        deadline = time.monotonic() + 60
        while not list(capture.glob("*.npz")) and time.monotonic() < deadline:
            time.sleep(0.1)  # wait until the run is stepping and writing
        assert process.poll() is None
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=3)
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert stderr.strip().splitlines()[-1] == "qpbench simulate: interrupted"
    assert not list(capture.glob(".tmp-*"))
    for path in capture.glob("*.npz"):
        files.load(path)  # every captured file is whole


def test_the_watchdog_ends_a_long_compiled_call_within_a_second(tmp_path: Path) -> None:
    partial = tmp_path / ".tmp-partial"
    script = textwrap.dedent(f"""
        import numpy as np
        from qpbench.interrupts import interrupt_watchdog
        matrix = np.random.default_rng(0).random((2500, 2500))
        with interrupt_watchdog("svd") as watchdog:
            watchdog.sweep({str(tmp_path)!r})
            open({str(partial)!r}, "w").write("half")
            print("ready", flush=True)
            while True:
                np.linalg.svd(matrix)  # several seconds each, in LAPACK: past the grace
    """)
    process = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "ready"
        time.sleep(0.5)  # inside the first decomposition
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=3)
    finally:
        process.kill()
    assert process.returncode == 130
    assert stderr == "qpbench svd: interrupted\n"
    assert not partial.exists()
