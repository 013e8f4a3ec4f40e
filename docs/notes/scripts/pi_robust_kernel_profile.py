"""Where the compiled kernel's own time goes on the fork's 5x5 dumps, function by function.

Usage: ``perf record -F 10000 -e cpu-clock -o perf.data -- .venv/bin/python
docs/notes/scripts/pi_robust_kernel_profile.py [ROUNDS]``, then ``python
docs/notes/scripts/pi_robust_kernel_profile.py --report perf.data``.

The first form compiles pi-robust's kernel afresh (numba's cache goes to a temporary folder, so
that the compiled module, and with it each function's address, is in this process), calls the
compiled entry ``envelope_pi_robust`` on every dump in turn for ROUNDS rounds (default 20000),
and then writes ``/tmp/perf-PID.map``, where ``perf report`` finds the names of the kernel's
functions (each taken to end where the next begins). The second form prints each function's
share of the samples of the run's last 40% (``WINDOW``: the loop alone, when it runs longer
than the half-minute compilation before it, as with the default rounds), largest first, as a
Markdown table. Shares depend on the CPU; the order of
the largest few is what the notes quote.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter

if "--report" not in sys.argv[1:]:
    # before numba is imported: a fresh cache, so that the kernel is compiled in this process
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="pi-robust-profile-")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# the kernel's mangled names: _ZN7qpbench7solvers16pi_robust_kernel<len><module><len><name>...
WINDOW = "60%-100%"  # of the run's samples: the timed loop's, after the compilation
MANGLED = re.compile(r"_ZN7qpbench7solvers16pi_robust_kernel\d+([a-z_]+?)\d+([A-Za-z_0-9]+?)B\d")


def write_symbol_map() -> int:
    """Write ``/tmp/perf-PID.map`` for the kernel's compiled functions; return their count."""
    from qpbench.solvers.pi_robust_kernel import entry

    addresses = {}
    for result in entry.envelope_pi_robust.overloads.values():
        library = result.library
        for function in library._final_module.functions:
            if not function.is_declaration and function.name not in addresses:
                address = library.get_pointer_to_function(function.name)
                if address:
                    addresses[function.name] = address
    ordered = sorted((address, name) for name, address in addresses.items())
    ends = [address for address, _ in ordered[1:]] + [ordered[-1][0] + 4096]
    with open(f"/tmp/perf-{os.getpid()}.map", "w") as symbols:
        for (address, name), end in zip(ordered, ends, strict=True):
            symbols.write(f"{address:x} {end - address:x} {name}\n")
    return len(ordered)


def run(rounds: int) -> None:
    """Call the kernel on every dump in turn, ``rounds`` times, then write the symbol map."""
    from pi_robust_common import dump_kernel_calls

    from qpbench.solvers.pi_robust_kernel import entry

    calls = dump_kernel_calls()
    start = time.perf_counter()
    for _ in range(rounds):
        for arguments in calls:
            entry.envelope_pi_robust(*arguments)
    per_call = (time.perf_counter() - start) / (rounds * len(calls))
    print(f"{len(calls)} dumps in turn, {rounds} rounds: {per_call * 1e6:.1f} us a call; "
          f"{write_symbol_map()} kernel functions mapped", file=sys.stderr)


def report(data: str) -> None:
    """Print the kernel functions' shares of the timed loop's samples in ``data``."""
    text = subprocess.run(["perf", "report", "-i", data, "--stdio", "--sort", "symbol",
                           "--time", WINDOW], capture_output=True, text=True,
                          check=True).stdout
    shares: Counter[str] = Counter()
    for line in text.splitlines():
        found = re.match(r"\s*([\d.]+)%\s+\[\.\]\s+(\S+)", line)
        if found is None:
            continue
        mangled = MANGLED.match(found.group(2))
        name = f"{mangled.group(1)}.{mangled.group(2)}" if mangled else found.group(2)
        shares[name] += float(found.group(1))
    print("| function | share of samples |")
    print("|---|---:|")
    for name, share in shares.most_common(16):
        print(f"| `{name}` | {share:.1f}% |")


if __name__ == "__main__":
    if "--report" in sys.argv[1:]:
        report(sys.argv[sys.argv.index("--report") + 1])
    else:
        run(int(sys.argv[1]) if len(sys.argv) > 1 else 20000)
