"""What a compiled pi-robust call loses when other work ran since the last one.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_cold_calls.py [--quick]``. On the
research fork's 5x5 grid dumps it times the compiled entry ``envelope_pi_robust`` alone (no
harness, no Python path), each problem's fastest of 30 rounds (10 with ``--quick``), in four
settings: the same problem called back to back; the problems in turn; the problems in turn
with a small SciPy sparse product between calls (as the harness's posing runs between two
timed solves); the problems in turn with a 32 MB buffer written between calls; and the same
with the kernel then run on a 3-contact problem (K3) before each call, which brings back its
code and the data every call shares but not the problem's own. It prints the geometric mean
over the problems of each.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from pi_robust_common import dump_kernel_calls

from qpbench.problem.formulations import pose
from qpbench.problem.generate import generate
from qpbench.solvers.pi_robust_kernel import entry


def main() -> None:
    rounds = 10 if "--quick" in sys.argv[1:] else 30
    calls = dump_kernel_calls()
    tiny = generate("k3", None, seed=0)[0]
    pose(tiny, "lcp")
    tiny_call = (tiny.Q.indptr, tiny.Q.indices, tiny.Q.data, tiny.b, tiny.diag_Q, *calls[0][5:])
    other = sp.random(300, 300, density=0.05, format="csc", random_state=0)
    buffer = np.zeros(4_000_000)

    def product() -> None:
        (other @ other.T).sum()

    def flush() -> None:
        buffer[:] += 1.0

    def flush_then_code() -> None:
        flush()
        entry.envelope_pi_robust(*tiny_call)

    def nothing() -> None:
        return None

    def in_turn(between: Callable[[], None]) -> float:
        best = [np.inf] * len(calls)
        for _ in range(rounds):
            for number, arguments in enumerate(calls):
                between()
                start = time.perf_counter()
                entry.envelope_pi_robust(*arguments)
                best[number] = min(best[number], time.perf_counter() - start)
        return float(np.exp(np.mean(np.log(best))))

    def back_to_back() -> float:
        best = []
        for arguments in calls:
            times = []
            for _ in range(rounds):
                start = time.perf_counter()
                entry.envelope_pi_robust(*arguments)
                times.append(time.perf_counter() - start)
            best.append(min(times))
        return float(np.exp(np.mean(np.log(best))))

    rows = [("the same problem back to back", back_to_back()),
            ("the problems in turn", in_turn(nothing)),
            ("in turn, a SciPy sparse product between calls", in_turn(product)),
            ("in turn, a 32 MB buffer written between calls", in_turn(flush)),
            ("in turn, the buffer written, then a K3 problem solved", in_turn(flush_then_code))]
    print(f"\nenvelope_pi_robust on {len(calls)} fork 5x5 dumps, accuracy 1e-8\n")
    print("| setting | geometric mean (us) |")
    print("|---|---:|")
    for name, seconds in rows:
        print(f"| {name} | {seconds * 1e6:.1f} |")


if __name__ == "__main__":
    main()
