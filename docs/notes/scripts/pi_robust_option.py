"""Compare pi-robust with one accuracy-table option changed: solves, failures, time.

Usage: ``.venv/bin/python docs/notes/scripts/pi_robust_option.py KEY VALUE... [--quick]
[--folder DIR]``,
e.g. ``active_set True False`` (the active-set hand-over), ``start_sweeps 0 1 2 5 10``
(the start sweeps), ``drift_steps 0 3`` (the drift rule). Values are read as Python
literals. Without ``--quick`` it takes a few minutes per value.
"""

from __future__ import annotations

import ast

from pi_robust_common import groups, quick_flag, run, table, with_row, words


def main() -> None:
    given = words()
    key, values = given[0], [ast.literal_eval(word) for word in given[1:]]
    quick = quick_flag()
    repeats = 1 if quick else 5
    results = {}
    names = []
    for name, problems in groups(quick):
        names.append(name)
        for value in values:
            results[name, repr(value)] = with_row(
                key, value, lambda problems=problems: run(problems, repeats))
    table(f"pi-robust at 1e-8, {key} = {' / '.join(map(repr, values))}",
          [repr(value) for value in values], results, names)


if __name__ == "__main__":
    main()
